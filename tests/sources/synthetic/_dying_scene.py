"""A scene whose building kills the process building it: a rendering worker that dies, as
one the out-of-memory killer ends (tests/sources/synthetic/test_frame_jobs.py)."""

import dataclasses
import os
import signal

from rp_jax.sources.synthetic.frame_jobs import SceneSpec


@dataclasses.dataclass(frozen=True)
class DyingScene(SceneSpec):
    def build(self):
        os.kill(os.getpid(), signal.SIGKILL)
