"""``python -m experiments.webcam_clipart``: the paper's Webcam Clip Art experiment (Sec. IV-A).

Builds (or reuses) the dataset, trains the repeatability predictor, evaluates it on the test
viewpoint against the baselines and writes metrics.json, report.md and the figures into the
workdir. Flags (``--help``): --workdir, --manual-dir, --size tiny|small|full, --data-dir,
--config FILE, --config.FIELD=VALUE, --print-config, --quiet, --cross-validate, --folds.
"""

import sys

from experiments import cli
from experiments.webcam_clipart.config import get_config

if __name__ == "__main__":
    sys.exit(cli.main(None, "webcam_clipart", get_config, __doc__))
