"""Shared command line of the experiments (Flax-examples style: thin entry points).

Every experiment takes the same flags::

    --workdir DIR        run directory (default runs/<experiment>_<size>); resumes if present
    --data-dir DIR       a real download in its real layout; absent: the synthetic world
    --size tiny|small|full   synthetic size (default full; ignored with --data-dir)
    --tfds-dir DIR       where built TFDS datasets are kept (default: $RP_JAX_DATA_DIR, else
                         data/tensorflow_datasets in the source checkout, whatever the
                         working directory; ~/.cache/rp_jax/... for an installed wheel)
    --config.FIELD=VALUE any field of the experiment's config, e.g. --config.num_epochs=3
    --cross-validate     instead of the test run: hold out each training viewpoint in turn
                         (experiments.sec4a.crossval); writes <workdir>/crossval/crossval.{json,md}
    --folds N            with --cross-validate: N groups of viewpoints (default: one each)
"""

from __future__ import annotations

import argparse
import ast
import sys
from collections.abc import Callable
from pathlib import Path

import ml_collections

SIZES = ("tiny", "small", "full")


def _default_tfds_dir() -> str:
    from rp_jax.datasets.loading import DEFAULT_DATA_DIR  # (TFDS-free module)

    return str(DEFAULT_DATA_DIR)


def _convert(old, text: str):
    if isinstance(old, bool):
        if text.lower() in ("true", "1", "yes"):
            return True
        if text.lower() in ("false", "0", "no"):
            return False
        raise ValueError(f"expected true/false, got {text!r}")
    if isinstance(old, int):
        return int(text)
    if isinstance(old, float):
        return float(text)
    if isinstance(old, (tuple, list)):
        value = ast.literal_eval(text)
        if not isinstance(value, (tuple, list)):
            raise ValueError(f"expected a tuple such as (64, 64, 128), got {text!r}")
        return tuple(value)
    return text


def apply_overrides(config: ml_collections.ConfigDict, overrides: list[str]) -> None:
    """Apply ``--config.a.b=value`` overrides, converting to the field's existing type."""
    for item in overrides:
        if not item.startswith("--config.") or "=" not in item:
            raise SystemExit(f"unknown argument {item!r}: expected --config.FIELD=VALUE")
        path, text = item[len("--config."):].split("=", 1)
        *parents, leaf = path.split(".")
        node = config
        for p in parents:
            if p not in node:
                raise SystemExit(f"--config.{path}: no field {p!r} in the config")
            node = node[p]
        if leaf not in node:
            fields = ", ".join(sorted(node.keys()))
            raise SystemExit(f"--config.{path}: no such field; fields: {fields}")
        try:
            node[leaf] = _convert(node[leaf], text)
        except (ValueError, SyntaxError) as e:
            raise SystemExit(f"--config.{path}={text}: {e}") from e


def parse(argv: list[str] | None, name: str, get_config: Callable[[str], ml_collections.ConfigDict],
          doc: str) -> tuple[ml_collections.ConfigDict, Path]:
    """Parse the flags into (config, workdir)."""
    config, workdir, _ = parse_flags(argv, name, get_config, doc)
    return config, workdir


