"""Command line of the benchmark (the predictor of Sec. III-B/C, ground truth of III-D, map
summarization of V-A and localization of V-B).

    python -m experiments.benchmark [STAGE ...] [--out DIR] [--size tiny|full] [--repeats N]
                                    [--quiet]

Stages: train, predict, layers, match, groundtruth, label_scale, summarize, localize
(default: all).

* label_scale: labelling one Webcam-like viewpoint of 1,000, 3,000 and 10,000 frames
  (``--label-scale-frames`` to choose), wall and CPU time, peak memory and records per size,
  and the fit of cost against n; frames are rendered once into DIR/label_scale/world/;

* layers: per-layer forward and forward+backward times, JAX vs PyTorch (``layer_profile``);

* summarize: seconds and peak memory to summarize synthetic maps of 10^4 .. 10^7 points for
  one timestamp (repeatability cached per point), ours vs the K-cover baseline;
* localize: per-query ms of retrieval, 2D-3D matching and PnP-RANSAC, ours vs OpenCV.

Writes ``DIR/benchmark.json`` and ``DIR/benchmark.md``; stages not run this time are kept
from an earlier report of the same size in ``DIR``.
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys

from experiments.benchmark.run import ALL_STAGES, run_benchmark
from rp_jax import command_line, progress


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m experiments.benchmark",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "stages",
        nargs="*",
        default=[],
        metavar="STAGE",
        help=f"stages to run, of {', '.join(ALL_STAGES)} (default all)",
    )
    parser.add_argument("--out", default="runs/benchmark", help="output directory")
    parser.add_argument("--size", choices=("tiny", "full"), default="full",
                        help="size of the synthetic world and maps timed: tiny (tests, "
                        "seconds) or full (default full)")
    parser.add_argument(
        "--repeats", type=int, default=5, help="timed rounds per stage (after warm-up)"
    )
    parser.add_argument(
        "--label-scale-frames", type=int, nargs="+", default=None, metavar="N",
        help="frame counts of the label_scale stage (default 1000 3000 10000 at full size)",
    )
    parser.add_argument(
        "--torch-compile",
        choices=("auto", "yes", "no"),
        default="auto",
        help="also measure torch.compile (auto: at full size only; compiling takes a minute)",
    )
    command_line.add_quiet(parser)
    args = parser.parse_args(argv)
    if args.quiet:
        progress.set_quiet()
    if args.repeats < 1:
        parser.error("--repeats must be >= 1")
    command_line.check_writable_folder(parser, "--out", args.out)
    unknown = [s for s in args.stages if s not in ALL_STAGES]
    if unknown:
        parser.error(f"unknown stage(s) {unknown}; expected some of {list(ALL_STAGES)}")
    stages = args.stages or list(ALL_STAGES)
    torch_compile = (
        args.size == "full" if args.torch_compile == "auto" else args.torch_compile == "yes"
    )
    started = dt.datetime.now().isoformat(timespec="seconds")
    js, md = run_benchmark(
        stages,
        args.out,
        size=args.size,
        repeats=args.repeats,
        torch_compile=torch_compile,
        started=started,
        label_scale_frames=tuple(args.label_scale_frames) if args.label_scale_frames else None,
    )
    print(md.read_text())
    print(f"wrote {js} and {md}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
