"""Command line of the synthetic world (Sec. IV datasets, rendered in their real layouts).

Usage::

    python -m rp_jax.sources.synthetic PRESET OUT_DIR [--size tiny|small|full] [--seed N]
                                       [--workers N] [--quiet] [--overwrite]
    python -m rp_jax.sources.synthetic contact-sheet OUT.png [--seed N] [--scene I]

PRESET is ``webcam_clipart``, ``cmu_seasons`` or ``robotcar`` (see ``presets``). A run
is resumable (frames already written are skipped) and deterministic for a seed. OUT_DIR
must be new, empty, or a render of the same parameters (``_synthetic/parameters.json``);
``--overwrite`` writes into any other folder.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from rp_jax import command_line
from rp_jax.sources.synthetic.presets import PRESET_NAMES, SIZES, generate

CONTACT_SHEET = "contact-sheet"


def _non_negative_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {value}")
    return value


def _positive_int(text: str) -> int:
    value = _non_negative_int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {value}")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (one sub-command per preset, plus ``contact-sheet``)."""
    parser = argparse.ArgumentParser(
        prog="python -m rp_jax.sources.synthetic",
        description="Render the synthetic world in a real dataset's on-disk layout.",
    )
    sub = parser.add_subparsers(
        dest="command", metavar="{" + ",".join(PRESET_NAMES) + f",{CONTACT_SHEET}}}"
    )
    sub.required = True
    for name in PRESET_NAMES:
        p = sub.add_parser(name, help=f"write the {name} layout")
        p.add_argument("out_dir", type=Path, help="dataset root to write (created if needed)")
        p.add_argument(
            "--size",
            choices=SIZES,
            default="full",
            help=command_line.SIZE_HELP.format(default="full"),
        )
        p.add_argument("--seed", type=_non_negative_int, default=0, help="world seed")
        p.add_argument(
            "--workers",
            type=_positive_int,
            default=None,
            help="rendering processes (default: one per core)",
        )
        command_line.add_quiet(p)
        p.add_argument(
            "--overwrite",
            action="store_true",
            help="write into OUT_DIR although the generator did not write it, or wrote it "
            "with other parameters (deleted first)",
        )
    p = sub.add_parser(CONTACT_SHEET, help="render a webcam through a day and a year")
    p.add_argument("out_png", type=Path, help="day sheet PNG; the year sheet is <stem>_year.png")
    p.add_argument("--seed", type=_non_negative_int, default=0)
    p.add_argument("--scene", type=_non_negative_int, default=0, help="webcam scene index 0-7")
    p.add_argument("--width", type=_positive_int, default=320)
    p.add_argument("--height", type=_positive_int, default=240)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    if args.command == CONTACT_SHEET:
        if args.out_png.suffix.lower() != ".png":
            parser.error(f"contact sheet output must end in .png, got {args.out_png}")
        if args.scene > 7:
            parser.error(f"--scene must be 0..7 (the 8 webcam scenes), got {args.scene}")
        from rp_jax.sources.synthetic.contact_sheet import render_sheets

        for path in render_sheets(
            args.out_png,
            scene_index=args.scene,
            seed=args.seed,
            width=args.width,
            height=args.height,
        ):
            print(path)
        return 0
    from rp_jax.files import folder_problem

    problem = folder_problem(args.out_dir)
    if problem is not None:
        parser.error(f"OUT_DIR {args.out_dir} {problem}")
    from rp_jax.sources.synthetic.output_folder import OutputFolderError

    try:
        out = generate(
            args.command,
            args.out_dir,
            size=args.size,
            seed=args.seed,
            workers=args.workers,
            progress=not args.quiet,
            overwrite=args.overwrite,
        )
    except OutputFolderError as err:  # not its folder: nothing was written
        print(f"{parser.prog}: error: {err}", file=sys.stderr)
        return 2
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
