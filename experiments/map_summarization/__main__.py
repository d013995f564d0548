"""``python -m experiments.map_summarization``: map summarization with RP (Sec. V, Fig. 11).

Trains the repeatability predictor on RobotCar, builds the map of Extended CMU Seasons
slice 8 from its reference model on each world seed, summarizes it at 50 %...90 % pruned
with the paper's RP protocol (rp_paper), the recommended RP method (rp), K-cover, random,
most-observed and two oracles, localizes the queries of every date and writes metrics.json
(accuracy with 95 % bootstrap intervals, paired counts and exact McNemar p-values against
K-cover, inlier AUCs), report.md, the Fig. 11 figures and per-seed submissions into the
workdir. Flags: --workdir, --data-dir, --size tiny|small|full (default small here),
--seeds 0,1,2, --tfds-dir, --config.FIELD=VALUE.
"""

import sys

from experiments import cli
from experiments.map_summarization.config import get_config

NAME = "map_summarization"
DEFAULT_SIZE = "small"  # the whole run in under 20 minutes on 2 cores (see README)


def _pop_seeds(argv: list[str]) -> tuple[list[str], tuple[int, ...] | None]:
    """Remove ``--seeds A,B`` / ``--seeds=A,B`` from argv; returns (rest, seeds or None)."""
    rest, seeds = [], None
    i = 0
    while i < len(argv):
        a = argv[i]
        text = None
        if a == "--seeds":
            if i + 1 >= len(argv):
                raise SystemExit("--seeds needs a value such as 0,1,2")
            text, i = argv[i + 1], i + 2
        elif a.startswith("--seeds="):
            text, i = a.split("=", 1)[1], i + 1
        else:
            rest.append(a)
            i += 1
            continue
        try:
            seeds = tuple(int(s) for s in text.split(",") if s.strip())
        except ValueError:
            raise SystemExit(
                f"--seeds {text}: expected comma-separated integers such as 0,1,2"
            ) from None
        if not seeds or any(s < 0 for s in seeds):
            raise SystemExit(f"--seeds {text}: expected non-negative integers such as 0,1,2")
    return rest, seeds


def parse(argv: list[str] | None = None):
    """(config, workdir) of the command line; ``--size`` defaults to ``DEFAULT_SIZE``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    argv, seeds = _pop_seeds(argv)
    if not any(a == "--size" or a.startswith("--size=") for a in argv):
        argv = ["--size", DEFAULT_SIZE, *argv]
    config, workdir = cli.parse(argv, NAME, get_config, __doc__)
    if seeds is not None:
        config.map.seeds = seeds
    return config, workdir


def main(argv: list[str] | None = None) -> int:
    """Parse the flags, run the experiment and print the accuracy table."""
    config, workdir = parse(argv)
    from rp_jax import platform

    platform.configure_cpu()
    from experiments.map_summarization import experiment
    from rp_jax.sources.layout import LayoutError

    try:
        experiment.methods_of(config)  # a bad recipe name fails here, before any work
    except ValueError as e:
        print(f"python -m experiments.{NAME}: error: {e}", file=sys.stderr)
        return 2
    try:
        metrics = experiment.run(config, workdir)
    except LayoutError as e:  # a --data-dir that is not the dataset's layout
        print(f"python -m experiments.{NAME}: error: {e}", file=sys.stderr)
        return 2
    print(f"wrote {workdir}/metrics.json, report.md and {len(metrics['figures'])} figures")
    print(
        f"{metrics['queries']} queries, seeds {metrics['seeds']}; accuracy (%) within "
        f"(5 m, 10 deg) at {', '.join(metrics['ratios'])} pruned (* p < 0.05 vs K-cover):"
    )
    for method in metrics["methods"]:
        cells = []
        for r in metrics["ratios"]:
            a = metrics["accuracy"][method][r]["5m_10deg"]
            p = metrics["paired"][method][r]["5m_10deg"]["p"]
            cells.append(f"{a:5.1f}{'*' if p < 0.05 and method != 'kcover' else ' '}")
        auc = metrics["inlier_auc"].get(method)
        print(
            f"  {method:16s} " + " ".join(cells) + (f"   AUC {auc:.3f}" if auc is not None else "")
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
