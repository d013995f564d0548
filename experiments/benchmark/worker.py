"""One benchmark configuration in its own process (see the package; Sec. III-B/C, III-D).

Model stages::

    python -m experiments.benchmark.worker {train|predict} VARIANT SIZE

set JAX's device count (from ``RP_BENCH_NUM_DEVICES``; XLA flags come in the environment)
before JAX initialises, build and warm up the bench, print ``@@BENCH {"ready": {...}}``,
then answer each ``measure`` line on stdin with ``@@BENCH {"speed": ...}`` until ``quit``.

The per-layer profile (``layer_profile.py``) uses the same protocol with stage ``layers``,
and ``measure LAYER|PASS`` lines.

Ground truth::

    python -m experiments.benchmark.worker groundtruth NUM_IMAGES SIZE

labels one synthetic viewpoint and prints its time and peak memory, then exits.

Matching alone (labelling's quadratic stage)::

    python -m experiments.benchmark.worker match NUM_IMAGES SIZE METHOD

matches one synthetic viewpoint with ``match_all_pairs(method=METHOD)`` and prints its time
and peak memory, then exits.

Labelling one large viewpoint (``label_scale_stage``)::

    python -m experiments.benchmark.worker label_scale LAYOUT_ROOT CACHE_DIR MAX_KEYPOINTS

labels the Webcam-like viewpoint at LAYOUT_ROOT as a dataset build does and prints its wall
and CPU time, peak memory and record count, then exits.

Map summarization (Sec. V-A)::

    python -m experiments.benchmark.worker summarize NUM_POINTS SIZE REPEATS KCOVER

builds a synthetic map of NUM_POINTS points, then prints one line per timed summary (ours,
and K-cover when KCOVER is 1, alternating round by round) as it finishes, then exits.

Errors are reported as ``@@BENCH {"error": "..."}`` and a non-zero exit.
"""

from __future__ import annotations

import json
import os
import sys
import traceback


def _send(payload: dict) -> None:
    from experiments.benchmark.config import PROTOCOL_PREFIX

    sys.stdout.write(PROTOCOL_PREFIX + json.dumps(payload) + "\n")
    sys.stdout.flush()


def _summarize(argv: list[str]) -> int:
    """``summarize NUM_POINTS SIZE REPEATS KCOVER``: stream the measurements of one map size."""
    if len(argv) != 4 or argv[3] not in ("0", "1"):
        sys.stderr.write(__doc__)
        return 2
    try:
        from experiments.benchmark.config import SIZES
        from experiments.benchmark.summarize_stage import summarize_worker

        size = SIZES[argv[1]]
        for msg in summarize_worker(int(argv[0]), size, int(argv[2]), argv[3] == "1"):
            _send(msg)
    except Exception as e:  # noqa: BLE001 - report any failure, then exit non-zero
        traceback.print_exc()
        _send({"error": f"{type(e).__name__}: {e}"})
        return 1
    return 0


def main(argv: list[str]) -> int:
    if argv[:1] == ["summarize"]:
        return _summarize(argv[1:])
    if argv[:1] == ["label_scale"] and len(argv) == 4:
        try:  # label_scale ROOT CACHE_DIR MAX_KEYPOINTS
            from pathlib import Path

            from experiments.benchmark.label_scale_stage import label_scale_once

            _send(label_scale_once(Path(argv[1]), Path(argv[2]), max_keypoints=int(argv[3])))
        except Exception as e:  # noqa: BLE001 - report any failure, then exit non-zero
            traceback.print_exc()
            _send({"error": f"{type(e).__name__}: {e}"})
            return 1
        return 0
    if argv[:1] == ["match"] and len(argv) == 4:
        try:
            from experiments.benchmark.config import SIZES
            from experiments.benchmark.match_stage import match_once

            _send(match_once(int(argv[1]), SIZES[argv[2]], argv[3]))
        except Exception as e:  # noqa: BLE001 - report any failure, then exit non-zero
            traceback.print_exc()
            _send({"error": f"{type(e).__name__}: {e}"})
            return 1
        return 0
    if len(argv) != 3:
        sys.stderr.write(__doc__)
        return 2
    stage, what, size_name = argv
    try:
        from experiments.benchmark.config import SIZES, VARIANTS

        size = SIZES[size_name]
        if stage == "groundtruth":
            from experiments.benchmark.groundtruth_stage import groundtruth_once

            _send(groundtruth_once(int(what), size))
            return 0
        variant = VARIANTS[what]
        if variant.malloc:
            from rp_jax.platform import tune_malloc

            tune_malloc()
        if variant.impl == "jax":
            import jax

            n = int(os.environ.get("RP_BENCH_NUM_DEVICES", "1"))
            if n > 1:
                jax.config.update("jax_num_cpu_devices", n)
        from experiments.benchmark.model_benches import make_bench

        bench = make_bench(stage, variant, size)
        _send({"ready": bench.setup()})
    except Exception as e:  # noqa: BLE001 - report any failure, then exit non-zero
        traceback.print_exc()
        _send({"error": f"{type(e).__name__}: {e}"})
        return 1
    for line in sys.stdin:
        command = line.strip()
        if command == "quit":
            break
        if command == "measure" or command.startswith("measure "):
            try:  # "measure KEY": one item of a bench with several (layer_profile)
                key = command[len("measure"):].strip()
                _send(bench.measure(key) if key else bench.measure())
            except Exception as e:  # noqa: BLE001 - as above
                traceback.print_exc()
                _send({"error": f"{type(e).__name__}: {e}"})
                return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
