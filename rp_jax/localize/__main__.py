"""``python -m rp_jax.localize``: localize query images against a (summary) map (Sec. V-B).

    python -m rp_jax.localize --map DIR --queries DIR [--ground-truth FILE] --out DIR

Writes ``DIR/submission.txt`` (visuallocalization.net format) and ``DIR/localization.json``
and prints, with ``--ground-truth``, the three-threshold accuracy table. The library
function is ``rp_jax.localize.run.localize_folder``. A ground-truth file is read in the
convention it states or ``--ground-truth-format`` gives (``rp_jax.localize.pose_files``:
the submission's translation t, or the Extended CMU Seasons camera centre C); the
dataset's own ``intrinsics.txt`` (per camera, ``c0``/``c1``) serves as ``--intrinsics``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from rp_jax import command_line, files, progress
from rp_jax.commands import OVERWRITE_HELP, InputError, run_command
from rp_jax.localize import pose_files

PROG = "python -m rp_jax.localize"


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG,
        description="Localize query images against a map: retrieval, 2D-3D matching, "
        "PnP-RANSAC. Writes the visuallocalization.net submission and, with --ground-truth, "
        "the accuracy within (0.25 m, 2 deg), (0.5 m, 5 deg) and (5 m, 10 deg).",
    )
    p.add_argument("--map", required=True, metavar="DIR",
                   help="map folder written by python -m rp_jax.mapsum summarize (model/ and "
                   "localization.npz), or a COLMAP model folder (then give --images or "
                   "--features)")
    p.add_argument("--queries", required=True, metavar="DIR",
                   help="folder of query images (.jpg, .jpeg, .png; names relative to it)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created)")
    p.add_argument("--ground-truth", metavar="FILE",
                   help="true query poses: a COLMAP model folder, or a file of 'name qw qx qy qz "
                   "X Y Z' lines (world-to-camera rotation) in the convention it states: a '# "
                   "name qw qx qy qz tx ty tz' or '... cx cy cz' header, or an Extended CMU "
                   "Seasons ground-truth name (ground-truth-*-images-slice*.txt, camera-poses/"
                   "*.txt: camera centres); or RobotCar Seasons' robotcar_v2_*.txt (a name and "
                   "a row-major camera-to-world matrix); else give --ground-truth-format")
    p.add_argument("--ground-truth-format", choices=tuple(pose_files.FORMATS),
                   help="what a --ground-truth line holds: submission, a quaternion and the "
                   "translation t (visuallocalization.net); camera-centre, a quaternion and the "
                   "camera centre C (Extended CMU Seasons ground truth, t = -R C); "
                   "camera-to-world, the row-major camera-to-world matrix (RobotCar Seasons v2)")
    p.add_argument("--intrinsics", metavar="FILE",
                   help="query cameras: hloc's queries_with_intrinsics.txt lines 'name MODEL W "
                   "H params...' (COLMAP models), or the dataset's intrinsics.txt of 'c0 OPENCV "
                   "W H params...' lines (a query takes the camera its name holds, c0 in "
                   "img_..._c0_...us.jpg); default: the map's camera if it has exactly one of "
                   "the query's size")
    p.add_argument("--images", metavar="DIR",
                   help="database images of a plain COLMAP model given as --map (to describe it "
                   "with SIFT)")
    p.add_argument("--features", metavar="FILE",
                   help="hloc features.h5 holding the queries' keypoints and descriptors (for a "
                   "map described with the same file)")
    p.add_argument("--global-features", metavar="FILE",
                   help="hloc global-feats-*.h5 (NetVLAD, ...) holding the queries' global "
                   "descriptors; default: VLAD with the map's vocabulary")
    p.add_argument("--num-retrieved", type=int, default=10, metavar="K",
                   help="database images retrieved per query (default 10)")
    p.add_argument("--match-ratio", type=float, default=0.8, metavar="R",
                   help="Lowe's ratio of the 2D-3D matching (default 0.8)")
    p.add_argument("--reprojection-error", type=float, default=8.0, metavar="PX",
                   help="PnP-RANSAC inlier threshold in pixels (default 8)")
    p.add_argument("--min-inliers", type=int, default=12, metavar="N",
                   help="fewer PnP inliers is a failure (default 12)")
    p.add_argument("--max-keypoints", type=int, default=4000, metavar="N",
                   help="SIFT keypoints per image (default 4000)")
    p.add_argument("--seed", type=int, default=0, help="RANSAC (and VLAD) seed (default 0)")
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    command_line.add_quiet(p)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the flags, localize, print the counts and the accuracy table."""
    args = _parser().parse_args(argv)
    if args.quiet:
        progress.set_quiet()

    def body() -> int:
        # Here, not at the top: --help and a bad flag need none of the pipeline's libraries.
        from rp_jax.localize.evaluate import DEFAULT_THRESHOLDS
        from rp_jax.localize.run import RESULTS, SUBMISSION, localize_folder, threshold_key

        for flag, folder, what in (("--map", args.map, "map folder"),
                                   ("--queries", args.queries, "folder of query images")):
            if not Path(folder).is_dir():
                raise InputError(f"{flag} {folder}: no such {what}")
        with files.OutputFolder(args.out, [SUBMISSION, RESULTS], overwrite=args.overwrite):
            result = localize_folder(
                args.map, args.queries, args.out, ground_truth=args.ground_truth,
                ground_truth_format=args.ground_truth_format, images=args.images,
                features=args.features, global_features=args.global_features,
                intrinsics=args.intrinsics, num_retrieved=args.num_retrieved,
                match_ratio=args.match_ratio, reprojection_error=args.reprojection_error,
                min_inliers=args.min_inliers, max_keypoints=args.max_keypoints, seed=args.seed)
        if result["map_camera_queries"]:
            named = (f"not in --intrinsics {args.intrinsics}" if args.intrinsics
                     else "no --intrinsics")
            print(f"{result['map_camera_queries']} of {result['queries']} queries took the map's "
                  f"only camera ({named}); their per_query 'camera' in {RESULTS} is 'map'")
        print(f"localized {result['localized']} of {result['queries']} queries against "
              f"{result['map_points']} map points; wrote {args.out}/{SUBMISSION}")
        if result["accuracy"] is not None:
            print(f"accuracy on the {result['scored']} queries with a true pose:")
            for th in DEFAULT_THRESHOLDS:
                label = f"({th[0]:g} m, {th[1]:g} deg)"
                print(f"  {label:16s} {result['accuracy'][threshold_key(th)]:6.1f} %")
        return 0

    return run_command(PROG, body)


if __name__ == "__main__":
    sys.exit(main())
