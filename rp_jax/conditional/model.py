"""The conditional repeatability predictor: one image pair's outcome, not a T-vector.

    logit = score(encode(patch, xy, capture [, category]), capture, target)

``encode`` runs the patch encoder of the paper's predictor (``rp_jax.model.PatchEncoder``)
once per interest point and mixes in its position, its capture time and (by
``conditions``) the capture's sun, weather and appearance and the point's semantic class;
``score`` turns that code and any number of targets (time, its difference to the capture,
the target's sun, weather and appearance) into one logit each: the log-odds that the point
is re-detected and matched as an inlier in an image taken then. ``__call__`` does both, for
[B] points and [B, K] targets. Everything is a pure function of ``params``: ``jax.jit``,
``jax.vmap`` (over targets or points) and ``jax.grad`` compose with it.

With ``decay_time_scales`` (opt-in; issue 17's long-term decay) the logit gains
``sum_b c_b(code) * phi_b(capture, target)``: the basis ``inputs.decay_basis`` of the years
between capture and target, whose coefficients ``c`` the network predicts from the point's
code (a shop sign decays faster than a wall); the moments then need ``year``. Empty (the
default) adds no parameter and leaves every output as it was.

The paper's T-vector is the mean probability over a timestamp's targets: ``t_vector`` for
targets that carry a slot (a viewpoint's images, the capture's own image counted as an
inlier as in Sec. III-D), ``t_vector_at_slots`` for the slot times of given days.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import flax.linen as nn
import jax
import jax.numpy as jnp
import optax

from rp_jax import categories
from rp_jax.conditional import inputs
from rp_jax.model import PatchEncoder

__all__ = [
    "ConditionalPredictor",
    "init_params",
    "pair_loss",
    "t_vector",
    "t_vector_at_slots",
]

_NUM_CATEGORIES = max(categories.NAMES) + 1  # ids 0..OTHER; -1 unknown is one more row
_CATEGORY_FEATURES = 8


class ConditionalPredictor(nn.Module):
    """Patch, position, capture and target -> logit of the pair's outcome.

    Attributes:
      conditions: a subset of ``inputs.CONDITIONS`` (empty: time only).
      encoder_channels, encoder_features, dtype: the patch encoder (as the paper's RP).
      hidden: width of the point code and the pair layers.
      harmonics: sin/cos multiples of the time-of-day angle.
      decay_time_scales: the long-term decay basis's time scales in years (e.g.
        ``inputs.DECAY_TIME_SCALES_YEARS``); empty: no decay term.
      decay_periodic: the basis also times the target's day and year waves.
    """

    conditions: tuple[str, ...] = ()
    encoder_channels: Sequence[int] = (64, 64, 128)
    encoder_features: int = 128
    hidden: int = 128
    harmonics: int = 2
    decay_time_scales: tuple[float, ...] = ()
    decay_periodic: bool = False
    dtype: Any = jnp.float32

    def setup(self):
        unknown = set(self.conditions) - set(inputs.CONDITIONS)
        if unknown:
            raise ValueError(f"unknown conditions {sorted(unknown)}; known {inputs.CONDITIONS}")
        self.patch_encoder = PatchEncoder(self.encoder_channels, self.encoder_features,
                                          self.dtype)
        if "semantics" in self.conditions:
            self.category_embedding = nn.Embed(_NUM_CATEGORIES + 1, _CATEGORY_FEATURES)
        self.point1 = nn.Dense(self.hidden)
        self.point2 = nn.Dense(self.hidden)
        self.point_to_pair = nn.Dense(self.hidden)
        self.target_to_pair = nn.Dense(self.hidden)
        self.pair = nn.Dense(self.hidden // 2)
        self.logit = nn.Dense(1)
        if self.decay_time_scales:
            if min(self.decay_time_scales) <= 0:
                raise ValueError(f"decay_time_scales {self.decay_time_scales}: years > 0")
            per_scale = 5 if self.decay_periodic else 1
            # Zero at init: the decay model starts as the model without it.
            self.decay_coefficients = nn.Dense(len(self.decay_time_scales) * per_scale,
                                               kernel_init=nn.initializers.zeros)

    def encode(self, patches, xy, capture, category=None) -> jnp.ndarray:
        """[B, hidden] code of each point (patches preprocessed, ``model.preprocess_patches``)."""
        feat = self.patch_encoder(patches).astype(jnp.float32)
        parts = [feat, jnp.asarray(xy, jnp.float32),
                 inputs.capture_features(capture, self.conditions, self.harmonics)]
        if "semantics" in self.conditions:
            ids = jnp.clip(jnp.asarray(category, jnp.int32) + 1, 0, _NUM_CATEGORIES)
            parts.append(self.category_embedding(ids))
        h = nn.relu(self.point1(jnp.concatenate(parts, axis=-1)))
        return nn.relu(self.point2(h))

    def score(self, code, capture, target) -> jnp.ndarray:
        """[B, K] logits for ``code`` [B, hidden] and targets of shape [B, K]."""
        t = inputs.target_features(capture, target, self.conditions, self.harmonics)
        h = nn.relu(self.point_to_pair(code)[:, None, :] + self.target_to_pair(t))
        logit = self.logit(nn.relu(self.pair(h)))[..., 0]
        if self.decay_time_scales:
            phi = inputs.decay_basis(capture, target, self.decay_time_scales,
                                     self.decay_periodic)
            logit = logit + jnp.einsum("bn,bkn->bk", self.decay_coefficients(code), phi)
        return logit

    def __call__(self, patches, xy, capture, target, category=None) -> jnp.ndarray:
        return self.score(self.encode(patches, xy, capture, category), capture, target)


def _zeros_moment(shape, with_year: bool = False) -> dict:
    keys = (inputs.MOMENT_KEYS + inputs.APPEARANCE_KEYS + inputs.SUN_CAMERA_KEYS
            + ((inputs.YEAR_KEY,) if with_year else ()))
    return {k: jnp.zeros(shape) for k in keys}


def init_params(net: ConditionalPredictor, rng) -> dict:
    """Initial ``params`` (shapes only under ``jax.eval_shape``), compiled as one program
    (as ``rp_jax.model.init_params``: op by op, every layer's operations compile one by one)."""
    year = bool(net.decay_time_scales)

    def init(rng):
        return net.init(rng, jnp.zeros((1, 64, 64, 3)), jnp.zeros((1, 2)),
                        _zeros_moment((1,), year), _zeros_moment((1, 1), year),
                        jnp.zeros((1,), jnp.int32))["params"]

    return jax.jit(init)(rng)


def pair_loss(logits, outcome, example_mask=None) -> jnp.ndarray:
    """Mean binary cross-entropy over the known pairs (``outcome`` 1 / 0; -1 unknown)."""
    known = (outcome >= 0).astype(jnp.float32)
    if example_mask is not None:
        known = known * jnp.asarray(example_mask, jnp.float32)[:, None]
    bce = optax.sigmoid_binary_cross_entropy(logits, (outcome == 1).astype(jnp.float32))
    return jnp.sum(known * bce) / jnp.maximum(jnp.sum(known), 1.0)


def t_vector(probabilities, target_slot, target_valid, own_target, num_timestamps: int):
    """The paper's y^j from pair probabilities: the mean over each timestamp's targets.

    Args:
      probabilities: [B, K] of each point's K targets.
      target_slot: int [B, K] timestamp of each target.
      target_valid: bool [B, K]: targets that count (a readable image; padding does not).
      own_target: bool [B, K]: the point's own image, counted as an inlier (Sec. III-D).
      num_timestamps: T.

    Returns:
      ``(t_vector [B, T], mask [B, T])``: mask False where no target has that timestamp.
    """
    p = jnp.where(own_target, 1.0, probabilities) * target_valid
    onehot = jax.nn.one_hot(target_slot, num_timestamps) * target_valid[..., None]
    count = jnp.sum(onehot, axis=1)
    total = jnp.einsum("bk,bkt->bt", p, onehot)
    return total / jnp.maximum(count, 1.0), count > 0


def t_vector_at_slots(apply_fn: Callable, params, point: dict, capture: dict,
                      slot_moments: dict) -> jnp.ndarray:
    """Mean probability at each timestamp over the given days: [B, T].

    Args:
      apply_fn: ``ConditionalPredictor(...).apply``.
      point: ``patch`` (preprocessed) [B, 64, 64, 3], ``xy_normalized`` [B, 2] and, with
        semantics, ``category`` [B].
      capture: the points' capture moment, arrays [B].
      slot_moments: the targets, arrays [T, M]: timestamp j on day m (time fields and
        conditions), the same for every point.
    """
    variables = {"params": params}
    code = apply_fn(variables, point["patch"], point["xy_normalized"], capture,
                    point.get("category"), method=ConditionalPredictor.encode)
    T, M = jnp.shape(slot_moments["hour"])
    batch = jnp.shape(code)[0]
    flat = {k: jnp.broadcast_to(jnp.reshape(jnp.asarray(v, jnp.float32), (1, T * M)),
                                (batch, T * M))
            for k, v in slot_moments.items()}
    logits = apply_fn(variables, code, capture, flat, method=ConditionalPredictor.score)
    return jnp.mean(jax.nn.sigmoid(logits).reshape(batch, T, M), axis=-1)
