"""Config of the conditional predictor's experiment (issue 17): a Sec. IV-A config plus
the conditional model's fields.

    python -m experiments.conditional --size small --cross-validate --folds 3 \
        --config.model.conditions=sun,weather
    python -m experiments.conditional --size small --cross-validate --folds 3 \
        --ablation time,sun,weather,semantics,sun+weather+semantics

Each fold trains the paper's predictor (``experiments.sec4a.crossval``, unchanged) and the
conditional one on the same training viewpoints and scores both against y^j on the held-out
ones. ``get_config(arg)``: ``arg`` is ``SIZE`` or ``DATASET:SIZE`` (default Webcam Clip
Art). Measured figures: the README's "Beyond the paper".
"""

import importlib

import ml_collections

# The conditional predictor's fields of config.model (defaults in rp_jax/configs/default.py);
# the paper's predictor is trained with them at their defaults (``paper_config``).
MODEL_FIELDS = ("conditions", "conditional_hidden", "time_harmonics")


def get_config(arg: str = "small") -> ml_collections.ConfigDict:
    dataset, _, size = arg.rpartition(":")
    dataset = dataset or "webcam_clipart"
    config = importlib.import_module(f"experiments.{dataset}.config").get_config(size)
    # Nothing is chosen on held-out points: every model trains its fixed number of epochs.
    config.train.keep_best = False
    config.input.validation_fraction = 0.0
    return config


def paper_config(config: ml_collections.ConfigDict) -> ml_collections.ConfigDict:
    """``config`` with the conditional fields at their defaults: what the paper's predictor
    trains with (so its workdir is the same whatever the conditional variant)."""
    from rp_jax.configs import default

    out = ml_collections.ConfigDict(config.to_dict())
    defaults = default.get_config().model
    for field in MODEL_FIELDS:
        out.model[field] = defaults[field]
    return out