def parse_flags(argv: list[str] | None, name: str,
                get_config: Callable[[str], ml_collections.ConfigDict], doc: str, *,
                cross_validation: bool = False
                ) -> tuple[ml_collections.ConfigDict, Path, argparse.Namespace]:
    """Parse the flags into (config, workdir, the parsed flags); ``cross_validation`` adds
    ``--cross-validate`` and ``--folds`` (the Sec. IV-A experiments)."""
    parser = argparse.ArgumentParser(prog=f"python -m experiments.{name}", description=doc,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--workdir", type=Path, default=None,
                        help="run directory (resumes if present)")
    parser.add_argument("--data-dir", type=Path, default=None,
                        help="a real download in its real layout (default: the synthetic world)")
    parser.add_argument("--size", choices=SIZES, default="full",
                        help="synthetic size (default full)")
    parser.add_argument(
        "--tfds-dir",
        type=Path,
        default=None,
        help=f"TFDS data directory (default: $RP_JAX_DATA_DIR or {_default_tfds_dir()}, the "
        "same from any working directory)",
    )
    if cross_validation:
        parser.add_argument("--cross-validate", action="store_true",
                            help="hold out each training viewpoint in turn instead of testing")
        parser.add_argument("--folds", type=int, default=0,
                            help="with --cross-validate: groups of viewpoints "
                                 "(default 0: one per viewpoint)")
    parser.set_defaults(cross_validate=False, folds=0)
    args, rest = parser.parse_known_args(argv)
    if args.folds and not args.cross_validate:
        parser.error("--folds needs --cross-validate")
    if args.folds < 0 or args.folds == 1:
        parser.error(f"--folds must be 0 (one per viewpoint) or at least 2, got {args.folds}")
    size = args.size
    config = get_config(size)
    if args.data_dir is not None:
        if not args.data_dir.is_dir():
            parser.error(f"--data-dir {args.data_dir} is not a directory")
        config.data_config = "real"
        config.manual_dir = str(args.data_dir.absolute())
        size = "real"
    if args.tfds_dir is not None:
        config.data_dir = str(args.tfds_dir.absolute())
    apply_overrides(config, rest)
    workdir = args.workdir or Path("runs") / f"{name}_{size}"
    return config, workdir, args


def main(argv, name: str, get_config, doc: str) -> int:
    """Parse flags, run ``experiments.sec4a.experiment.run`` and print the headline figures."""
    config, workdir, args = parse_flags(argv, name, get_config, doc, cross_validation=True)
    from rp_jax import platform

    platform.configure_cpu()
    from experiments.sec4a import config as sec4a_config
    from experiments.sec4a import experiment
    from rp_jax import train
    from rp_jax.sources.layout import LayoutError

    try:
        sec4a_config.validate(config, workdir)  # before any build: one line, exit 2
        if args.cross_validate:
            return _cross_validate(config, Path(workdir) / "crossval", args.folds)
        metrics = experiment.run(config, workdir)
    except LayoutError as e:  # a --data-dir that is not the dataset's layout: say what is missing
        print(f"python -m experiments.{name}: error: {e}", file=sys.stderr)
        return 2
    except (train.ConfigError, train.WorkdirMismatchError) as e:  # a field out of range, or
        # a workdir this config cannot resume
        print(f"python -m experiments.{name}: error: {e}", file=sys.stderr)
        return 2
    except train.NonFiniteLossError as e:  # diverged: nothing of it was saved or reported
        print(f"python -m experiments.{name}: error: {e}", file=sys.stderr)
        return 1
    except ValueError as e:
        if not args.cross_validate:
            raise
        print(f"python -m experiments.{name}: error: {e}", file=sys.stderr)
        return 2
    b = metrics["baselines"]
    print(f"wrote {workdir}/metrics.json, report.md and {len(metrics['figures'])} figures")
    print(f"test MAE {metrics['test_mae']:.4f} "
          f"(per-slot mean {b['per_slot_mean']['test_mae']:.4f}, "
          f"slot-conditioned {b['slot_conditioned_mean']['test_mae']:.4f}, "
          f"descriptor kNN {b['descriptor_knn']['test_mae']:.4f}); "
          f"curve corr {metrics['curve_corr']:.3f}")
    return 0


def _cross_validate(config, workdir: Path, folds: int) -> int:
    """Leave-viewpoints-out over the training split; prints the summary table."""
    from experiments.sec4a import crossval, experiment

    data = experiment.build_dataset(config, workdir)
    result = crossval.cross_validate(config, workdir, data["train"], num_folds=folds)
    print(crossval.markdown(result))
    print(f"wrote {workdir}/crossval.json and crossval.md")
    return 0
