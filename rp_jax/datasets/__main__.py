"""Command line of the keypoint-record datasets (Sec. III-D, Fig. 6, Fig. 9).

    python -m rp_jax.datasets build NAME [--size tiny|small|full | --manual-dir DIR | --real]
                                         [--data-dir DIR] [--quiet]
    python -m rp_jax.datasets curves NAME [--size tiny|small|full | --real] [--data-dir DIR]
                                          --out PNG
    python -m rp_jax.datasets outcomes NAME [--size tiny|small|full | --manual-dir DIR | --real]
                                            [--data-dir DIR] [--workers N] [--quiet]

The flags mean what they mean in every command of the project (``rp_jax.command_line``):
``--data-dir`` is the TFDS data directory the dataset is built in, ``--manual-dir`` the real
download it is built from (which selects the real data), ``--size`` the size of the
synthetic world otherwise; ``--real`` selects the real data at TFDS's default manual dir
(``<data-dir>/downloads/manual``). ``--config NAME`` (a TFDS builder config) still works
this release, with a warning.

``build`` builds (or finds already built) the TFDS dataset and prints the number of
records per split, per timestamp (the slot of the image an interest point comes from) and
per category where known. ``curves`` writes the average ground-truth repeatability curve
of each split to ``--out`` and, where categories are known, the Fig. 9 per-category
curves to ``<out stem>_categories.png`` and each category's repeatability at the interest
point's own timestamp against the others (parked cars: only their own date) to
``<out stem>_own_date.png``. ``outcomes`` builds the dataset if needed, then writes the
per-image-pair outcomes of its records with each image's time and conditions beside it
(``rp_jax.datasets.outcomes``; what ``experiments.conditional`` trains on).
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

from rp_jax import command_line
from rp_jax.datasets import CONFIG_NAMES, DATASET_NAMES
from rp_jax.datasets.loading import BUILD_FLAGS, DEFAULT_DATA_DIR

SIZES = ("tiny", "small", "full")
_CONFIG_OF_SIZE = {"tiny": "synthetic_tiny", "small": "synthetic_small", "full": "synthetic"}
_FLAGS_OF_CONFIG = {**BUILD_FLAGS, "real": "--real (or --manual-dir DIR)"}

__all__ = ["main"]


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m rp_jax.datasets",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = p.add_subparsers(dest="command", required=True)

    def common(q):
        q.add_argument("name", choices=DATASET_NAMES, help="dataset")
        q.add_argument("--size", choices=SIZES, default=None,
                       help=command_line.SIZE_HELP.format(default="full"))
        q.add_argument("--real", action="store_true",
                       help="the real data (TFDS builder config real) instead of the synthetic "
                       "world")
        # Released spelling: a TFDS builder config name; --size / --real say the same.
        q.add_argument("--config", dest="config_name", choices=CONFIG_NAMES, default=None,
                       help=argparse.SUPPRESS)
        command_line.add_data_dir(q, default=str(DEFAULT_DATA_DIR))

    b = sub.add_parser("build", help="build a dataset and print its counts")
    common(b)
    command_line.add_manual_dir(b)
    b.add_argument(
        "--synthetic-root",
        type=Path,
        default=None,
        help="folder of the synthetic layout (rendered there if absent)",
    )
    b.add_argument(
        "--workers",
        type=int,
        default=None,
        help="processes labelling viewpoints (default: min(2, cores))",
    )
    b.add_argument(
        "--beam-pipeline-options",
        default=None,
        metavar="KEY=VALUE,...",
        help="label in an Apache Beam pipeline with these options (pip install rp_jax[beam]), "
        "e.g. runner=DirectRunner,direct_num_workers=2,direct_running_mode=multi_processing",
    )
    command_line.add_quiet(b)
    o = sub.add_parser("outcomes", help="write the per-image-pair outcomes beside a dataset")
    common(o)
    command_line.add_manual_dir(o)
    o.add_argument("--workers", type=int, default=1,
                   help="processes matching viewpoints whose outcomes were not cached "
                   "(default 1)")
    command_line.add_quiet(o)
    c = sub.add_parser("curves", help="write the average ground-truth curves as PNGs")
    common(c)
    c.add_argument("--out", type=Path, required=True, help="PNG of the per-split curves")
    return p


def _print_counts(name: str, config: str, data_dir) -> None:
    from rp_jax import categories
    from rp_jax.datasets import loading, statistics
    from rp_jax.schedule import preset

    labels = preset(name).labels
    for split, n in loading.splits(name, config=config, data_dir=data_dir).items():
        cols = loading.load_columns(
            name, split, keys=("slot", "category", "viewpoint"), config=config, data_dir=data_dir
        )
        print(f"{split}: {n} records, {len(set(cols['viewpoint'].tolist()))} viewpoints")
        per_slot = statistics.counts(cols["slot"])
        print(
            "  per timestamp: "
            + ", ".join(f"{labels[s]}={per_slot.get(s, 0)}" for s in range(len(labels)))
        )
        per_cat = statistics.counts(cols["category"])
        if any(c >= 0 for c in per_cat):
            print(
                "  per category: "
                + ", ".join(
                    f"{categories.NAMES.get(c, 'unknown' if c < 0 else str(c))}={k}"
                    for c, k in per_cat.items()
                )
            )


def _build(args) -> int:
    from rp_jax.datasets import loading, provenance

    if args.synthetic_root is not None and args.config == "real":
        raise _UsageError("--synthetic-root is for the synthetic world, not the real data "
                          "(--manual-dir / --real)")
    if args.workers is not None and args.workers < 1:
        raise _UsageError(f"--workers must be >= 1, got {args.workers}")
    if args.manual_dir is not None and not args.manual_dir.is_dir():
        raise _UsageError(f"--manual-dir {args.manual_dir} is not a folder")
    builder = loading.get_builder(
        args.name,
        config=args.config,
        data_dir=args.data_dir,
        synthetic_root=args.synthetic_root,
        workers=args.workers,
    )
    beam_options = None
    if args.beam_pipeline_options is not None:
        from rp_jax.datasets.builder import beam_pipeline_options

        try:
            beam_options = beam_pipeline_options(args.beam_pipeline_options)
        except ImportError as err:
            raise _UsageError(f"--beam-pipeline-options needs apache-beam ({err.msg}): install "
                              "the beam extra in an environment of its own (README, Scaling "
                              "out)") from None
    start = time.perf_counter()
    # A real dataset already built there must have been built from this --manual-dir.
    if not provenance.prepare(builder, args.manual_dir, beam_options=beam_options):
        print(f"{args.name}/{args.config} already built in {builder.data_dir}")
    else:
        print(
            f"built {args.name}/{args.config} in {time.perf_counter() - start:.1f} s "
            f"-> {builder.data_dir}"
        )
    _print_counts(args.name, args.config, args.data_dir)
    return 0


def _outcomes(args) -> int:
    from rp_jax.datasets import loading, outcomes, provenance

    if args.workers < 1:
        raise _UsageError(f"--workers must be >= 1, got {args.workers}")
    if args.manual_dir is not None and not args.manual_dir.is_dir():
        raise _UsageError(f"--manual-dir {args.manual_dir} is not a folder")
    builder = loading.get_builder(args.name, config=args.config, data_dir=args.data_dir)
    provenance.prepare(builder, args.manual_dir)
    start = time.perf_counter()
    directory = outcomes.build(builder, manual_dir=args.manual_dir, workers=args.workers)
    print(f"per-pair outcomes of {args.name}/{args.config} in {time.perf_counter() - start:.1f} s"
          f" -> {directory}")
    return 0


def _curves(args) -> int:
    from rp_jax import categories, plots
    from rp_jax.datasets import loading, statistics
    from rp_jax.schedule import preset

    if args.out.suffix.lower() != ".png":
        raise _UsageError(f"--out must name a .png file, got {args.out}")
    labels = preset(args.name).labels
    per_split, per_group = {}, {g: {} for g in categories.FIGURE9_GROUPS}
    contrast = {}
    for split in loading.splits(args.name, config=args.config, data_dir=args.data_dir):
        cols = loading.load_columns(
            args.name,
            split,
            keys=("label", "label_mask", "category", "slot"),
            config=args.config,
            data_dir=args.data_dir,
        )
        if not len(cols["label"]):
            continue
        per_split[split] = statistics.average_curve(cols["label"], cols["label_mask"])
        for group, curve in statistics.category_curves(
            cols["label"], cols["label_mask"], cols["category"]
        ).items():
            per_group[group][split] = curve
        contrast[split] = statistics.own_date_contrast(
            cols["label"], cols["label_mask"], cols["category"], cols["slot"]
        )
    if not per_split:
        raise _UsageError(f"{args.name}/{args.config} has no records to plot")
    title = f"{args.name} ({args.config}): average ground-truth repeatability"
    written = [plots.plot_average_curves(per_split, labels, args.out, title=title)]
    for split, (mean, count) in per_split.items():
        print(
            f"{split}: "
            + ", ".join(f"{lab}={m:.3f}" for lab, m, n in zip(labels, mean, count) if n)
        )
    if any(per_group.values()):
        out = args.out.with_name(f"{args.out.stem}_categories.png")
        written.append(
            plots.plot_category_curves(
                per_group, labels, out, title=f"{args.name} ({args.config}): per category"
            )
        )
    if any(contrast.values()):
        for split, groups in contrast.items():
            print(
                f"{split}, own timestamp vs others: "
                + ", ".join(f"{g} {v['own']:.3f} vs {v['others']:.3f}" for g, v in groups.items())
            )
        out = args.out.with_name(f"{args.out.stem}_own_date.png")
        written.append(
            plots.plot_own_date_contrast(
                contrast, out, title=f"{args.name} ({args.config}): own timestamp vs the others"
            )
        )
    for path in written:
        print(f"wrote {path}")
    return 0


class _UsageError(Exception):
    """A bad combination of arguments: printed without a traceback, exit status 2."""


def _builder_config(prog: str, args) -> str:
    """The TFDS builder config the flags select (``--size`` / ``--manual-dir`` / ``--real``)."""
    manual_dir = getattr(args, "manual_dir", None)
    real = args.real or manual_dir is not None
    if args.config_name is not None:  # the released spelling
        command_line.deprecation_warning(prog, f"--config {args.config_name}",
                                         _FLAGS_OF_CONFIG[args.config_name])
        if args.size is not None or (real and args.config_name != "real"):
            raise _UsageError(f"--config {args.config_name} and "
                              f"{'--size' if args.size else '--manual-dir/--real'} disagree: "
                              "give only --size, or --manual-dir / --real")
        return args.config_name
    if real and args.size is not None:
        raise _UsageError(f"--size {args.size} is the synthetic world's size; --manual-dir / "
                          "--real select the real data: give one or the other")
    return "real" if real else _CONFIG_OF_SIZE[args.size or "full"]


def main(argv: list[str] | None = None) -> int:
    """Run the CLI; returns the exit status."""
    parser = _parser()
    args = parser.parse_args(argv)
    if getattr(args, "quiet", False):
        from rp_jax import progress

        progress.set_quiet()
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    for noisy in ("absl", "matplotlib"):
        logging.getLogger(noisy).setLevel(logging.WARNING)
    from rp_jax.datasets.loading import NotBuiltError
    from rp_jax.files import folder_problem
    from rp_jax.sources.layout import LayoutError
    from rp_jax.sources.synthetic.output_folder import OutputFolderError

    try:
        args.config = _builder_config(f"{parser.prog} {args.command}", args)
        problem = None if args.data_dir is None else folder_problem(args.data_dir)
        if problem is not None and (args.command != "curves" or args.data_dir.is_file()):
            # build and outcomes write there; curves only reads (a shared, read-only store)
            raise _UsageError(f"--data-dir {args.data_dir} {problem}; expected the TFDS data "
                              "directory (a folder you may write in, created if absent)")
        command = {"build": _build, "outcomes": _outcomes, "curves": _curves}[args.command]
        return command(args)
    except (_UsageError, NotBuiltError, LayoutError, OutputFolderError) as err:
        print(f"{parser.prog} {args.command}: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
