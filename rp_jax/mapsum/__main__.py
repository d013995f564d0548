"""``python -m rp_jax.mapsum summarize``: summarize one's own COLMAP model (Sec. V-A).

    python -m rp_jax.mapsum summarize --model COLMAP_DIR --images IMAGE_DIR \\
        --predictor MODEL --at TIME --ratio 0.8 [--method rp|kcover|random|most_observed] \\
        [--all-slots] --out DIR

Writes a map folder (``model/`` binary, ``model_txt/`` text, ``localization.npz``,
``summary.json``) that ``python -m rp_jax.localize --map`` reads; with ``--all-slots`` one per
timestamp of the predictor's schedule. The library function is
``rp_jax.mapsum.model_summary.summarize_model``. ``--out`` is a ``files.OutputFolder`` (a
user's own ``summary.json`` there is never replaced without ``--overwrite``; a failed run
leaves nothing), ``--ratio`` must lie strictly between 0 and 1, and ``--at`` is checked
against the predictor's schedule (and what part of a time it reads) before any work.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from rp_jax import command_line, files, progress
from rp_jax.commands import (
    INPUT_ERRORS,
    OVERWRITE_HELP,
    InputError,
    check_time_has_what_the_model_reads,
    datetime_flag,
    load_predictor,
    run_command,
    time_inputs,
)

PROG = "python -m rp_jax.mapsum"
METHOD_CHOICES = ("rp", "kcover", "random", "most_observed")


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=PROG, description="Map summarization with predicted "
                                "repeatability (Sec. V-A of the paper).")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")
    s = sub.add_parser(
        "summarize", prog=f"{PROG} summarize",
        help="keep the points of a COLMAP model that a method ranks first at a query time",
        description="Summarize a COLMAP model: keep the (1 - RATIO) share of each part of the "
        "map that METHOD ranks first (rp: the most repeatable at --at, predicted from the "
        "database images' patches at their capture times). Writes a map folder: model/ "
        "(COLMAP binary), model_txt/ (text), localization.npz and summary.json.")
    s.add_argument("--model", required=True, metavar="COLMAP_DIR",
                   help="COLMAP model folder (cameras, images, points3D as .bin or .txt)")
    s.add_argument("--images", required=True, metavar="IMAGE_DIR",
                   help="folder of the model's database images (names as in the model)")
    s.add_argument("--out", required=True, metavar="DIR",
                   help="output folder (created; files in it that this command did not write "
                   "are never replaced without --overwrite; a failed run leaves nothing)")
    s.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    s.add_argument("--ratio", required=True, type=float, metavar="R",
                   help="pruning ratio: the fraction of each part's points removed, strictly "
                   "between 0 and 1 (0 would keep the whole map, 1 would leave none)")
    s.add_argument("--method", choices=METHOD_CHOICES, default="rp",
                   help="rp: most repeatable at --at (the paper's); kcover: Li et al.'s "
                   "minimal scene description; random; most_observed: longest tracks "
                   "(default rp)")
    s.add_argument("--predictor", metavar="MODEL",
                   help="trained predictor workdir (config.json, schedule.json, checkpoints/) "
                   "or a shipped model's name (e.g. cmu_seasons-synthetic); needed by "
                   "--method rp")
    s.add_argument("--at", type=datetime_flag, metavar="TIME",
                   help='query time, e.g. "2024-12-01 17:00" (wall clock of the map\'s place); '
                   "needed by --method rp unless --all-slots. The predictor reads only part of "
                   "it (the command prints which: the time of day for webcam_clipart-synthetic "
                   "and robotcar-synthetic, the day of the year for cmu_seasons-synthetic); a "
                   "date alone is midnight, refused for a predictor that reads the time of day")
    s.add_argument("--all-slots", action="store_true",
                   help="one summary per timestamp of the predictor's schedule, in "
                   "DIR/slot_<j>_<label>/ (the paper's periodic server job; --method rp)")
    s.add_argument("--times", metavar="CSV",
                   help="capture times of the database images, 'name,datetime' rows; default: "
                   "each image's EXIF DateTimeOriginal, else its name (Extended CMU Seasons "
                   "img_..._<unix us>us.jpg, RobotCar <unix us>.png, or YYYYMMDD_HHMMSS)")
    s.add_argument("--features", metavar="FILE",
                   help="hloc features.h5 the model was built from: the points' descriptors come "
                   "from it (default: SIFT re-detected on the images)")
    s.add_argument("--global-features", metavar="FILE",
                   help="hloc global-feats-*.h5 (NetVLAD, ...) of the database images, for "
                   "retrieval (default: VLAD over the local descriptors)")
    s.add_argument("--partition", choices=("kmeans", "grid", "none"), default="kmeans",
                   help="map parts pruned separately: k-means of the 3D points (--parts), a "
                   "ground-plane grid (--cell-size) or none (default kmeans)")
    s.add_argument("--parts", type=int, default=8, metavar="N",
                   help="k-means parts (default 8, capped at the number of points)")
    s.add_argument("--cell-size", type=float, metavar="S",
                   help="grid cell side in the model's units (--partition grid)")
    s.add_argument("--max-keypoints", type=int, default=4000, metavar="N",
                   help="SIFT keypoints re-detected per database image (default 4000)")
    s.add_argument("--seed", type=int, default=0,
                   help="seed of k-means, --method random and VLAD (default 0)")
    s.add_argument("--html", metavar="PAGE",
                   help="also write PAGE (.html, --method rp): a self-contained page, offline, "
                   "of the map seen from above with a slider over the predictor's timestamps "
                   "showing which points the summary keeps at each, and each clicked point's "
                   "repeatability curve (docs/page.md)")
    command_line.add_quiet(s)
    return p


def _outputs(args, predictor) -> list[str]:
    """What ``summarize_model`` writes in ``--out`` (``files.OutputFolder``'s names)."""
    from rp_jax.localize.map_description import (
        MAP_DESCRIPTION,
        MAP_MODEL_DIR,
        MAP_MODEL_TEXT_DIR,
    )
    from rp_jax.mapsum.model_summary import POINT_REPEATABILITY, SUMMARY_JSON, slot_folder

    names = [SUMMARY_JSON] + ([POINT_REPEATABILITY] if args.method == "rp" else [])
    if args.all_slots:
        return names + [slot_folder(j, label) for j, label in enumerate(predictor.schedule.labels)]
    return names + [MAP_MODEL_DIR, MAP_MODEL_TEXT_DIR, MAP_DESCRIPTION]


def _check_inside_schedule(at, schedule) -> None:
    """Refuse, before any work, an --at the predictor's schedule does not cover (the library
    found it only after predicting every observation of the map)."""
    import numpy as np

    from rp_jax import predict
    from rp_jax.schedule import OutsideScheduleError

    if at is None:
        return
    try:
        predict.at_time(np.zeros(schedule.num_timestamps), schedule, at)
    except OutsideScheduleError as err:
        raise InputError("--at " + str(err).split("; pass wrap=True")[0]) from err


def _summarize(args) -> int:
    from rp_jax.mapsum.model_summary import summarize_model
    from rp_jax.sources.capture_times import CaptureTimes, read_time_table

    if not 0.0 < args.ratio < 1.0:  # 1 wrote an empty map with exit status 0
        raise InputError(f"--ratio {args.ratio:g}: expected a pruning ratio strictly between 0 "
                         "and 1, the fraction of the points removed (0 keeps the whole map, 1 "
                         "leaves no point to localize against)")
    if not Path(args.model).is_dir():
        raise InputError(f"--model {args.model}: no such folder")
    if not Path(args.images).is_dir():
        raise InputError(f"--images {args.images}: no such folder")
    predictor = capture_time = None
    if args.method == "rp":
        if args.predictor is None:
            raise InputError("--method rp needs --predictor MODEL")
        if args.at is None and not args.all_slots:
            raise InputError("--method rp needs --at TIME (or --all-slots)")
        capture_time = CaptureTimes(table=read_time_table(args.times) if args.times else None,
                                    hint="give --times CSV with name,datetime rows")
    elif args.all_slots:
        raise InputError(f"--all-slots summarizes per timestamp of the predictor; --method "
                         f"{args.method} does not depend on time")
    if args.html is not None:  # checked before any work
        from rp_jax import page

        if args.method != "rp":
            raise InputError(f"--html shows the summary at each timestamp: it needs --method "
                             f"rp, not {args.method}")
        try:
            page.check_page_path(args.html)
        except page.PageExistsError as err:
            raise InputError(f"--html {err}") from err
    if args.partition == "grid" and not args.cell_size:
        raise InputError("--partition grid needs --cell-size (in the model's units)")
    if args.method == "rp":
        from rp_jax import platform

        platform.configure_cpu()
        predictor = load_predictor(args.predictor, "--predictor")
        check_time_has_what_the_model_reads("--at", args.at, predictor.config)
        _check_inside_schedule(args.at, predictor.schedule)
        print(f"predictor {Path(str(args.predictor)).name} reads "
              f"{time_inputs(predictor.config)}")
    with files.OutputFolder(args.out, _outputs(args, predictor), overwrite=args.overwrite):
        try:
            records = summarize_model(
                args.model, args.images, args.out, ratio=args.ratio, method=args.method,
                predictor=predictor, at=args.at, all_slots=args.all_slots,
                capture_time=capture_time, features=args.features,
                global_features=args.global_features, partition_method=args.partition,
                parts=args.parts, cell_size=args.cell_size, max_keypoints=args.max_keypoints,
                seed=args.seed)
        except ValueError as err:  # e.g. a time the predictor's schedule does not cover
            if isinstance(err, INPUT_ERRORS):
                raise
            raise InputError(str(err)) from err
    if args.html is not None:
        from rp_jax.mapsum.summary_page import summary_page

        page.write_page(args.html, summary_page(
            args.model, args.out, predictor.schedule, ratio=args.ratio,
            partition_method=args.partition, parts=args.parts, cell_size=args.cell_size,
            seed=args.seed, at=args.at, predictor_name=Path(args.predictor).name))
        print(f"wrote the page {args.html}")
    for r in records:
        when = f" slot {r['slot']}" if "slot" in r else (
            f" at {r['at']:%Y-%m-%d %H:%M}" if r.get("at") else "")
        print(f"{r['method']}{when}: kept {r['kept_points']} of {r['map_points']} points "
              f"({r['parts']} parts, ratio {r['ratio']:g}; every database image keeps >= "
              f"{r['kept_points_per_image']['min']}) -> {r['folder']}")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the flags and run the subcommand."""
    args = _parser().parse_args(argv)
    if args.quiet:
        progress.set_quiet()
    return run_command(PROG, lambda: _summarize(args))


if __name__ == "__main__":
    sys.exit(main())
