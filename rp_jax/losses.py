"""The training loss of Sec. III-C.

The paper trains with the mean squared error (1/N) sum_i ||y_i - y_hat_i||_2^2: a sum over
the T timestamps, a mean over the N interest points. Two masks extend it without changing
it where everything is valid:

* ``label_mask`` [N, T]: False where slot j had no images (its y^j is undefined, Sec.
  III-D); those terms are left out of the sum.
* ``example_mask`` [N]: False for padding examples of a fixed-shape batch; the mean is
  over real examples only.
"""

from __future__ import annotations

import jax.numpy as jnp

__all__ = ["mse", "mae"]


def _masks(pred, label_mask, example_mask):
    lm = jnp.ones(pred.shape, jnp.float32) if label_mask is None else label_mask.astype(jnp.float32)
    em = (jnp.ones(pred.shape[:1], jnp.float32) if example_mask is None
          else example_mask.astype(jnp.float32))
    return lm * em[:, None], em


def mse(pred, label, label_mask=None, example_mask=None) -> jnp.ndarray:
    """(1/N) sum_i sum_j m_ij (y_ij - y_hat_ij)^2 over valid examples (Sec. III-C)."""
    m, em = _masks(pred, label_mask, example_mask)
    return jnp.sum(m * (pred - label) ** 2) / jnp.maximum(jnp.sum(em), 1.0)


def mae(pred, label, label_mask=None, example_mask=None) -> jnp.ndarray:
    """Mean absolute error per valid (example, slot) entry: an evaluation figure."""
    m, _ = _masks(pred, label_mask, example_mask)
    return jnp.sum(m * jnp.abs(pred - label)) / jnp.maximum(jnp.sum(m), 1.0)
