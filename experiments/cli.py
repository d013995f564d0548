"""Shared command line of the experiments (Flax-examples style: thin entry points).

Every experiment takes the same flags (the project's one vocabulary,
``rp_jax.command_line``)::

    --workdir DIR        run directory (default runs/<experiment>_<size>); resumes if present
    --manual-dir DIR     the real dataset you downloaded, in its real layout (TFDS's
                         manual_dir); absent: the synthetic world
    --size tiny|small|full   synthetic size (ignored with --manual-dir)
    --data-dir DIR       TFDS data directory, where built datasets are kept (TFDS's data_dir;
                         default: $RP_JAX_DATA_DIR, else data/tensorflow_datasets in the source
                         checkout, whatever the working directory; ~/.cache/rp_jax/... for an
                         installed wheel)
    --config FILE[:ARG]  an ml_collections config file (default: the experiment's own, called
                         with --size); ``ml_collections.config_flags`` loads it
    --config.FIELD=VALUE any field of the config, e.g. --config.train.num_epochs=3 (config_flags)
    --print-config       print the resolved config and exit
    --quiet              no progress output
    --cross-validate     instead of the test run: hold out each training viewpoint in turn
                         (experiments.sec4a.crossval); writes <workdir>/crossval/crossval.{json,md}
    --folds N            with --cross-validate: N groups of viewpoints (default: one each)

Deprecated for one release (a warning on stderr): ``--tfds-dir`` (now ``--data-dir``) and
``--data-dir`` naming a download (now ``--manual-dir``): a ``--data-dir`` folder that holds
files but no built dataset is read as the download, with a warning.

Why argparse around ``config_flags`` rather than an absl app: absl's ``--help`` lists absl's
own flags (logging, verbosity, ...) beside ours, cannot take positional arguments or
sub-commands the other commands have, and loses the description text; so argparse keeps the
command line and its ``--help``, and every ``--config`` / ``--config.FIELD`` argument is
handed to ``config_flags`` on a private ``FlagValues``: loading, typed overrides (tuples,
bools, ``--noconfig.FIELD``) and their errors are ``config_flags``' own.
"""

from __future__ import annotations

import argparse
import contextlib
import re
import sys
from collections.abc import Callable
from pathlib import Path

import ml_collections

from rp_jax import command_line

SIZES = ("tiny", "small", "full")


def _default_tfds_dir() -> str:
    from rp_jax.datasets.loading import DEFAULT_DATA_DIR  # (TFDS-free module)

    return str(DEFAULT_DATA_DIR)


def _is_tfds_data_dir(path: Path) -> bool:
    """Whether ``path`` can be a TFDS data directory: new, empty, or holding built datasets."""
    from rp_jax.datasets import CONFIG_NAMES, DATASET_NAMES

    if not path.exists():
        return True
    if not path.is_dir():
        return False
    if not any(path.iterdir()) or (path / "downloads").is_dir():
        return True
    if any((path / name / config).is_dir() for name in DATASET_NAMES for config in CONFIG_NAMES):
        return True
    # Any TFDS dataset (NAME/VERSION or NAME/CONFIG/VERSION with its dataset_info.json).
    return any(path.glob("*/*/dataset_info.json")) or any(path.glob("*/*/*/dataset_info.json"))


_OVERRIDE = re.compile(r"^--?(no)?config\.")
_BOOL_WORDS = {"yes": "true", "no": "false"}


def seed_list(text: str) -> tuple[int, ...]:
    """Comma-separated non-negative world seeds, ``A,B,...`` (an argparse type)."""
    try:
        seeds = tuple(int(s) for s in text.split(",") if s.strip())
    except ValueError:
        seeds = ()
    if not seeds or any(s < 0 for s in seeds):
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected comma-separated non-negative integers such as 0,1,2")
    return seeds


def override_args(rest: list[str], parser: argparse.ArgumentParser) -> list[str]:
    """The ``--config.FIELD[=VALUE]`` arguments of ``rest`` (a value may follow as the next
    argument, as absl allows); anything else is an error naming it."""
    out, i = [], 0
    while i < len(rest):
        item = rest[i]
        if not _OVERRIDE.match(item):
            parser.error(f"unrecognized argument {item!r}: expected a flag of --help or "
                         "--config.FIELD=VALUE")
        out.append(item)
        if "=" not in item and i + 1 < len(rest) and not rest[i + 1].startswith("-"):
            out.append(rest[i + 1])
            i += 1
        i += 1
    return out


