"""``python -m experiments.decay``: the inlier fraction against years apart, slow changes off
vs on (issue 17; ``experiments.decay.measure``).

Usage::

    python -m experiments.decay [--size tiny|small|full] [--workdir DIR] [--seed N]
                                [--workers N] [--max-keypoints N] [--resamples N]
                                [--kinds tenant,repaint,...] [--quiet]
    python -m experiments.decay --predict [--size small] [--num-epochs N]
                                [--points-per-image N] [--workdir DIR] [--quiet]

Writes ``<workdir>/decay.json``, ``decay.md``, ``decay.png`` and ``years.png`` (default
workdir ``runs/decay_<size>``; ``decay-<kinds>.*`` with ``--kinds``) and prints the tables.
Resumable: renders and labels already on disk are reused.

``--predict``: the conditional predictor with and without its long-term decay basis,
trained on the ``webcam_years`` training scenes but one and scored on that one per
years-apart bin (``experiments.decay.predict``); writes ``predict.json``, ``.md``, ``.png``.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

from rp_jax import command_line

DEFAULT_SIZE = "small"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m experiments.decay",
        description="Inlier fraction against the years between capture and target image, "
        "in the synthetic Webcam world with its slow changes off and on.",
    )
    command_line.add_size(parser, DEFAULT_SIZE)
    parser.add_argument("--workdir", type=Path, default=None,
                        help="run directory (default runs/decay_<size>); resumes if present")
    parser.add_argument("--seed", type=int, default=0, help="world seed")
    parser.add_argument("--workers", type=int, default=None,
                        help="rendering processes (default: one per core)")
    parser.add_argument("--max-keypoints", type=int, default=1000,
                        help="interest points per image (the ground truth's cap)")
    parser.add_argument("--resamples", type=int, default=2000,
                        help="bootstrap resamples of the intervals")
    parser.add_argument("--kinds", default=None,
                        help="an ablation: only these slow changes, comma-separated, of "
                        "tenant, repaint, sign, tree_replacement, tree_growth (default: all); "
                        "writes decay-<kinds>.*")
    parser.add_argument("--predict", action="store_true",
                        help="instead: train the conditional predictor with and without its "
                        "decay basis on the changing world's training scenes but one, and "
                        "score it on that one per years apart (needs --size small or full)")
    parser.add_argument("--num-epochs", type=float, default=4.0,
                        help="with --predict: training epochs of each model")
    parser.add_argument("--points-per-image", type=int, default=40,
                        help="with --predict: interest points kept per image")
    command_line.add_quiet(parser)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    from rp_jax.sources.synthetic.slow_changes import KINDS

    if args.kinds is not None:
        unknown = sorted(set(args.kinds.split(",")) - set(KINDS))
        if unknown:
            parser.error(f"--kinds {args.kinds}: unknown {', '.join(unknown)}; expected a "
                         f"comma-separated subset of {', '.join(KINDS)}")
    for flag, value, least in (("--workers", args.workers, 1), ("--seed", args.seed, 0),
                               ("--max-keypoints", args.max_keypoints, 1),
                               ("--resamples", args.resamples, 1)):
        if value is not None and value < least:
            parser.error(f"{flag} {value}: expected an integer >= {least}")
    if args.workdir is not None:
        command_line.check_writable_folder(parser, "--workdir", args.workdir)
    logging.basicConfig(level=logging.WARNING if args.quiet else logging.INFO,
                        format="%(levelname)s %(name)s: %(message)s")
    from experiments.decay.measure import category_markdown, markdown, run

    workdir = args.workdir or Path("runs") / f"decay_{args.size}"
    if args.predict:
        from experiments.decay import predict

        if args.num_epochs <= 0 or args.points_per_image < 1:
            parser.error("--num-epochs > 0 and --points-per-image >= 1 expected")
        try:
            result = predict.run(workdir, size=args.size, seed=args.seed,
                                 workers=args.workers, max_keypoints=args.max_keypoints,
                                 points_per_image=args.points_per_image, epochs=args.num_epochs,
                                 progress=not args.quiet)
        except ValueError as e:
            parser.error(str(e))
        print(predict.markdown(result), end="")
        print(f"written into {workdir}: predict.json, .md, .png")
        return 0
    result = run(workdir, size=args.size, seed=args.seed, workers=args.workers,
                 max_keypoints=args.max_keypoints, resamples=args.resamples,
                 kinds=None if args.kinds is None else tuple(args.kinds.split(",")),
                 progress=not args.quiet)
    print(markdown(result["bins"]))
    print(category_markdown(result["by_category"]), end="")
    print(f"written into {workdir}: decay*.json, .md, .png, years*.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
