"""A variant of the conditional predictor (issue 17): its name, its network and the
parameters a run saved for it; read by the cross-validation that trains the variants
(``crossval``) and by the figures drawn from them (``figures``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from experiments.conditional import config as config_lib

__all__ = ["load_params", "network", "variant_name"]


def variant_name(conditions: tuple[str, ...]) -> str:
    """``("sun", "weather")`` -> ``"sun+weather"``; no condition -> ``"time"``."""
    return "+".join(conditions) if conditions else "time"


def network(config, conditions):
    """The ``ConditionalPredictor`` of a variant, of the config's model widths."""
    from rp_jax.conditional.model import ConditionalPredictor
    from rp_jax.model import DTYPES

    m = config.model
    return ConditionalPredictor(conditions=conditions,
                                encoder_channels=tuple(m.encoder_channels),
                                encoder_features=int(m.encoder_features),
                                hidden=int(m.conditional_hidden),
                                harmonics=int(m.time_harmonics), dtype=DTYPES[m.dtype],
                                decay_time_scales=config_lib.decay_time_scales(config))


def load_params(net, path: Path):
    """The params a run saved (``params.msgpack``) for the network ``net``."""
    import jax
    from flax import serialization

    from rp_jax.conditional import model as cmodel

    template = jax.eval_shape(lambda: cmodel.init_params(net, jax.random.key(0)))
    template = jax.tree.map(lambda s: np.zeros(s.shape, s.dtype), template)
    return serialization.from_bytes(template, path.read_bytes())