def _field(config: ml_collections.ConfigDict, override: str):
    """(found, value) of the field an override names."""
    node = config
    for key in _OVERRIDE.sub("", override.split("=", 1)[0]).split("."):
        if not isinstance(node, ml_collections.ConfigDict) or key not in node:
            return False, None
        node = node[key]
    return True, node


def _regrouped(parser, config, item: str, path: str) -> tuple[str, str]:
    """A field named as before the config was grouped (``--config.num_epochs=3``) is read as
    its grouped name (``--config.train.num_epochs=3``) with a deprecation warning, for one
    release; anything else is returned unchanged."""
    from rp_jax.configs import default

    prefix, name = path.split("config.", 1)
    head, _, rest = name.partition(".")
    new = default.FLAT_TO_GROUPED.get(head)
    if new is None or not _field(config, f"--config.{new}")[0]:
        return item, path
    new_path = f"{prefix}config.{new}" + (f".{rest}" if rest else "")
    command_line.deprecation_warning(parser.prog, path, new_path)
    return new_path + item[len(path):], new_path


def _check_fields(parser, config: ml_collections.ConfigDict, overrides: list[str]) -> list[str]:
    """Every override names a field (else ``parser.error`` listing the fields there);
    ``--config.FLAG=yes|no`` of a bool field reads as true/false, as the earlier parser did."""
    out = []
    for item in overrides:
        if not _OVERRIDE.match(item):  # a value given as the next argument
            out.append(item)
            continue
        path = item.split("=", 1)[0]
        found, value = _field(config, item)
        if not found:
            item, path = _regrouped(parser, config, item, path)
            found, value = _field(config, item)
        if not found:
            parent = path.rsplit(".", 1)[0]
            _, node = _field(config, parent) if "." in _OVERRIDE.sub("", path) else (True, config)
            fields = ", ".join(sorted(node.keys())) if isinstance(
                node, ml_collections.ConfigDict) else "(none)"
            parser.error(f"{path}: no such field in the config; fields there: {fields}")
        if isinstance(value, bool) and "=" in item:
            text = item.split("=", 1)[1]
            item = f"{path}={_BOOL_WORDS.get(text.lower(), text)}"
        out.append(item)
    return out


def load_config(parser: argparse.ArgumentParser, default: Callable[[], ml_collections.ConfigDict],
                config_file: str | None, overrides: list[str]) -> ml_collections.ConfigDict:
    """The config of ``--config FILE[:ARG]`` (else ``default()``) with ``--config.FIELD=VALUE``
    overrides, both through ``ml_collections.config_flags``; a bad one is ``parser.error``."""
    from absl import flags
    from ml_collections import config_flags

    if config_file is None:
        config = default()
    else:
        if not Path(config_file.split(":", 1)[0]).is_file():
            parser.error(f"--config {config_file}: no such file (expected a Python file with "
                         "get_config())")
        argv = [parser.prog, f"--config={config_file}"]
        values = flags.FlagValues()
        try:  # config_flags' own loader of --config=FILE[:ARG]
            config_flags.DEFINE_config_file("config", flag_values=values, sys_argv=argv,
                                            lock_config=False)
            values(argv)
            config = values.config
        except (TypeError, ValueError, flags.Error) as err:  # its get_config failed
            parser.error(f"--config {config_file}: {str(err).strip().splitlines()[-1]}")
        if not isinstance(config, ml_collections.ConfigDict):
            parser.error(f"--config {config_file}: get_config() returned "
                         f"{type(config).__name__}, not an ml_collections.ConfigDict")
    overrides = _check_fields(parser, config, overrides)
    argv = [parser.prog, *overrides]
    values = flags.FlagValues()
    try:
        config_flags.DEFINE_config_dict("config", config, flag_values=values, sys_argv=argv,
                                        lock_config=False)
        values(argv)
    except flags.Error as err:
        parser.error(str(err).replace("flag --config", "--config"))
    return values.config


