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
MODEL_FIELDS = ("conditions", "conditional_hidden", "time_harmonics", "decay_time_scales")


def get_config(arg: str = "small") -> ml_collections.ConfigDict:
    dataset, _, size = arg.rpartition(":")
    dataset = dataset or "webcam_clipart"
    config = importlib.import_module(f"experiments.{dataset}.config").get_config(size)
    # Nothing is chosen on held-out points: every model trains its fixed number of epochs.
    config.train.keep_best = False
    config.input.validation_fraction = 0.0
    return config


def decay_time_scales(config: ml_collections.ConfigDict) -> tuple[float, ...]:
    """``config.model.decay_time_scales`` ("1,3,10") as years; () for "" (no decay basis).

    Raises:
      ValueError: an entry that is not a number of years > 0 (the message names the field).
    """
    text = config.model.get("decay_time_scales", "")
    items = [s.strip() for s in str(text).split(",") if s.strip()]
    try:
        years = tuple(float(s) for s in items)
    except ValueError:
        years = ()
    if len(years) != len(items) or any(not y > 0 for y in years):
        raise ValueError(f"config.model.decay_time_scales={text!r}: expected a comma list of "
                         "years > 0 (e.g. 1,3,10), or '' for no decay basis")
    return years


def paper_config(config: ml_collections.ConfigDict) -> ml_collections.ConfigDict:
    """``config`` with the conditional fields at their defaults: what the paper's predictor
    trains with (so its workdir is the same whatever the conditional variant)."""
    from rp_jax.configs import default

    out = ml_collections.ConfigDict(config.to_dict())
    defaults = default.get_config().model
    for field in MODEL_FIELDS:
        out.model[field] = defaults[field]
    return out
