"""``python -m experiments.ship_models``: put a default run's trained model into the package.

The maintainers' step after a default experiment (``rp_jax.shipped`` says what a shipped
model holds)::

    python -m experiments.ship_models RUN_WORKDIR NAME --dataset D --size S --split SPLIT \\
        --about ABOUT.json

writes ``rp_jax/models/NAME/``: the run's config and schedule, its parameters, the first
``rp_jax.shipped.SAMPLE_SIZE`` records of the split with the predictions made now, and
``model.json`` (ABOUT.json's ``what``, ``command``, ``figures``, ``good_for``, ``not_for``,
plus ``time_inputs``, the parts of a time the model reads, from its config; ``trained_image_size``,
the (W, H) of the images of its dataset, from the split's records, which ``python -m
rp_jax.keypoints`` reduces larger photos to; and the sample's MAE).
``python -m experiments.ship_models --list`` lists them.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

from rp_jax import command_line, files, shipped

__all__ = ["export", "main", "sample_mae", "sample_predictions", "trained_image_size"]

ABOUT_KEYS = ("what", "command", "figures", "good_for", "not_for")
_CONFIG_OF_SIZE = {"tiny": "synthetic_tiny", "small": "synthetic_small", "full": "synthetic"}


def sample_predictions(predictor, sample) -> np.ndarray:
    """[N, T] predictions of ``predictor`` on a ``sample.npz``'s inputs (the records'
    columns, predicted as the Sec. IV-A experiment does)."""
    from experiments.sec4a import experiment

    return experiment.rp_predictions(predictor, predictor.config, sample)


def sample_mae(pred: np.ndarray, sample) -> float:
    """Mean absolute error over the sample's labelled slots."""
    mask = np.asarray(sample["label_mask"]).astype(bool)
    return float(np.abs(pred - sample["label"])[mask].mean())


def trained_image_size(image_sizes) -> list[int]:
    """The (W, H) most of a split's records were cut from (their ``image_size`` column)."""
    sizes, counts = np.unique(np.asarray(image_sizes).reshape(-1, 2), axis=0, return_counts=True)
    return [int(v) for v in sizes[int(np.argmax(counts))]]


def export(workdir: str | os.PathLike, name: str, *, dataset: str, data_config: str,
           split: str, about: dict, data_dir: str | None = None) -> Path:
    """Writes the shipped model ``name`` from a trained ``workdir`` (see the module doc)."""
    from rp_jax import predict, time_encoding
    from rp_jax.datasets import loading

    missing = [k for k in ABOUT_KEYS if not about.get(k)]
    if missing:
        raise ValueError(f"the about file needs {', '.join(missing)}")
    rp = predict.load(workdir)
    cols = loading.load_columns(dataset, split, keys=(*shipped.SAMPLE_KEYS, "image_size"),
                                config=data_config, data_dir=data_dir)
    size = trained_image_size(cols.pop("image_size"))
    sample = {k: np.asarray(v[: shipped.SAMPLE_SIZE]) for k, v in cols.items()}
    pred = sample_predictions(rp, sample).astype(np.float32)
    folder = shipped.MODELS_DIR / name
    config = rp.config.to_dict()
    # Where the maintainer's run read its data means nothing on a user's machine.
    config["input"]["data_dir"] = config["input"]["manual_dir"] = ""
    files.write_json(folder / "config.json", config, default=list)
    files.write_json(folder / "schedule.json", rp.schedule.to_dict(), default=list)
    with files.replacing(folder / "params.npz") as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, **shipped.flatten(rp.params))
    with files.replacing(folder / "sample.npz") as tmp, open(tmp, "wb") as f:
        np.savez_compressed(f, **sample, predictions=pred)
    record = {"name": name, **{k: about[k] for k in ABOUT_KEYS},
              "time_inputs": time_encoding.READS[rp.config.model.time_fields],
              "trained_image_size": size, "sample": {
        "source": f"{dataset}/{data_config}, split {split!r}, first {len(pred)} records",
        "mae": round(sample_mae(pred, sample), 6)}}
    files.write_json(folder / "model.json", record)
    return folder


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.ship_models",
                                description=__doc__.split("\n")[0].replace("`", ""))
    p.add_argument("workdir", nargs="?", help="the trained workdir of a default run")
    p.add_argument("name", nargs="?", help="the shipped model's name, e.g. robotcar-synthetic")
    p.add_argument("--dataset", help="dataset of the sample: webcam_clipart, cmu_seasons, robotcar")
    p.add_argument("--size", choices=tuple(_CONFIG_OF_SIZE), default=None,
                   help="size of the synthetic world whose build the sample's records come "
                   "from (tiny, small, full; needed unless --real)")
    p.add_argument("--real", action="store_true", help="the sample comes from the real data "
                   "(TFDS builder config real) instead of the synthetic world")
    command_line.add_data_dir(p, default="rp_jax.datasets.loading.default_data_dir()")
    # Released spelling: a TFDS builder config name; --size / --real say the same.
    p.add_argument("--config", dest="config_name", default=None, help=argparse.SUPPRESS)
    p.add_argument("--split", default="test", help="its split (default test)")
    p.add_argument("--about", help="a JSON file with what, command, figures, good_for, not_for")
    p.add_argument("--list", action="store_true", help="list the shipped models and stop")
    args = p.parse_args(argv)
    if args.list:
        for n in shipped.names():
            print(n, json.loads((shipped.MODELS_DIR / n / "model.json").read_text())["sample"])
        return 0
    data_config = args.config_name
    if data_config is not None:
        command_line.deprecation_warning(p.prog, f"--config {data_config}", "--size or --real")
    elif args.real or args.size:
        data_config = "real" if args.real else _CONFIG_OF_SIZE[args.size]
    if not (args.workdir and args.name and args.dataset and data_config and args.about):
        p.error("WORKDIR NAME --dataset --size (or --real) --about are needed (or --list)")
    try:
        about = json.loads(Path(args.about).read_text())
        folder = export(args.workdir, args.name, dataset=args.dataset, data_config=data_config,
                        split=args.split, about=about, data_dir=args.data_dir)
    except (OSError, ValueError) as err:
        print(f"python -m experiments.ship_models: error: {err}", file=sys.stderr)
        return 2
    print(f"wrote {folder}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
