"""``python -m experiments.map_summarization``: map summarization with RP (Sec. V, Fig. 11).

Trains the repeatability predictor on RobotCar, builds the map of Extended CMU Seasons
slice 8 from its reference model, summarizes it at 10 %...90 % pruned with RP, K-cover,
random and most-observed, localizes the Mar 04 queries and writes metrics.json, report.md,
the Fig. 11 figures and the submission files into the workdir. Flags: --workdir,
--data-dir, --size tiny|small|full (default small here), --tfds-dir, --config.FIELD=VALUE.
"""

import sys

from experiments import cli
from experiments.map_summarization.config import get_config

NAME = "map_summarization"
DEFAULT_SIZE = "small"  # the whole run in about 15 minutes on 2 cores (see config.py)


def parse(argv: list[str] | None = None):
    """(config, workdir) of the command line; ``--size`` defaults to ``DEFAULT_SIZE``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not any(a == "--size" or a.startswith("--size=") for a in argv):
        argv = ["--size", DEFAULT_SIZE, *argv]
    return cli.parse(argv, NAME, get_config, __doc__)


def main(argv: list[str] | None = None) -> int:
    """Parse the flags, run the experiment and print the accuracy table."""
    config, workdir = parse(argv)
    from rp_jax import platform

    platform.configure_cpu()
    from rp_jax.mapsum import experiment

    metrics = experiment.run(config, workdir)
    acc = metrics["accuracy"]
    print(f"wrote {workdir}/metrics.json, report.md and {len(metrics['figures'])} figures")
    print("accuracy (%) within (5 m, 10 deg) at " + ", ".join(metrics["ratios"]) + " pruned:")
    for method, per_ratio in acc.items():
        print(
            f"  {method:14s} "
            + " ".join(f"{per_ratio[r]['5m_10deg']:5.1f}" for r in metrics["ratios"])
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
