"""``python -m rp_jax.keypoints``: the repeatable keypoints of images at a time (the command).

The library is ``rp_jax.keypoints`` (``image_keypoints``); this module is its command line:
one ``.npz`` and one overlay PNG per image. ``--help`` lists the flags.
"""

from __future__ import annotations

import argparse
import datetime as dt
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from rp_jax import command_line, page, shipped
from rp_jax.commands import (
    FALLBACK_MAX_SIZE,
    OVERWRITE_HELP,
    TIME_INPUTS,
    InputError,
    check_time_has_what_the_model_reads,
    datetime_flag,
    load_predictor,
    model_about,
    run_command,
    time_inputs,
    wrap_hint,
)
from rp_jax.files import OutputFolder
from rp_jax.keypoints import (
    DEFAULT_MAX_KEYPOINTS,
    colour_range,
    image_keypoints,
    load_image,
    write_overlay,
)
from rp_jax.schedule import OutsideScheduleError
from rp_jax.sources import hloc
from rp_jax.sources.capture_times import CaptureTimes

__all__ = ["main", "run"]

PROG = "python -m rp_jax.keypoints"
OVERLAY_SUFFIX = "_repeatability.png"


def _output_stems(paths: Sequence[Path]) -> list[str]:
    stems = [p.stem for p in paths]
    seen: dict[str, Path] = {}
    for p, s in zip(paths, stems):
        if s in seen:
            raise InputError(f"{seen[s]} and {p} would both write {s}.npz: give them separate "
                             "runs or different --out folders")
        seen[s] = p
    return stems


def resolve_max_size(max_size: int | None, model: str | os.PathLike | None) -> int | None:
    """``--max-size``: None or absent means the model's training resolution (the longer
    side of ``trained_image_size`` in its ``model.json``; ``FALLBACK_MAX_SIZE`` for a
    workdir that does not say); 0 keeps every image as it is."""
    if max_size == 0:
        return None
    if max_size is not None:
        if max_size < 0:
            raise InputError(f"--max-size {max_size}: expected a number of pixels (0: no limit)")
        return int(max_size)
    size = model_about(model).get("trained_image_size") if model is not None else None
    return int(max(size)) if size else FALLBACK_MAX_SIZE


