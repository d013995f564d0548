"""Default configuration of the repeatability predictor's training (Sec. III-B, III-C).

Run it on the built-in learnable task:

    python -m experiments.demo --workdir runs/demo

Expected: validation MSE far below the per-slot-mean baseline's (both printed), in about a
minute on 2 CPU cores. Experiments import this and override only what differs.

The fields are grouped as big_vision groups them, by what they describe:

- ``seed``: parameter init and the data order;
- ``input``: the records and how they are batched and augmented;
- ``model``: the network (Sec. III-B), its time input included;
- ``train``: optimisation, checkpoints and devices;
- ``eval``: validation, prediction and baselines.

Which fields make a checkpoint (a workdir resumes only under the same values) and which are
free to change between runs is ``rp_jax.train.MODEL_FIELDS`` / ``DATA_FIELDS``. Config
files written before the grouping (flat ``config.json``) are read through ``upgrade``.
"""

import ml_collections


def get_config() -> ml_collections.ConfigDict:
    config = ml_collections.ConfigDict()
    config.seed = 0  # seeds parameter init and the data order (with the epoch)

    # The records (rp_jax.datasets) and their batches.
    i = config.input = ml_collections.ConfigDict()
    i.dataset = "learnable_task"  # "learnable_task", or set by an experiment
    i.schedule = "webcam_clipart"  # the labels' timestamps (rp_jax.schedule preset): T
    i.num_train_points = 6000  # learnable_task only: training points
    i.num_val_points = 1000  # learnable_task only: validation points
    i.batch_size = 256  # global training batch, split over config.train.num_devices
    i.augment = ml_collections.ConfigDict()
    i.augment.brightness = 0.0  # max brightness shift of centred patches (0 = off)
    i.augment.contrast = 0.0  # max relative contrast change (0 = off)
    i.augment.flip = False  # random horizontal mirror of patches
    i.augment.colour = 0.0  # max relative gain change per colour channel (0 = off)
    i.augment.zoom = 0.0  # max zoom-in about the keypoint, factor in [1, 1 + zoom] (0 = off)

    # The network (rp_jax.model.RepeatabilityPredictor), with its time input
    # (rp_jax.time_encoding).
    m = config.model = ml_collections.ConfigDict()
    m.encoder_channels = (64, 64, 128)  # patch-encoder conv widths (16, 8, 4 px maps)
    m.encoder_features = 128  # patch-encoder output size, concatenated with xy, time
    m.gem_init_p = 3.0  # initial GeM exponent (p = 1 mean, p -> inf max)
    m.dtype = "float32"  # patch-encoder compute dtype: float32 | bfloat16
    m.time_fields = "time_of_day"  # time_of_day | day_of_year | hour_of_year (d = 2, 2, 4)
    m.time_encoding = "cyclic"  # cyclic (sin/cos, continuous across the cycle) | raw
    # Beyond the paper (rp_jax.conditional, issue 17): with conditions set, the Sec. IV-A
    # experiments' --cross-validate also trains the conditional predictor, which scores one
    # image pair from the capture's and the target's time and these conditions; the paper's
    # predictor never reads these four fields.
    m.conditions = ""  # comma list of sun, weather, semantics; "" = the paper's predictor only
    m.conditional_hidden = 128  # conditional predictor: width of the point code and pair layers
    m.time_harmonics = 2  # conditional predictor: sin/cos multiples of the time-of-day angle
    # conditional predictor: the long-term decay basis's time scales, a comma list of years
    # ("1,3,10": rp_jax.conditional.inputs.DECAY_TIME_SCALES_YEARS); "" = no decay basis
    m.decay_time_scales = ""

    # Optimisation (optax), checkpoints (orbax) and devices.
    t = config.train = ml_collections.ConfigDict()
    t.num_epochs = 30  # passes over the training records
    t.learning_rate = 2e-3  # peak learning rate of AdamW
    t.warmup_epochs = 1.0  # linear warm-up, then cosine decay to 0
    t.weight_decay = 1e-4  # AdamW decoupled weight decay
    t.grad_clip = 1.0  # global-norm gradient clipping
    t.keep_best = False  # keep the best-validation parameters in workdir/best
    t.num_devices = 0  # data-parallel devices; 0 = all local devices
    t.checkpoint_every_epochs = 1  # orbax checkpoint after every this many epochs
    t.max_checkpoints_to_keep = 2  # older checkpoints are deleted

    # Validation and prediction.
    e = config.eval = ml_collections.ConfigDict()
    e.every_epochs = 1  # validation after every this many epochs
    e.batch_size = 512  # batch size of evaluation and prediction
    return config


# Where each field of the flat config (before the grouping, 2026-12) lives now. The
# experiments' own fields are here too, so that one table reads every old config.json.
FLAT_TO_GROUPED = {
    "dataset": "input.dataset",
    "schedule": "input.schedule",
    "num_train_points": "input.num_train_points",
    "num_val_points": "input.num_val_points",
    "batch_size": "input.batch_size",
    "augment": "input.augment",
    "data_config": "input.data_config",
    "data_dir": "input.data_dir",
    "manual_dir": "input.manual_dir",
    "synthetic_root": "input.synthetic_root",
    "validation_fraction": "input.validation_fraction",
    "time_fields": "model.time_fields",
    "time_encoding": "model.time_encoding",
    "num_epochs": "train.num_epochs",
    "learning_rate": "train.learning_rate",
    "warmup_epochs": "train.warmup_epochs",
    "weight_decay": "train.weight_decay",
    "grad_clip": "train.grad_clip",
    "keep_best": "train.keep_best",
    "num_devices": "train.num_devices",
    "checkpoint_every_epochs": "train.checkpoint_every_epochs",
    "max_checkpoints_to_keep": "train.max_checkpoints_to_keep",
    "eval_every_epochs": "eval.every_epochs",
    "eval_batch_size": "eval.batch_size",
    "knn_k": "eval.knn_k",
}


# Fields added since the first grouped release, with the value that means "as before": a
# config written before them reads as if it had them at that value.
ADDED_FIELDS = {
    "model.conditions": "",
    "model.conditional_hidden": 128,
    "model.time_harmonics": 2,
    "model.decay_time_scales": "",
}


def upgrade(config: dict) -> dict:
    """A config dict (a ``config.json``) in the current layout: a flat one (written before the
    grouping) has each of its ``FLAT_TO_GROUPED`` fields moved to its group, and a field of
    ``ADDED_FIELDS`` that a config's group lacks is given its "as before" value. Fields the
    tables do not name stay where they are. The argument is not modified."""
    out = _regroup(config) if any(key in config for key in FLAT_TO_GROUPED) else config
    missing = [(k, v) for k, v in ADDED_FIELDS.items()
               if isinstance(out.get(k.split(".")[0]), dict)
               and k.split(".")[1] not in out[k.split(".")[0]]]
    if not missing:
        return out
    out = {k: dict(v) if isinstance(v, dict) else v for k, v in out.items()}
    for dotted, value in missing:
        group, field = dotted.split(".")
        out[group][field] = value
    return out


def _regroup(config: dict) -> dict:
    out: dict = {}
    for key, value in config.items():
        if key in FLAT_TO_GROUPED:
            group, field = FLAT_TO_GROUPED[key].split(".")
            out.setdefault(group, {})[field] = value
        elif isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key].update(value)
        else:
            out[key] = value if not isinstance(value, dict) else dict(value)
    return out
