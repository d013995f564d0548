"""One process of the multi-process training test (tests/test_distributed.py).

Run through the launcher, one per process::

    python -m rp_jax.distributed --coordinator 127.0.0.1:PORT --num-processes 2 \\
        --process-id P tests._distributed_train --workdir DIR [--pause-after-epoch K --marker DIR]

It trains ``config()`` on ``sources()`` with ``train.train_and_evaluate``, then process 0
writes the final parameters to ``<workdir>/final_params.npz``. With ``--pause-after-epoch``
it stops after that epoch's checkpoint, writes ``<marker>/<process id>`` and sleeps until
the test kills it.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import jax
import numpy as np

from rp_jax import schedule as schedule_lib
from rp_jax import train
from rp_jax.configs import default
from rp_jax.datasets import input_pipeline as ip
from rp_jax.datasets import learnable_task

SCHEDULE = schedule_lib.preset("webcam_clipart")


def config():
    """A small network and 3 epochs of 8 steps: seconds per run."""
    c = default.get_config()
    c.model.encoder_channels = (16, 16, 32)
    c.model.encoder_features = 32
    c.input.batch_size = 32
    c.eval.batch_size = 64
    c.train.num_epochs = 3
    c.train.learning_rate = 3e-3
    return c


def sources():
    """(train, validation): 256 and 64 points of the learnable task."""
    return tuple(ip.ArraySource(learnable_task.make_learnable_task(n, SCHEDULE, seed=seed),
                                ip.MODEL_KEYS) for n, seed in ((256, 0), (64, 1)))


def flat_params(params) -> dict[str, np.ndarray]:
    """Parameters as ``{"a/b/kernel": array}``."""
    leaves = jax.tree_util.tree_flatten_with_path(train.params_to_numpy(params))[0]
    return {"/".join(str(getattr(k, "key", k)) for k in path): np.asarray(v)
            for path, v in leaves}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--workdir", type=Path, required=True)
    parser.add_argument("--pause-after-epoch", type=int, default=0)
    parser.add_argument("--marker", type=Path, default=None)
    args = parser.parse_args(argv)

    def pause(epoch, _):
        if epoch == args.pause_after_epoch:
            (args.marker / str(jax.process_index())).write_text("paused")
            time.sleep(600)  # killed here by the test

    train_source, val_source = sources()
    state = train.train_and_evaluate(config(), args.workdir, train_source, val_source,
                                     progress=False, on_epoch_end=pause)
    if jax.process_index() == 0:
        np.savez(args.workdir / "final_params.npz", **flat_params(state.params))
    return 0


if __name__ == "__main__":
    sys.exit(main())