def run(
    images: Sequence[str | os.PathLike],
    model: str | os.PathLike,
    out: str | os.PathLike,
    *,
    captured: dt.datetime | None = None,
    at: dt.datetime | None = None,
    features: str | os.PathLike | None = None,
    max_keypoints: int = DEFAULT_MAX_KEYPOINTS,
    overlay: bool = True,
    predictor=None,
    html: str | os.PathLike | None = None,
    max_size: int | None = None,
    wrap: bool | None = None,
    overwrite: bool = False,
) -> list[dict]:
    """The command's work: every image's ``.npz`` (and overlay PNG) in ``out``.

    Args:
      images: image files.
      model: the predictor's trained workdir or shipped name (loaded unless ``predictor``
        is given; named in the overlays, its ``model.json`` gives the default ``max_size``).
      out: output folder (created; a ``files.OutputFolder``).
      captured: capture time of every image; None reads each one's EXIF or file name.
      at: query time; None: each image's capture time.
      features: an hloc ``features.h5`` holding the images' keypoints (looked up by name);
        None detects SIFT.
      max_keypoints: SIFT keypoints per image.
      overlay: also write the PNGs (one colour scale for the whole run: ``colour_range``).
      predictor: an already loaded ``Predictor``.
      html: also write the one image's page, scrubbing its keypoints through the cycle
        (``rp_jax.page``).
      max_size: reduce larger images to this longer side first (``resolve_max_size``:
        None, the model's training resolution; 0, none).
      wrap: read ``at`` across the schedule's gap (``rp_jax.predict.at_time``).
      overwrite: replace files in ``out`` that this command did not write.

    Returns:
      One dict per image: image, npz, png, keypoints, captured, at, mean score, image and
      detection size.

    Raises:
      InputError / FileNotFoundError / NoCaptureTimeError / OutputExistsError: a missing
        image or model, an image without a capture time, an image missing from
        ``features``, a time the model cannot read, a file of the user's in ``out``.
    """
    paths = [Path(p) for p in images]
    if not paths:
        raise InputError("no IMAGE given")
    for p in paths:
        if p.is_dir():
            raise InputError(f"{p} is a folder: give its images (e.g. {p / '*.jpg'})")
        if not p.is_file():
            raise InputError(f"{p}: no such image file")
    stems = _output_stems(paths)
    if html is not None:  # checked before any work: one image, and no file of the user's there
        if len(paths) != 1:
            raise InputError(f"--html {html}: a page shows one IMAGE, got {len(paths)}")
        try:
            page.check_page_path(html)
        except page.PageExistsError as err:
            raise InputError(f"--html {err}") from err
    times = CaptureTimes(captured, hint="give --captured TIME")
    whens = [times(p) for p in paths]  # every capture time is known before any work
    names = hloc.NameIndex(hloc.list_names(features)) if features is not None else None
    limit = resolve_max_size(max_size, model)
    outputs = [f"{s}{suffix}" for s in stems
               for suffix in (".npz", *((OVERLAY_SUFFIX,) if overlay else ()))]
    folder = OutputFolder(out, outputs, overwrite=overwrite)
    folder.__enter__()  # refuses a file of the user's before the model is even loaded
    try:
        predictor = predictor if predictor is not None else load_predictor(model, "--predictor")
        for flag, when in (("--captured", captured), ("--at", at)):
            check_time_has_what_the_model_reads(flag, when, predictor.config)
        out = Path(out)
        results, kps = [], []
        for path, stem, when in zip(paths, stems, whens):
            rgb = load_image(path)
            given = scales = None
            if features is not None:
                key = names.find(path.as_posix())
                if key is None:
                    raise InputError(f"--features {features}: no keypoints for image {path}")
                f = hloc.read_local_features(features, key)
                if f.image_size is not None and f.image_size != (rgb.shape[1], rgb.shape[0]):
                    raise InputError(f"--features {features}: image {key!r} is "
                                     f"{f.image_size[0]}x{f.image_size[1]} there but {path} is "
                                     f"{rgb.shape[1]}x{rgb.shape[0]}")
                given, scales = f.keypoints, f.scales
            try:
                kp = image_keypoints(predictor, rgb, when, at=at, keypoints=given, scales=scales,
                                     max_keypoints=max_keypoints, max_size=limit, wrap=wrap)
            except OutsideScheduleError as err:
                raise InputError(f"{path}: {wrap_hint(err)}") from err
            except ValueError as err:
                raise InputError(f"{path}: {err}") from err
            npz = kp.save(out / f"{stem}.npz")
            if html is not None:
                page.write_keypoints_page(html, rgb, kp, predictor.schedule,
                                          model=Path(model).name if model else "",
                                          title=f"{path.name}: {len(kp)} keypoints", wrap=wrap)
            kps.append(kp)
            results.append({
                "image": str(path), "npz": str(npz), "png": None,
                "keypoints": len(kp), "captured": kp.captured, "at": kp.at,
                "mean_score": float(kp.score.mean()) if len(kp) else float("nan"),
                "image_size": kp.image_size, "detection_size": kp.detection_size,
                "time_inputs": time_inputs(predictor.config),
            })
        if overlay:  # one colour scale for the run's images, known once all are predicted
            vmin, vmax = colour_range(kps)
            for path, stem, kp, r in zip(paths, stems, kps, results):
                r["png"] = str(write_overlay(
                    load_image(path), kp, out / f"{stem}{OVERLAY_SUFFIX}",
                    title=f"{path.name}: {len(kp)} keypoints, captured "
                    f"{kp.captured:%Y-%m-%d %H:%M}", model=Path(str(model)).name,
                    vmin=vmin, vmax=vmax))
    except BaseException as err:
        folder.__exit__(type(err), err, err.__traceback__)  # removes what this run wrote
        raise
    folder.__exit__(None, None, None)
    return results


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG,
        description="Keypoints of your images, their predicted repeatability curves (one "
        "value per timestamp of the model's schedule) and their score at a query time. "
        "Writes DIR/<stem>.npz and DIR/<stem>_repeatability.png per image.",
    )
    p.add_argument("images", nargs="+", metavar="IMAGE", help="image files (JPEG, PNG, ...)")
    p.add_argument("--predictor", metavar="MODEL",
                   help="(required) trained predictor: a workdir with config.json, "
                   "schedule.json and checkpoints/ (python -m experiments.webcam_clipart "
                   f"writes one), or a model shipped in the package ({', '.join(shipped.names())})")
    p.add_argument("--captured", type=datetime_flag, metavar="TIME",
                   help='capture time of every IMAGE on its own wall clock, e.g. "2024-06-01 '
                   '09:30"; default: each image\'s EXIF DateTimeOriginal, else its file name '
                   "(Extended CMU Seasons, RobotCar or YYYYMMDD_HHMMSS conventions)")
    p.add_argument("--at", type=datetime_flag, metavar="TIME",
                   help="query time the score (and the overlay colour) is read at; default: "
                   "the capture time. A model reads only part of a time: "
                   + "; ".join(f"{k.replace('_', ' ')} models read {v}"
                               for k, v in TIME_INPUTS.items())
                   + " (model.json's time_inputs; the command prints it). A date alone is "
                   "midnight: refused for a model that reads the time of day")
    p.add_argument("--wrap", action="store_true",
                   help="read --at across the gap between the schedule's last and first "
                   "timestamps (e.g. 22:00 for an 08:00-18:00 model: interpolated between "
                   "18:00 and 08:00 of the next day, which the model never saw); without it "
                   "such a time is refused")
    command_line.deprecated_alias(p, "--model", "--predictor", dest="predictor")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output folder (created; files in it that this command did not write "
                   "are never replaced without --overwrite; a failed run leaves nothing)")
    p.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    p.add_argument("--max-size", type=int, metavar="PX",
                   help="reduce each image so that its longer side is at most PX pixels before "
                   "detection (default: the resolution the model was trained at, model.json's "
                   f"trained_image_size: 640 for webcam_clipart-synthetic; {FALLBACK_MAX_SIZE} "
                   "for a workdir that does not say; 0: no limit). Why: the model sees "
                   "64x64-pixel patches, so the same photo at another size shows it other "
                   "patches and scores differently. Memory: the photo is decoded whole (3 bytes "
                   "a pixel, twice at the peak: 0.3 GB for 50 megapixels), then detection and "
                   "prediction cost what a PX-pixel image does, under 1 GB in all at the "
                   "default; without a limit SIFT and the patches grow with the photo, several "
                   "GB for a 12-megapixel one (python -m experiments.benchmark.large_image "
                   "prints both on your machine)")
    p.add_argument("--features", metavar="FILE",
                   help="hloc features.h5 whose keypoints to use instead of detecting SIFT "
                   "(images looked up by name)")
    p.add_argument("--max-keypoints", type=int, default=DEFAULT_MAX_KEYPOINTS, metavar="N",
                   help=f"SIFT keeps the N strongest keypoints (default {DEFAULT_MAX_KEYPOINTS})")
    p.add_argument("--no-overlay", action="store_true", help="write the .npz files only")
    p.add_argument("--html", metavar="PAGE",
                   help="also write PAGE (.html, one IMAGE): a self-contained page, offline, "
                   "with a slider over the model's cycle that re-colours the keypoints and "
                   "each clicked keypoint's repeatability curve (docs/page.md)")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the flags, run, print one line per image."""
    parser = _parser()
    args = parser.parse_args(argv)
    if args.predictor is None:
        parser.error("the following arguments are required: --predictor")
    from rp_jax import platform

    platform.configure_cpu()

    def body() -> int:
        results = run(args.images, args.predictor, args.out, captured=args.captured, at=args.at,
                      features=args.features, max_keypoints=args.max_keypoints,
                      overlay=not args.no_overlay, html=args.html, max_size=args.max_size,
                      wrap=args.wrap or None, overwrite=args.overwrite)
        if results:
            print(f"model {Path(str(args.predictor)).name} reads {results[0]['time_inputs']}")
        for r in results:
            if r["detection_size"] != r["image_size"]:
                print(f"{r['image']}: reduced from {r['image_size'][0]}x{r['image_size'][1]} to "
                      f"{r['detection_size'][0]}x{r['detection_size'][1]} (--max-size)")
            png = f" and {Path(r['png']).name}" if r["png"] else ""
            captured, at = (f"{r[k]:%Y-%m-%d %H:%M}" for k in ("captured", "at"))
            scored = (f"mean repeatability {r['mean_score']:.3f} at {at}" if r["keypoints"] else
                      "nothing to score (a textureless image, or one too small for SIFT)")
            print(f"{r['image']}: {r['keypoints']} keypoints, captured {captured}, {scored} -> "
                  f"{Path(r['npz']).name}{png}")
        print(f"wrote {len(results)} image(s) to {args.out}"
              + (f" and the page {args.html}" if args.html else ""))
        return 0

    return run_command(PROG, body)


if __name__ == "__main__":
    sys.exit(main())
