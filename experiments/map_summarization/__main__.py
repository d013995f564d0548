"""``python -m experiments.map_summarization``: map summarization with RP (Sec. V, Fig. 11).

Trains the repeatability predictor on RobotCar, builds the map of Extended CMU Seasons
slice 8 from its reference model on each world seed, summarizes it at 50 %...90 % pruned
with the paper's RP protocol (rp_paper), the recommended RP method (rp), K-cover, random,
most-observed, maplab and the oracles (experiments/map_summarization/methods.py), localizes
the queries of every date and writes metrics.json (accuracy with 95 % bootstrap intervals,
the paired difference to K-cover with a 95 % interval clustered by world seed and date,
exact McNemar p-values as exploratory figures, inlier and selecting AUCs), report.md, the
Fig. 11 figures and per-seed submissions into the workdir. Flags: --workdir, --manual-dir,
--size tiny|small|full (default small here), --seeds 0,1,2, --processes N (seeds evaluated
at once, each in a process of its own), --data-dir, --config FILE, --config.FIELD=VALUE,
--print-config, --quiet.
"""

import argparse
import sys

from experiments import cli
from experiments.map_summarization.config import get_config

NAME = "map_summarization"
# The first run of the default renders and labels the outcome scorer's 48 label slices
# (about an hour on 2 cores, cached in the workdir and reused by a re-run; what each
# stage took: docs/results/map_summarization.md, "Cost").
DEFAULT_SIZE = "small"


def _add_flags(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seeds", type=cli.seed_list, default=None, metavar="A,B,...",
                        help="synthetic world seeds the maps are built on (default "
                        "--config.map.seeds, 0,1,2)")
    from experiments.map_summarization.seed_processes import add_processes

    add_processes(parser)


def parse(argv: list[str] | None = None):
    """(config, workdir) of the command line; ``--size`` defaults to ``DEFAULT_SIZE``."""
    config, workdir, _ = _parse(argv)
    return config, workdir


def _parse(argv):
    config, workdir, args = cli.parse_flags(argv, NAME, get_config, __doc__,
                                            default_size=DEFAULT_SIZE, add_flags=_add_flags)
    if args.seeds is not None:
        config.map.seeds = args.seeds
    if args.processes is not None:
        config.map.processes = args.processes
    return config, workdir, args


def main(argv: list[str] | None = None) -> int:
    """Parse the flags, run the experiment and print the accuracy table."""
    config, workdir, args = _parse(argv)
    from rp_jax import platform, progress

    if args.quiet:
        progress.set_quiet()
    platform.configure_cpu()
    from experiments.map_summarization import experiment
    from experiments.map_summarization.config import validate
    from rp_jax.sources.layout import LayoutError

    try:
        validate(config, workdir)  # every field, the downloads, slice and dates: before any work
    except ValueError as e:
        print(f"python -m experiments.{NAME}: error: {e}", file=sys.stderr)
        return 2
    from experiments.map_summarization.seed_processes import SeedProcessError

    try:
        metrics = experiment.run(config, workdir)
    except LayoutError as e:  # a --manual-dir that is not the dataset's layout
        print(f"python -m experiments.{NAME}: error: {e}", file=sys.stderr)
        return 2
    except SeedProcessError as e:
        print(f"python -m experiments.{NAME}: error: {e}", file=sys.stderr)
        return 1
    print(f"wrote {workdir}/metrics.json, report.md and {len(metrics['figures'])} figures")
    print(
        f"{metrics['queries']} queries, seeds {metrics['seeds']}; accuracy (%) within "
        f"(5 m, 10 deg) at {', '.join(metrics['ratios'])} pruned (* the clustered 95 % interval "
        "of the difference to K-cover excludes zero):"
    )
    for method in metrics["methods"]:
        cells = []
        for r in metrics["ratios"]:
            a = metrics["accuracy"][method][r]["5m_10deg"]
            lo, hi = metrics["paired_interval"][method][r]["5m_10deg"]
            cells.append(f"{a:5.1f}{'*' if (lo > 0 or hi < 0) else ' '}")
        auc = metrics["selecting_auc"].get(method)
        print(
            f"  {method:16s} " + " ".join(cells)
            + (f"   selecting AUC {auc:.3f}" if auc is not None else "")
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
