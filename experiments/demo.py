"""``python -m experiments.demo``: train the predictor on the built-in learnable task and report.

A check of the whole training machinery (Sec. III-B/C) that needs no dataset: labels are a
known function of patch and time (``rp_jax.datasets.learnable_task``), so a working
predictor must end far below the per-slot mean of the training labels. Prints both errors
and the predicted vs true curve of a few validation points.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from experiments import cli
from rp_jax import command_line, files, platform, predict, progress, time_encoding, train
from rp_jax import schedule as schedule_lib
from rp_jax.configs import default
from rp_jax.datasets import input_pipeline, learnable_task


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m experiments.demo", description=__doc__.splitlines()[0].replace("`", ""),
        epilog="--config.FIELD=VALUE  override one field of the config (ml_collections."
        "config_flags), e.g. --config.train.num_epochs=3; --print-config lists the fields.")
    parser.add_argument("--workdir", default="runs/demo_learnable_task",
                        help="run directory (resumes if present)")
    command_line.add_config_file(parser, default="rp_jax/configs/default.py")
    command_line.add_quiet(parser)
    command_line.deprecated_alias(parser, "--epochs", "--config.train.num_epochs=N", dest="epochs",
                                  type=int)
    args, rest = parser.parse_known_args(argv)
    config = cli.load_config(parser, default.get_config, args.config_file,
                             cli.override_args(rest, parser))
    if getattr(args, "epochs", None) is not None:
        config.train.num_epochs = args.epochs
    if args.print_config:
        print(config, end="")
        return 0
    if args.quiet:
        progress.set_quiet()
    platform.configure_cpu()
    try:  # every field, the devices and the workdir, before the task is made and trained
        train.validate_config(config)
        train.check_devices(config)
        train.check_workdir(args.workdir, config)
    except (train.ConfigError, train.WorkdirMismatchError) as e:
        print(f"{parser.prog}: error: {e}", file=sys.stderr)
        return 2
    schedule = schedule_lib.preset(config.input.schedule)
    train_rec = learnable_task.make_learnable_task(config.input.num_train_points, schedule,
                                                   seed=config.seed)
    val_rec = learnable_task.make_learnable_task(config.input.num_val_points, schedule,
                                                 seed=config.seed + 1)
    keys = input_pipeline.MODEL_KEYS
    print(f"learnable task: {len(train_rec['patch'])} train / {len(val_rec['patch'])} val points, "
          f"T={schedule.num_timestamps} ({schedule.labels[0]}..{schedule.labels[-1]})")
    train.train_and_evaluate(config, args.workdir, input_pipeline.ArraySource(train_rec, keys),
                             input_pipeline.ArraySource(val_rec, keys), schedule=schedule)

    rp = predict.load(args.workdir)
    pred = rp(val_rec["patch"], val_rec["xy_normalized"], _times(val_rec, rp))
    slot_mean = train_rec["label"].mean(0)
    result = {
        "val_mse_predictor": float(((pred - val_rec["label"]) ** 2).sum(1).mean()),
        "val_mse_per_slot_mean": float(((slot_mean - val_rec["label"]) ** 2).sum(1).mean()),
    }
    result["ratio"] = result["val_mse_predictor"] / result["val_mse_per_slot_mean"]
    np.set_printoptions(precision=2, suppress=True, linewidth=150)
    for i, kind in enumerate(learnable_task.KINDS):
        k = int(np.flatnonzero(val_rec["kind"] == i)[0])
        print(f"{kind:9s} slot {val_rec['slot'][k]:2d}  true {val_rec['label'][k][::2]}")
        print(f"{'':9s}          pred {pred[k][::2]}")
    print(json.dumps(result, indent=2))
    files.write_json(Path(args.workdir) / "demo_result.json", result)
    return 0


def _times(rec, rp):
    return np.asarray(time_encoding.encode(rec["hour"], rec["minute"], rec["day"], rec["month"],
                                           fields=rp.config.model.time_fields,
                                           encoding=rp.config.model.time_encoding))


if __name__ == "__main__":
    sys.exit(main())
