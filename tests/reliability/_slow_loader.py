"""A picklable image loader that never returns: a label worker stuck in its task.

It records the worker's pid as ``<root>/pids/<pid>`` (root: two levels above the image, the
layout of ``tests.groundtruth._scenes.to_disk``), so the test knows whom to look for.
"""

import os
import time
from pathlib import Path


def load_forever(capture):
    pids = Path(capture.image_path).parents[1] / "pids"
    pids.mkdir(exist_ok=True)
    (pids / str(os.getpid())).touch()
    time.sleep(600)
