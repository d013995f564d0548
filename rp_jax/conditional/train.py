"""Fitting the conditional predictor on per-pair outcomes (optax; pure, jitted steps).

``fit(net, arrays, settings)`` minimises the binary cross-entropy of the known pairs
(``model.pair_loss``) with AdamW, global-norm clipping and a warm-up cosine schedule, the
patches jittered as the paper's predictor's are (``rp_jax.train.augment_patches``). The
order of the points is a pure function of (seed, epoch), as in ``rp_jax.train``. Each
step encodes a batch of points once and scores all K targets of each.
``predict_probabilities`` and ``predict_t_vectors`` evaluate a trained model.
"""

from __future__ import annotations

import dataclasses
import functools
import logging

import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax.training import train_state

from rp_jax import model as model_lib
from rp_jax.conditional import model as cmodel
from rp_jax.conditional.pairs import PairArrays, batch
from rp_jax.train import augment_patches

__all__ = ["FitSettings", "fit", "predict_probabilities", "predict_t_vectors", "train_step"]

log = logging.getLogger(__name__)


@dataclasses.dataclass(frozen=True)
class FitSettings:
    """How to fit (the run config's ``train`` and ``input`` fields that apply)."""

    num_epochs: float = 8
    batch_size: int = 128
    learning_rate: float = 2e-3
    warmup_epochs: float = 1.0
    weight_decay: float = 1e-4
    grad_clip: float = 1.0
    seed: int = 0
    brightness: float = 0.0
    contrast: float = 0.0
    flip: bool = False


def _model_inputs(b: dict):
    return (model_lib.preprocess_patches(b["patch"]), b["xy_normalized"], b["capture"],
            b["target"], b["category"])


def train_step(state: train_state.TrainState, b: dict, settings: FitSettings):
    """One AdamW step on the masked pair BCE (pure; jit it)."""
    patches, xy, capture, target, category = _model_inputs(b)
    if settings.brightness or settings.contrast or settings.flip:
        rng = jax.random.fold_in(jax.random.key(settings.seed), state.step)
        patches = augment_patches(patches, rng, brightness=settings.brightness,
                                  contrast=settings.contrast, flip=settings.flip)

    def loss_fn(params):
        logits = state.apply_fn({"params": params}, patches, xy, capture, target, category)
        return cmodel.pair_loss(logits, b["outcome"], b["mask"])

    loss, grads = jax.value_and_grad(loss_fn)(state.params)
    return state.apply_gradients(grads=grads), {"loss": loss,
                                                "grad_norm": optax.global_norm(grads)}


@functools.lru_cache(maxsize=8)
def _compiled_step(settings: FitSettings):
    """The jitted step of ``settings`` (one compile per model and batch shape)."""
    return jax.jit(lambda s, b: train_step(s, b, settings), donate_argnums=(0,))


@functools.lru_cache(maxsize=8)
def _compiled_init(net: cmodel.ConditionalPredictor):
    return jax.jit(lambda rng: cmodel.init_params(net, rng))


@functools.lru_cache(maxsize=8)
def _compiled_eval(net: cmodel.ConditionalPredictor, num_timestamps: int):
    """Jitted (params, batch) -> probabilities [B, K] and the T-vector with its mask."""

    def evaluate(params, b):
        p = jax.nn.sigmoid(net.apply({"params": params}, *_model_inputs(b)))
        vec, mask = cmodel.t_vector(p, b["target_slot"], b["target_valid"], b["own_target"],
                                    num_timestamps)
        return p, vec, mask

    return jax.jit(evaluate)


def _order(n: int, seed: int, epoch: int) -> np.ndarray:
    return np.random.default_rng(np.random.SeedSequence([seed, epoch])).permutation(n)


def fit(net: cmodel.ConditionalPredictor, arrays: PairArrays, settings: FitSettings, *,
        progress: bool = True) -> tuple[dict, list[dict]]:
    """Train ``net`` on ``arrays``; returns (params, one metrics dict per epoch).

    Raises:
      ValueError: fewer points than one batch, or a non-finite loss.
    """
    from rp_jax.progress import bar as tqdm  # the one progress helper

    n = len(arrays)
    steps_per_epoch = n // settings.batch_size
    if steps_per_epoch == 0:
        raise ValueError(f"{n} training points is fewer than one batch of {settings.batch_size}")
    total = max(int(round(settings.num_epochs * steps_per_epoch)), 2)
    warmup = max(1, min(int(settings.warmup_epochs * steps_per_epoch), total - 1))
    schedule = optax.warmup_cosine_decay_schedule(0.0, settings.learning_rate, warmup, total)
    tx = optax.chain(optax.clip_by_global_norm(settings.grad_clip),
                     optax.adamw(schedule, weight_decay=settings.weight_decay))
    params = _compiled_init(net)(jax.random.key(settings.seed))
    state = train_state.TrainState.create(apply_fn=net.apply, params=params, tx=tx)
    step = _compiled_step(settings)
    history, done, epoch = [], 0, 0
    while done < total:
        order = _order(n, settings.seed, epoch)
        steps = min(steps_per_epoch, total - done)
        losses = []
        for i in tqdm(range(steps), desc=f"conditional epoch {epoch + 1}", leave=False,
                      disable=not progress):
            idx = order[i * settings.batch_size:(i + 1) * settings.batch_size]
            state, m = step(state, batch(arrays, idx))
            losses.append(m["loss"])
        loss = float(jnp.mean(jnp.stack(losses)))
        if not np.isfinite(loss):
            raise ValueError(f"conditional training: loss {loss} in epoch {epoch + 1} "
                             f"(learning_rate={settings.learning_rate}); lower it")
        history.append({"epoch": epoch + 1, "train_bce": loss})
        log.info("conditional epoch %d: train BCE %.4f", epoch + 1, loss)
        done += steps
        epoch += 1
    return jax.device_get(state.params), history


def _batches(arrays: PairArrays, batch_size: int):
    n = len(arrays)
    for start in range(0, n, batch_size):
        idx = np.arange(start, min(start + batch_size, n))
        yield idx, batch(arrays, idx, batch_size)


def predict_probabilities(net, params, arrays: PairArrays, batch_size: int = 256) -> np.ndarray:
    """[N, K] probability of each point's outcome in each target of its table."""
    evaluate = _compiled_eval(net, 1)
    out = np.zeros(arrays.points["outcome"].shape, np.float32)
    for idx, b in _batches(arrays, batch_size):
        out[idx] = np.asarray(evaluate(params, b)[0])[: len(idx)]
    return out


def predict_t_vectors(net, params, arrays: PairArrays, num_timestamps: int,
                      batch_size: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """[N, T] mean probability over each timestamp's images of the point's viewpoint (own
    image counted as an inlier, Sec. III-D) and its mask: the paper's y^j, predicted."""
    evaluate = _compiled_eval(net, num_timestamps)
    n = len(arrays)
    vec, mask = np.zeros((n, num_timestamps), np.float32), np.zeros((n, num_timestamps), bool)
    for idx, b in _batches(arrays, batch_size):
        _, v, m = evaluate(params, b)
        vec[idx], mask[idx] = np.asarray(v)[: len(idx)], np.asarray(m)[: len(idx)]
    return vec, mask
