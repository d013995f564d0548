"""Config shared by the experiments of Sec. IV-A (each overrides only its dataset's fields).

Sizes: ``tiny`` (seconds; tests), ``small`` (minutes), ``full`` (the default synthetic world,
sized so a whole run stays well under 15 minutes on 2 CPU cores). ``tiny`` also trains a
narrower network (16, 16, 32 channels instead of the default 64, 64, 128): its runs check
that every stage works; what the network learns is measured at the full size.
"""

from pathlib import Path

import ml_collections

from rp_jax.configs import default

DATA_CONFIGS = {"tiny": "synthetic_tiny", "small": "synthetic_small", "full": "synthetic"}


def get_config(size: str = "full") -> ml_collections.ConfigDict:
    if size not in DATA_CONFIGS:
        raise ValueError(f"size must be one of {sorted(DATA_CONFIGS)}, got {size!r}")
    config = default.get_config()
    i = config.input
    i.dataset = ""  # TFDS builder name (rp_jax/datasets/<name>), set by the experiment
    i.data_config = DATA_CONFIGS[size]  # synthetic size, or "real" with --manual-dir
    i.data_dir = ""  # TFDS data directory (--data-dir; "" = loading.default_data_dir())
    i.manual_dir = ""  # the real download (--manual-dir)
    i.synthetic_root = ""  # where the synthetic layout is rendered ("" = beside data_dir)
    i.validation_fraction = 0.15  # share of training viewpoints held out for validation
    i.batch_size = {"tiny": 32, "small": 128, "full": 256}[size]
    # Few training viewpoints (6-7 scenes): without these the predictor learns each scene's
    # colours and loses to the per-slot mean on a held-out scene (measured, full Webcam).
    i.augment.brightness = 0.15
    i.augment.contrast = 0.25
    i.augment.flip = True
    config.train.num_epochs = {"tiny": 2, "small": 8, "full": 8}[size]
    if size == "tiny":  # see the docstring: the test suite's end-to-end runs, faster
        config.model.encoder_channels = (16, 16, 32)
    config.train.keep_best = True  # model selection on the validation viewpoints
    config.eval.batch_size = 256
    config.eval.knn_k = 10  # neighbours of the descriptor-kNN baseline
    return config


def validate(config: ml_collections.ConfigDict, workdir=None) -> None:
    """Refuse a config (or ``workdir``) that cannot run, before any expensive stage.

    Raises ``rp_jax.train.ConfigError`` naming the first field out of range (the training
    fields through ``train.validate_config``, then this experiment's own), and
    ``train.WorkdirMismatchError`` for a ``workdir`` that is a file or holds a run of another
    model or data. A bad value otherwise surfaces only after the dataset is built (minutes)
    or as a traceback from deep inside.
    """
    from rp_jax import schedule as schedule_lib
    from rp_jax import train
    from rp_jax.datasets import CONFIG_NAMES, DATASET_NAMES

    def expect(ok: bool, field: str, expected: str) -> None:
        if not ok:
            raise train.ConfigError(
                f"config.{field}={train.field_value(config, field)!r}: expected {expected}")

    train.validate_config(config)
    train.check_devices(config)  # batch_size=33 on 2 devices failed after the build
    i = config.input
    expect(i.dataset in DATASET_NAMES, "input.dataset", f"one of {list(DATASET_NAMES)}")
    expect(i.data_config in CONFIG_NAMES, "input.data_config", f"one of {list(CONFIG_NAMES)}")
    # The records are labelled at the dataset's own timestamps: another schedule has another T.
    expect(i.schedule == i.dataset, "input.schedule",
           f"{i.dataset!r}, the timestamps {i.dataset}'s records are labelled at "
           f"(T = {schedule_lib.preset(i.dataset).num_timestamps})")
    fraction = i.validation_fraction
    expect(isinstance(fraction, (int, float)) and not isinstance(fraction, bool)
           and 0 <= fraction < 1, "input.validation_fraction",
           "a number in [0, 1): the share of training viewpoints held out (0: none)")
    from rp_jax.conditional import inputs as conditional_inputs

    m = config.model
    try:
        conditional_inputs.parse_conditions(m.conditions)
    except (ValueError, AttributeError) as e:
        known = ", ".join(conditional_inputs.CONDITIONS)
        expect(False, "model.conditions", f"a comma list of {known}, or '' ({e})")
    for field in ("conditional_hidden", "time_harmonics"):
        value = m[field]
        expect(isinstance(value, int) and not isinstance(value, bool) and value >= 1,
               f"model.{field}", "an integer >= 1")
    knn_k = config.eval.knn_k
    expect(isinstance(knn_k, int) and not isinstance(knn_k, bool) and knn_k >= 1,
           "eval.knn_k", "an integer >= 1")
    if i.data_config == "real":
        expect(bool(i.manual_dir), "input.manual_dir",
               "the folder of the real download (--manual-dir) with data_config 'real'")
    if i.manual_dir:
        expect(Path(i.manual_dir).is_dir(), "input.manual_dir", "an existing folder")
    for field in ("data_dir", "synthetic_root"):  # created if absent
        expect(not i[field] or not Path(i[field]).exists() or Path(i[field]).is_dir(),
               f"input.{field}", "a folder (created if absent), not a file")
    if workdir is not None:
        train.check_workdir(workdir, config)
        from experiments import records

        records.check_trained_on(workdir, records.records_identity(config))
