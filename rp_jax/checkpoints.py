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

__all__ = ["CHECKPOINTS_DIR", "BEST_DIR", "state_tree", "writer", "reader", "params_mismatch",
           "restore_params"]

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
      ValueError: the checkpoint's parameters have other names or shapes (checked on its
        metadata before any array is read: a restore that failed half way left orbax's
        reads of the other arrays pending, and each printed a traceback into the
        user's terminal when it was collected or the process exited).
      KeyError or TypeError (from orbax): the checkpoint does not fit otherwise.
    """
    mismatch = params_mismatch(manager.item_metadata(step), abstract_params)
    if mismatch:
        raise ValueError("its parameters differ: " + "; ".join(mismatch))
    device = jax.sharding.SingleDeviceSharding(jax.local_devices()[0])
    target = {"params": jax.tree.map(
        lambda s: jax.ShapeDtypeStruct(s.shape, s.dtype, sharding=device), abstract_params)}
    restored = manager.restore(step, args=ocp.args.PyTreeRestore(
        item=target, restore_args=ocp.checkpoint_utils.construct_restore_args(target),
        partial_restore=True))
    return jax.tree.map(np.asarray, restored["params"])


def params_mismatch(metadata, abstract_params, *, at_most: int = 3) -> list[str]:
    """How a checkpoint's saved parameters differ from the expected ones, by name and shape.

    Args:
      metadata: ``manager.item_metadata(step)`` of a saved ``state_tree``.
      abstract_params: the expected params tree (anything with ``.shape``).
      at_most: how many differences to name; the rest are counted.

    Returns:
      One line per difference (``'encoder.dense.kernel: saved (128, 32), expected
      (128, 48)'``, a parameter only saved or only expected), empty when they agree.
      Dtypes are not compared: the restore casts.
    """
    tree = getattr(metadata, "tree", metadata)
    saved = _shapes(tree["params"]) if "params" in tree else {}
    expected = _shapes(abstract_params)
    lines = []
    for name in sorted(saved.keys() | expected.keys()):
        if name not in expected:
            lines.append(f"{name}: saved {saved[name]}, not expected")
        elif name not in saved:
            lines.append(f"{name}: expected {expected[name]}, not saved")
        elif saved[name] != expected[name]:
            lines.append(f"{name}: saved {saved[name]}, expected {expected[name]}")
    if len(lines) > at_most:
        lines = lines[:at_most] + [f"and {len(lines) - at_most} more"]
    return lines


def _shapes(tree) -> dict[str, tuple[int, ...]]:
    """``{'a.b.kernel': shape}`` of a tree's leaves (``()`` for a leaf without a shape)."""
    return {".".join(str(getattr(k, "key", getattr(k, "idx", k))) for k in path):
            tuple(getattr(leaf, "shape", ())) for path, leaf in
            jax.tree_util.tree_leaves_with_path(tree)}
