"""``python -m experiments.robotcar_day``: the RobotCar RP over the whole day (Sec. IV-A's
evaluation of Sec. IV-B-1's predictor, T = 24 hourly timestamps instead of 9).

Builds (or reuses) the ``robotcar_day`` dataset (the synthetic world's ``robotcar_day``
preset, or a download with ``--manual-dir``), trains the repeatability predictor on its
training viewpoints, evaluates it on the held-out ones against the baselines and writes
metrics.json, report.md and the figures into the workdir: Fig. 6's average curve is the
daily curve, with its fall at dusk and night. Flags (``--help``): --workdir, --manual-dir,
--size tiny|small|full, --data-dir, --config FILE, --config.FIELD=VALUE, --print-config,
--quiet, --cross-validate, --folds.
"""

import sys

from experiments import cli
from experiments.robotcar_day.config import get_config

if __name__ == "__main__":
    sys.exit(cli.main(None, "robotcar_day", get_config, __doc__, default_size="small"))
