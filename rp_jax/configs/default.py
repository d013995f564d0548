"""Default configuration of the repeatability predictor's training (Sec. III-B, III-C).

Run it on the built-in learnable task:

    python -m experiments.demo --workdir runs/demo

Expected: validation MSE far below the per-slot-mean baseline's (both printed), in about a
minute on 2 CPU cores. Experiments import this and override only what differs.
"""

import ml_collections


def get_config() -> ml_collections.ConfigDict:
    config = ml_collections.ConfigDict()
    config.seed = 0  # seeds parameter init and the data order (with the epoch)

    # Data.
    config.dataset = "learnable_task"  # "learnable_task", or set by an experiment
    config.schedule = "webcam_clipart"  # a rp_jax.schedule preset: gives T, the output size
    config.num_train_points = 6000  # learnable_task only: training points
    config.num_val_points = 1000  # learnable_task only: validation points

    # Time input (rp_jax.time_encoding).
    config.time_fields = "time_of_day"  # time_of_day | day_of_year | hour_of_year (d = 2, 2, 4)
    config.time_encoding = "cyclic"  # cyclic (sin/cos, continuous across the cycle) | raw

    # Model (rp_jax.model.RepeatabilityPredictor).
    config.model = ml_collections.ConfigDict()
    config.model.encoder_channels = (64, 64, 128)  # patch-encoder conv widths (16, 8, 4 px maps)
    config.model.encoder_features = 128  # patch-encoder output size, concatenated with xy, time
    config.model.gem_init_p = 3.0  # initial GeM exponent (p = 1 mean, p -> inf max)
    config.model.dtype = "float32"  # patch-encoder compute dtype: float32 | bfloat16

    # Optimisation (optax).
    config.batch_size = 256  # global batch, split over config.num_devices
    config.num_epochs = 30  # passes over the training records
    config.learning_rate = 2e-3  # peak learning rate of AdamW
    config.warmup_epochs = 1.0  # linear warm-up, then cosine decay to 0
    config.weight_decay = 1e-4  # AdamW decoupled weight decay
    config.grad_clip = 1.0  # global-norm gradient clipping
    config.augment = ml_collections.ConfigDict()
    config.augment.brightness = 0.0  # max brightness shift of centred patches (0 = off)
    config.augment.contrast = 0.0  # max relative contrast change (0 = off)
    config.augment.flip = False  # random horizontal mirror of patches
    config.augment.colour = 0.0  # max relative gain change per colour channel (0 = off)
    config.augment.zoom = 0.0  # max zoom-in about the keypoint, factor in [1, 1 + zoom] (0 = off)
    config.keep_best = False  # keep the best-validation parameters in workdir/best

    # Loop, devices and checkpoints.
    config.num_devices = 0  # data-parallel devices; 0 = all local devices
    config.eval_every_epochs = 1  # validation after every this many epochs
    config.checkpoint_every_epochs = 1  # orbax checkpoint after every this many epochs
    config.max_checkpoints_to_keep = 2  # older checkpoints are deleted
    config.eval_batch_size = 512  # batch size of evaluation and prediction
    return config