def build_parser(name: str, doc: str, *, default_size: str = "full",
                 cross_validation: bool = False, module: str | None = None
                 ) -> argparse.ArgumentParser:
    """The experiments' argparse parser (``--config.FIELD=VALUE`` are parsed apart); its
    program is ``python -m experiments.<module>`` (default ``name``, which also names the
    default workdir)."""
    parser = argparse.ArgumentParser(
        prog=f"python -m experiments.{module or name}", description=doc,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="--config.FIELD=VALUE  override one field of the config (ml_collections."
        "config_flags: tuples as (8,8,16), bools as true/false or --config.FIELD / "
        "--noconfig.FIELD); --print-config lists the fields.")
    parser.add_argument("--workdir", type=Path, default=None,
                        help=f"run directory (default runs/{name}_<size>; resumes if present)")
    command_line.add_manual_dir(parser)
    parser.add_argument("--size", choices=SIZES, default=None,
                        help=command_line.SIZE_HELP.format(default=default_size))
    command_line.add_data_dir(parser, default=_default_tfds_dir() + ", the same from any "
                              "working directory")
    command_line.deprecated_alias(parser, "--tfds-dir", "--data-dir", dest="data_dir", type=Path)
    command_line.add_config_file(parser, default="this experiment's own, with ARG = --size")
    command_line.add_quiet(parser)
    if cross_validation:
        parser.add_argument("--cross-validate", action="store_true",
                            help="hold out each training viewpoint in turn instead of testing")
        parser.add_argument("--folds", type=int, default=0,
                            help="with --cross-validate: groups of viewpoints "
                                 "(default 0: one per viewpoint)")
        parser.add_argument("--ablation", default=None, metavar="V,V,...",
                            help="with --cross-validate, beyond the paper: also train the "
                            "conditional predictor in these variants, each 'time' or "
                            "conditions joined by '+' (e.g. time,sun,weather,"
                            "sun+weather+semantics); default: --config.model.conditions "
                            "when set")
    parser.set_defaults(cross_validate=False, folds=0, ablation=None)
    return parser


def parse(argv: list[str] | None, name: str, get_config: Callable[[str], ml_collections.ConfigDict],
          doc: str, **kwargs) -> tuple[ml_collections.ConfigDict, Path]:
    """Parse the flags into (config, workdir)."""
    config, workdir, _ = parse_flags(argv, name, get_config, doc, **kwargs)
    return config, workdir


def parse_flags(argv: list[str] | None, name: str,
                get_config: Callable[[str], ml_collections.ConfigDict], doc: str, *,
                cross_validation: bool = False, default_size: str = "full",
                add_flags: Callable[[argparse.ArgumentParser], None] | None = None,
                module: str | None = None,
                ) -> tuple[ml_collections.ConfigDict, Path, argparse.Namespace]:
    """Parse the flags into (config, workdir, the parsed flags).

    ``cross_validation`` adds ``--cross-validate`` and ``--folds`` (the Sec. IV-A
    experiments); ``default_size`` is the ``--size`` when none is given; ``add_flags`` adds
    an experiment's own flags; ``module`` the command's module where it is not ``name``.
    ``--print-config`` prints the config and exits (status 0).
    """
    parser = build_parser(name, doc, default_size=default_size, cross_validation=cross_validation,
                          module=module)
    if add_flags is not None:
        add_flags(parser)
    args, rest = parser.parse_known_args(sys.argv[1:] if argv is None else argv)
    if args.folds and not args.cross_validate:
        parser.error("--folds needs --cross-validate")
    if args.folds < 0 or args.folds == 1:
        parser.error(f"--folds must be 0 (one per viewpoint) or at least 2, got {args.folds}")
    if (args.data_dir is not None and args.manual_dir is None
            and not _is_tfds_data_dir(args.data_dir)):
        # The released meaning of --data-dir here was the download: read it so for one release.
        command_line.deprecation_warning(
            parser.prog, f"--data-dir {args.data_dir} (a folder with no built dataset, read as "
            "the download)", f"--manual-dir {args.data_dir}; --data-dir now names the TFDS "
            "data directory, as in python -m rp_jax.datasets")
        args.manual_dir, args.data_dir = args.data_dir, None
    size = args.size or default_size
    overrides = override_args(rest, parser)
    if args.config_file is not None and args.size is not None and ":" not in args.config_file:
        args.config_file = f"{args.config_file}:{args.size}"
    config = load_config(parser, lambda: get_config(size), args.config_file, overrides)
    if args.manual_dir is not None:
        if not args.manual_dir.is_dir():
            parser.error(f"--manual-dir {args.manual_dir} is not a directory")
        config.input.data_config = "real"
        config.input.manual_dir = str(args.manual_dir.absolute())
        size = "real"
    elif args.config_file is not None:
        stem, _, arg = args.config_file.partition(":")
        file = Path(stem)
        size = "_".join(filter(None, (file.parent.name if file.stem == "config" else file.stem,
                                      arg)))
    if args.data_dir is not None:
        config.input.data_dir = str(args.data_dir.absolute())
    if args.print_config:
        print(config, end="")  # ConfigDict's YAML, as the Flax examples log it
        raise SystemExit(0)
    workdir = args.workdir or Path("runs") / f"{name}_{size}"
    command_line.check_writable_folder(parser, "--workdir", workdir)  # every experiment
    return config, workdir, args


