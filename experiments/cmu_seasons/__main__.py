"""``python -m experiments.cmu_seasons``: the paper's Extended CMU Seasons experiment (Sec. IV-A).

Builds (or reuses) the dataset, trains the repeatability predictor, evaluates it on the test
slice against the baselines (and per category, Fig. 9) and writes metrics.json, report.md
and the figures into the workdir. Flags (``--help``): --workdir, --manual-dir,
--size tiny|small|full, --data-dir, --config FILE, --config.FIELD=VALUE, --print-config,
--quiet, --cross-validate, --folds.
"""

import sys

from experiments import cli
from experiments.cmu_seasons.config import get_config

if __name__ == "__main__":
    sys.exit(cli.main(None, "cmu_seasons", get_config, __doc__))
