"""bfloat16 pieces shared by the certified nearest-neighbour searches.

Labelling's all-pairs matching (``rp_jax.groundtruth.matching``, Sec. III-D) and
localization's 2D-3D matching (``rp_jax.localize.matching``, Sec. V-B) both let a bfloat16
matrix product with float32 accumulation *choose* candidates and re-check them exactly;
their certificates differ, the two tools they need are these.
"""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["product", "split3"]


def split3(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Three bfloat16 pieces [..., 3] of ``x`` and what they leave (float64 ``x - sum``).

    The pieces sum to ``x`` to about 2**-24 relative; exactly (a zero residual) for integers
    below 2**24.
    """
    import ml_dtypes

    out = np.empty((*np.shape(x), 3), ml_dtypes.bfloat16)
    rest = np.asarray(x, np.float64)
    for k in range(3):
        out[..., k] = rest.astype(ml_dtypes.bfloat16)
        rest = rest - out[..., k].astype(np.float64)
    return out, rest


@functools.cache
def product():
    """jitted ``(a [M, D], b [N, D]) -> a @ b.T`` [M, N]: bfloat16 inputs, float32 sums."""
    import jax
    import jax.numpy as jnp

    def dot(a, b):
        a, b = a.astype(jnp.bfloat16), b.astype(jnp.bfloat16)
        return jax.lax.dot_general(
            a, b, (((1,), (1,)), ((), ())), preferred_element_type=jnp.float32
        )

    return jax.jit(dot)