def main(argv, name: str, get_config, doc: str, *, default_size: str = "full") -> int:
    """Parse flags, run ``experiments.sec4a.experiment.run`` and print the headline figures."""
    config, workdir, args = parse_flags(argv, name, get_config, doc, cross_validation=True,
                                        default_size=default_size)
    from rp_jax import platform, progress

    if args.quiet:
        progress.set_quiet()
    # malloc: glibc keeps the memory XLA frees instead of page-faulting each train step's
    # temporaries in again (rp_jax.platform.tune_malloc): the train step +19 % in
    # experiments/results/benchmark.md (2026-12-02, quiet: 1,745 against 1,465 samples/s), the
    # numbers computed do not change (a webcam_clipart run's metrics compared equal with
    # and without it). Prediction (-12 % and +9 % in two runs that day) is seconds here.
    platform.configure_cpu(malloc=True)
    from experiments.sec4a import config as sec4a_config
    from experiments.sec4a import experiment
    from rp_jax import train, workdir_lock
    from rp_jax.sources.layout import LayoutError

    conditional = bool(args.ablation or config.model.conditions
                       or config.model.get("decay_time_scales"))
    if conditional and not args.cross_validate:
        print(f"python -m experiments.{name}: error: the conditional predictor "
              "(--config.model.conditions, --config.model.decay_time_scales, --ablation) is "
              "measured on held-out training viewpoints only in this release: add "
              "--cross-validate", file=sys.stderr)
        return 2
    try:  # a bad flag or workdir is answered before the workdir is touched, not even by the
        # lock file (both checks only read)
        sec4a_config.validate(config, None if conditional else workdir)
    except (train.ConfigError, train.WorkdirMismatchError) as e:
        print(f"python -m experiments.{name}: error: {e}", file=sys.stderr)
        return 2
    # One run at a time in a workdir (rp_jax.workdir_lock): a second one stops here, at once
    # (a workdir that is a file is left to sec4a_config.validate's message).
    holding = (contextlib.nullcontext() if Path(workdir).is_file()
               else workdir_lock.hold(workdir))
    try:
        holding.__enter__()
    except workdir_lock.FolderBusyError as e:
        print(f"python -m experiments.{name}: error: {e}", file=sys.stderr)
        return 2
    try:
        if conditional:  # beyond the paper: the paper's predictor and the conditional one
            from experiments.conditional import config as conditional_config
            from experiments.conditional import crossval as conditional_crossval

            sec4a_config.validate(config)
            # The workdir holds the paper's run: compared with the paper's fields.
            train.check_workdir(workdir, conditional_config.paper_config(config))
            return conditional_crossval.run(config, Path(workdir) / "conditional",
                                            args.ablation, args.folds, quiet=args.quiet,
                                            prog=f"python -m experiments.{name}")
        sec4a_config.validate(config, workdir)  # before any build: one line, exit 2
        if args.cross_validate:
            return _cross_validate(config, Path(workdir) / "crossval", args.folds)
        metrics = experiment.run(config, workdir)
    except LayoutError as e:  # a --manual-dir that is not the dataset's layout: what is missing
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
    finally:
        holding.__exit__(None, None, None)
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
    from experiments import records
    from experiments.sec4a import crossval

    data = records.build_dataset(config, workdir)
    result = crossval.cross_validate(config, workdir, data["train"], num_folds=folds)
    print(crossval.markdown(result))
    print(f"wrote {workdir}/crossval.json and crossval.md")
    return 0
