"""Orbax checkpoints of a training run: written by ``rp_jax.train``, read by ``rp_jax.predict``.

A checkpoint holds a train state as the tree ``{"params", "opt_state", "step"}``
(``state_tree``). A workdir keeps the latest ones under ``checkpoints/`` and, with
``config.train.keep_best``, the best validation epoch under ``best/``. ``restore_params`` reads the
parameters alone back (an orbax partial restore), so loading a predictor needs neither the
optimiser nor ``rp_jax.train``.
"""

from __future__ import annotations

import os
from pathlib import Path

import jax
import numpy as np
import orbax.checkpoint as ocp

__all__ = ["CHECKPOINTS_DIR", "BEST_DIR", "state_tree", "writer", "reader", "restore_params"]

CHECKPOINTS_DIR = "checkpoints"  # the latest train states of a workdir
BEST_DIR = "best"  # the best validation epoch (config.train.keep_best)


def state_tree(state) -> dict:
    """What a checkpoint holds of a Flax ``TrainState``: params, optimiser state and step."""
    return {"params": state.params, "opt_state": state.opt_state, "step": state.step}


def writer(directory: str | os.PathLike, max_to_keep: int) -> ocp.CheckpointManager:
    """A manager that saves ``state_tree``s in ``directory`` (created) and keeps the last few.

    It also restores whole states (``ocp.args.StandardRestore(state_tree(state))``): how a
    run resumes.
    """
    return ocp.CheckpointManager(
        Path(directory).absolute(),
        options=ocp.CheckpointManagerOptions(max_to_keep=max_to_keep, create=True),
    )


def reader(directory: str | os.PathLike) -> ocp.CheckpointManager:
    """A read-only manager whose ``restore`` can read part of a saved state (``restore_params``)."""
    return ocp.CheckpointManager(Path(directory).absolute(),
                                 item_handlers=ocp.PyTreeCheckpointHandler())


def restore_params(manager: ocp.CheckpointManager, step: int, abstract_params):
    """Restore the params of a saved train state onto this host's first device, as numpy.

    The checkpoint may come from any device layout (e.g. 2 forced CPU devices).
    ``abstract_params`` (shapes and dtypes, e.g. from ``jax.eval_shape`` of the model's init)
    fixes the tree, so a checkpoint of another model config fails here.

    Args:
      manager: a ``reader``.
      step: the checkpoint's step.
      abstract_params: the expected params tree of ``jax.ShapeDtypeStruct`` (or arrays).

    Raises:
      ValueError, KeyError or TypeError (from orbax): the checkpoint does not fit.
    """
    device = jax.sharding.SingleDeviceSharding(jax.local_devices()[0])
    target = {"params": jax.tree.map(
        lambda s: jax.ShapeDtypeStruct(s.shape, s.dtype, sharding=device), abstract_params)}
    restored = manager.restore(step, args=ocp.args.PyTreeRestore(
        item=target, restore_args=ocp.checkpoint_utils.construct_restore_args(target),
        partial_restore=True))
    return jax.tree.map(np.asarray, restored["params"])
