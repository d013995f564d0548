"""Tests of rp_jax.checkpoints: what a saved train state holds and how its params are read."""

import jax
import numpy as np

from rp_jax import checkpoints


def _sds(*shape):
    return jax.ShapeDtypeStruct(shape, np.float32)


def test_params_mismatch_names_each_difference_by_name_and_shape():
    expected = {"fc1": {"kernel": _sds(36, 64), "bias": _sds(64)},
                "proj": {"kernel": _sds(512, 48)}, "gem": {"p": _sds(1)}}
    saved = {"params": {"fc1": {"kernel": _sds(36, 64), "bias": _sds(64)},
                        "proj": {"kernel": _sds(512, 32)}, "extra": {"w": _sds(2)}},
             "step": _sds()}
    assert checkpoints.params_mismatch(saved, expected) == [
        "extra.w: saved (2,), not expected",
        "gem.p: expected (1,), not saved",
        "proj.kernel: saved (512, 32), expected (512, 48)",
    ]
    same = {"params": expected, "opt_state": {}, "step": _sds()}
    assert checkpoints.params_mismatch(same, expected) == []
    # Only names and shapes: the restore casts dtypes.
    bf16 = {"params": jax.tree.map(lambda s: jax.ShapeDtypeStruct(s.shape, jax.numpy.bfloat16),
                                   expected)}
    assert checkpoints.params_mismatch(bf16, expected) == []


def test_params_mismatch_counts_what_it_does_not_name():
    expected = {f"w{i}": _sds(i + 1) for i in range(5)}
    lines = checkpoints.params_mismatch({"params": {}}, expected, at_most=2)
    assert lines == ["w0: expected (1,), not saved", "w1: expected (2,), not saved", "and 3 more"]
