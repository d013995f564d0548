"""Config shared by the experiments of Sec. IV-A (each overrides only its dataset's fields).

Sizes: ``tiny`` (seconds; tests), ``small`` (minutes), ``full`` (the default synthetic world,
sized so a whole run stays well under 15 minutes on 2 CPU cores).
"""

import ml_collections

from rp_jax.configs import default

DATA_CONFIGS = {"tiny": "synthetic_tiny", "small": "synthetic_small", "full": "synthetic"}


def get_config(size: str = "full") -> ml_collections.ConfigDict:
    if size not in DATA_CONFIGS:
        raise ValueError(f"size must be one of {sorted(DATA_CONFIGS)}, got {size!r}")
    config = default.get_config()
    config.dataset = ""  # TFDS builder name (rp_jax/datasets/<name>), set by the experiment
    config.data_config = DATA_CONFIGS[size]  # synthetic size, or "real" with --manual-dir
    config.data_dir = ""  # TFDS data directory (--data-dir; "" = loading.default_data_dir())
    config.manual_dir = ""  # the real download (--manual-dir)
    config.synthetic_root = ""  # where the synthetic layout is rendered ("" = beside data_dir)
    config.validation_fraction = 0.15  # share of training viewpoints held out for validation
    config.knn_k = 10  # neighbours of the descriptor-kNN baseline
    config.num_epochs = {"tiny": 2, "small": 8, "full": 8}[size]
    config.batch_size = {"tiny": 32, "small": 128, "full": 256}[size]
    config.eval_batch_size = 256
    # Few training viewpoints (6-7 scenes): without these the predictor learns each scene's
    # colours and loses to the per-slot mean on a held-out scene (measured, full Webcam).
    config.augment.brightness = 0.15
    config.augment.contrast = 0.25
    config.augment.flip = True
    config.keep_best = True  # model selection on the validation viewpoints
    return config
