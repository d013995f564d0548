"""Why the day map localizes no night query: the night camera's factors taken away in turn.

In the RobotCar-Seasons-like world (``conditions``) the full map, built by overcast day,
localizes no night or night-rain query, so the by-condition run's primary comparison (does
knowing the condition keep what localizes at night?) cannot be read. The night is several
physical things at once (``rp_jax.sources.synthetic``): street lamps and lit windows instead
of the sky (``photometry.EN_13201``), and a camera that meets the dark with its longest
exposure, during which the car moves on, and then with gain, which raises the noise
(``camera_effects.GRASSHOPPER2_11HZ``). This experiment re-renders a sample of one world's
night queries with one of those taken away at a time and asks the same full map again:

- ``as_taken``: the preset's own frame, re-rendered (the layout's image before its JPEG);
- ``still``: the car stands while the shutter is open (no motion blur; the same exposure,
  gain and noise);
- ``noiseless``: no sensor noise (the same exposure, gain and blur);
- ``still_noiseless``: neither;
- ``short_exposure``: the camera as it is but for its auto-exposure, stopped where the car's
  motion moves a point 10 m to the side by one pixel (6-8 ms at the full size's speeds,
  against the frame period's 90 ms), the rest made up by gain: a blur-limiting exposure
  policy, which trades the blur for a darker, noisier frame;
- ``by_day``: the same view at the reference traversal's time of day and sky (overcast,
  around noon): what the map was built from, the ceiling of the other rows.

Each variant is a counterfactual of one frame, never a setting of the world: the run
changes no layout and no result of ``conditions``. Every variant goes through the layout's
JPEG, SIFT (as a query is described) and the full map's localization (VLAD retrieval,
2D-3D matching, PnP-RANSAC, as ``world.localize_full_map``); the report gives, per
condition and variant, the keypoints, the map points re-detected under the true pose (the
oracles' evidence, ``oracles.redetection_hits``), how many frames re-detect at least as many
points as a pose needs inliers, and the share localized within (0.5 m, 5°) and (5 m, 10°).

::

    python -m experiments.map_summarization.night_factors --size full --seed 0
    python -m experiments.map_summarization.night_factors --size tiny --frames 4   # a check
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from experiments.map_summarization import conditions as cond_lib
from experiments.map_summarization.pooling import THRESHOLD_KEYS, success
from experiments.map_summarization.queries import describe_query
from experiments.map_summarization.world import localization_kwargs
from rp_jax.localize import LocalizationMap, localize_all
from rp_jax.mapsum.oracles import redetection_hits
from rp_jax.sources import robotcar_seasons as rcs
from rp_jax.sources.capture import Camera

NAME = "map_summarization_night_factors"
FACTORS = {
    "as_taken": "as taken (the preset's frame)",
    "still": "the car still while the shutter is open (no motion blur)",
    "noiseless": "no sensor noise",
    "still_noiseless": "no motion blur and no sensor noise",
    "short_exposure": "exposure stopped at one pixel of blur 10 m away, the rest by gain",
    "by_day": "the same view by day (the reference traversal's time and sky)",
}
NIGHT_CONDITIONS = cond_lib.CONDITION_GROUPS["night"]
# ``short_exposure``: the exposure at which the car's motion moves a point this far to the
# side of the camera by one pixel (blur below a pixel for everything farther). 10 m is about
# the distance from the car's lane to the nearer row of facades on the preset's street
# (``scene.facade_y``: 10.6-13.7 m from the centre line in world seeds 0-4, the car's
# eastbound lane 1.7 m from it),
# where most of the map's points lie.
BLUR_DISTANCE_M = 10.0


@dataclasses.dataclass(frozen=True)
class World:
    """A synthetic RobotCar-Seasons-like layout and the preset's plan that rendered it."""

    root: Path
    seed: int
    size: str
    jobs: list  # the plan's FrameJobs


def synthetic_world(root: Path) -> World:
    """The layout at ``root`` with its preset's frames (the plan of the seed and size its
    ``_synthetic/parameters.json`` records).

    Raises:
      LayoutError: not a layout the synthetic ``robotcar_seasons`` preset wrote.
    """
    params_path = root / "_synthetic" / "parameters.json"
    try:
        params = json.loads(params_path.read_text())
    except (OSError, ValueError) as e:
        raise cond_lib.LayoutError(
            f"{params_path}: unreadable ({e}); expected the parameters the synthetic "
            "robotcar_seasons preset writes (its frames are re-rendered)") from None
    if params.get("preset") != "robotcar_seasons":
        raise cond_lib.LayoutError(f"{params_path}: preset {params.get('preset')!r}, expected "
                                   "'robotcar_seasons'")
    return planned_world(root, params["size"], int(params["seed"]))


def planned_world(root: Path, size: str, seed: int) -> World:
    """The ``robotcar_seasons`` preset's frames of ``size`` and ``seed``, as if written to
    ``root`` (nothing is rendered or written)."""
    from rp_jax.sources.synthetic import plan_robotcar_seasons

    return World(root, seed, size, plan_robotcar_seasons.plan(root, size, seed).jobs)


def condition_jobs(world: World, condition: str) -> list:
    """Every frame of ``condition``, in the plan's order.

    Raises:
      LayoutError: the preset renders no frame of ``condition`` at the world's size.
    """
    jobs = [j for j in world.jobs if j.image_path.parent.parent.name == condition]
    if not jobs:
        raise cond_lib.LayoutError(f"{world.root}: the preset renders no {condition} frame")
    return jobs


def sample_jobs(world: World, condition: str, frames: int) -> list:
    """``frames`` query frames of ``condition``, spread evenly over its traversal (every
    camera in turn), in the plan's order."""
    jobs = condition_jobs(world, condition)
    picks = np.unique(np.linspace(0, len(jobs) - 1, min(frames, len(jobs))).round().astype(int))
    return [jobs[i] for i in picks]


def by_day(job, condition: str):
    """``job`` at the reference traversal's instant (the same time into the traversal)
    and under its overcast sky."""
    offset = job.when - rcs.traversal_start(condition)
    when = rcs.traversal_start(rcs.REFERENCE_CONDITION) + offset
    from rp_jax.sources.synthetic.plan_robotcar_seasons import CONDITION_WEATHER

    return dataclasses.replace(job, when=when.astimezone(job.when.tzinfo),
                               weather=CONDITION_WEATHER[rcs.REFERENCE_CONDITION])


def counterfactual_job(job, condition: str, factor: str):
    """``job`` (a frame of ``condition``) with ``factor`` (a key of ``FACTORS``) taken away."""
    if factor not in FACTORS:
        raise ValueError(f"unknown factor {factor!r}; expected one of {', '.join(FACTORS)}")
    if factor in ("still", "still_noiseless"):
        job = dataclasses.replace(job, velocity=None)
    if factor in ("noiseless", "still_noiseless"):
        job = dataclasses.replace(job, sensor_noise=0.0)
    if factor == "short_exposure" and job.velocity is not None:
        job = dataclasses.replace(job, exposure_limit_s=blur_limited_exposure(job))
    if factor == "by_day":
        job = by_day(job, condition)
    return job


def blur_limited_exposure(job) -> float:
    """The exposure (s) during which the car's motion moves a point ``BLUR_DISTANCE_M`` to
    the side of the camera by one pixel (f v t / d = 1), at most the sensor's longest."""
    from rp_jax.sources.synthetic import camera_effects

    longest = camera_effects.sensor_named(job.sensor).max_exposure_s
    speed = float(np.linalg.norm(job.velocity))
    return min(longest, BLUR_DISTANCE_M / (float(job.K[0, 0]) * speed))


def render_variant(job, condition: str, factor: str) -> tuple[np.ndarray, dict]:
    """The frame of ``job`` with ``factor`` taken away (``counterfactual_job``), as the
    layout's reader decodes it (after the layout's JPEG), and the camera's meta."""
    from rp_jax.sources.synthetic import frame_jobs, write_layout

    job = counterfactual_job(job, condition, factor)
    frame = frame_jobs.render_frame(job)
    encoded = write_layout.encode_image(np.asarray(frame.rgb), job.image_path.suffix)
    return frame_jobs.decoded_rgb(encoded), frame.meta


COUNTERFACTUAL_JSON = Path("_synthetic") / "counterfactual.json"
GENERATION_JSON = Path("_synthetic") / "generation.json"


def write_counterfactual_layout(src: Path, dst: Path, factor: str, conditions: Sequence[str],
                                *, workers: int = 1, progress: bool = True) -> int:
    """A copy of the synthetic layout ``src`` at ``dst`` in which every query frame of
    ``conditions`` is rendered again with ``factor`` taken away (its image and
    segmentation); every other file is the source's (a hard link where the file system
    allows, else a copy). ``_synthetic/counterfactual.json`` says what was changed; the
    source's generation marker, written last, marks the copy finished, so that the
    experiments read it as they read the source. Resumes where a run stopped.

    Returns:
      The number of frames rendered.

    Raises:
      ValueError: ``dst`` holds files that are not a counterfactual copy of this one.
    """
    import os
    import shutil

    from rp_jax.sources.synthetic import frame_jobs, write_layout

    world = synthetic_world(src)
    record = {"factor": factor, "description": FACTORS.get(factor), "conditions": list(conditions),
              "source": str(src.absolute())}
    mark = dst / COUNTERFACTUAL_JSON
    if mark.is_file():
        found = json.loads(mark.read_text())
        if found != record:
            raise ValueError(f"{mark}: another counterfactual copy ({json.dumps(found)}), not "
                             f"{json.dumps(record)}: choose another folder")
    elif dst.exists() and any(dst.iterdir()):
        raise ValueError(f"{dst}: not empty and not a counterfactual copy (no "
                         f"{COUNTERFACTUAL_JSON}); choose another folder")
    jobs = []
    for c in conditions:
        for job in condition_jobs(world, c):
            rel = job.image_path.relative_to(src)
            seg = (dst / job.segmentation_path.relative_to(src)
                   if job.segmentation_path is not None else None)
            jobs.append(dataclasses.replace(counterfactual_job(job, c, factor),
                                            image_path=dst / rel, segmentation_path=seg,
                                            keypoints_path=None))
    rendered = {j.image_path for j in jobs} | {j.segmentation_path for j in jobs}
    dst.mkdir(parents=True, exist_ok=True)
    write_layout.write_bytes_atomic(mark, (json.dumps(record, indent=1) + "\n").encode())
    for path in sorted(p for p in src.rglob("*") if p.is_file()):
        rel = path.relative_to(src)
        out = dst / rel
        if rel in (GENERATION_JSON, COUNTERFACTUAL_JSON) or out in rendered or out.exists():
            continue
        out.parent.mkdir(parents=True, exist_ok=True)
        try:
            os.link(path, out)
        except OSError:
            shutil.copy2(path, out)
    count = frame_jobs.run_jobs(jobs, workers=workers, progress=progress)
    shutil.copy2(src / GENERATION_JSON, dst / GENERATION_JSON)
    return count


def measure(config, world_map, lmap: LocalizationMap, jobs: Sequence, condition: str,
            factor: str, loc_kwargs: dict) -> dict:
    """One variant of ``jobs``' frames against the full map: per frame its keypoints,
    re-detected map points, localization outcome and the camera's gain and exposure."""
    from rp_jax.sources import images

    m = config.map
    queries, meta, same = [], [], []
    for job in jobs:
        rgb, cam = render_variant(job, condition, factor)
        if factor == "as_taken":  # the re-render is the layout's own image
            same.append(bool(np.array_equal(rgb, images.read_rgb(job.image_path))))
        camera = Camera("PINHOLE", job.width, job.height, job.K)  # undistorted, as written
        queries.append(describe_query(job.image_path.name, rgb, camera, (job.R, job.t),
                                      job.when, job.image_path, m.max_keypoints,
                                      world_map.vocabulary))
        meta.append(cam)
    mp = world_map.map_points
    hits = redetection_hits(
        mp, world_map.point_descriptors,
        [(q["query"].xy, q["query"].descriptors, q["query"].K, *q["pose"], q["size"])
         for q in queries],
        radius_px=m.oracle_radius_px, ratio=m.match_ratio)
    results = localize_all([q["query"] for q in queries], lmap, **loc_kwargs)
    outcomes = [success(q["pose"], (r.pose.R, r.pose.t) if r.success else None)
                for q, r in zip(queries, results)]
    return {
        "keypoints": [int(len(q["query"].xy)) for q in queries],
        "redetected": [int(len(h)) for h in hits],
        "localized": {k: [bool(o[i]) for o in outcomes] for i, k in enumerate(THRESHOLD_KEYS)},
        "gain": [float(c["gain"]) for c in meta],
        "exposure_ms": [1000.0 * float(c.get("exposure_s", 0.0)) for c in meta],
        **({"equals_layout_image": same} if factor == "as_taken" else {}),
    }


def summary(per_frame: dict, min_inliers: int) -> dict:
    """Medians, means and shares of ``measure``'s per-frame lists."""
    red = np.asarray(per_frame["redetected"])
    return {
        "frames": int(len(red)),
        "keypoints_median": float(np.median(per_frame["keypoints"])),
        "redetected_mean": float(red.mean()),
        "redetected_median": float(np.median(red)),
        "redetected_max": int(red.max()),
        "enough_redetected": float(np.mean(red >= min_inliers)),
        "localized": {k: float(np.mean(v)) for k, v in per_frame["localized"].items()},
        "gain_median": float(np.median(per_frame["gain"])),
        "exposure_ms_median": float(np.median(per_frame["exposure_ms"])),
    }


def rendered_conditions(world: World) -> list[str]:
    """The query conditions the preset renders, in the dataset's order."""
    present = {j.image_path.parent.parent.name for j in world.jobs}
    return [c for c in rcs.QUERY_CONDITIONS if c in present]


def run(config, workdir: Path, *, seed: int, frames: int,
        conditions: Sequence[str] | None = None, progress: bool = True) -> dict:
    """Every factor on ``frames`` frames of each of ``conditions`` (default: the night
    conditions the world's size renders) of world ``seed``; writes ``metrics.json`` and
    ``report.md`` in ``workdir``."""
    from experiments import provenance, run_files
    from rp_jax import files
    from rp_jax.progress import bar as tqdm

    root = cond_lib.ensure_layout(config, seed, progress=progress)
    world = synthetic_world(root)
    present = rendered_conditions(world)
    if conditions is None:
        conditions = [c for c in NIGHT_CONDITIONS if c in present]
    missing = [c for c in conditions if c not in present]
    if missing:
        raise cond_lib.LayoutError(f"{root}: no {', '.join(missing)} frames at size "
                                   f"{world.size} (it renders {', '.join(present)})")
    world_map = cond_lib.build_map(config, root, {}, seed, progress=progress)
    loc_kwargs = localization_kwargs(config, seed)
    lmap = LocalizationMap(world_map.map_points, world_map.point_descriptors, world_map.index)
    results: dict = {}
    steps = [(c, f) for c in conditions for f in FACTORS]
    for c, f in tqdm(steps, desc="night factors", disable=not progress):
        jobs = sample_jobs(world, c, frames)
        per_frame = measure(config, world_map, lmap, jobs, c, f, loc_kwargs)
        results.setdefault(c, {})[f] = {**summary(per_frame, config.map.min_inliers),
                                         "per_frame": per_frame}
    out = {
        "world": {"seed": seed, "size": world.size, "root": _shown(root)},
        "frames_per_condition": frames,
        "min_inliers": int(config.map.min_inliers),
        "factors": FACTORS,
        "results": results,
        "provenance": provenance.gather(),
    }
    workdir.mkdir(parents=True, exist_ok=True)
    run_files.write_json(workdir / "metrics.json", out)
    files.write_text(workdir / "report.md", markdown(out))
    return out


def _shown(path: Path) -> str:
    """``path`` relative to the working directory where it lies below it (a result file
    names no one's home folder), else as it is."""
    try:
        return str(Path(path).absolute().relative_to(Path.cwd()))
    except ValueError:
        return str(path)


def tables_markdown(out: dict) -> str:
    """One table per condition: a row per factor."""
    lines = []
    need = out["min_inliers"]
    for c, by_factor in out["results"].items():
        n = next(iter(by_factor.values()))["frames"]
        lines += [f"**{c}** ({n} frames of world seed {out['world']['seed']}, "
                  f"size {out['world']['size']})", "",
                  "| frame | keypoints | re-detected map points: mean / median / max | "
                  f"frames re-detecting >= {need} | localized (0.5 m, 5 deg) | "
                  "localized (5 m, 10 deg) | gain | exposure |",
                  "|---|---|---|---|---|---|---|---|"]
        for f, s in by_factor.items():
            loc = s["localized"]
            lines.append(
                f"| {FACTORS[f]} | {s['keypoints_median']:.0f} | "
                f"{s['redetected_mean']:.1f} / {s['redetected_median']:.0f} / "
                f"{s['redetected_max']} | {100 * s['enough_redetected']:.0f} % | "
                f"{100 * loc['0.5m_5deg']:.0f} % | {100 * loc['5m_10deg']:.0f} % | "
                f"{s['gain_median']:.0f} | {s['exposure_ms_median']:.1f} ms |")
        lines.append("")
    return "\n".join(lines)


def markdown(out: dict) -> str:
    """The report: what was varied, then the tables."""
    return "\n".join([
        "# Night queries against the day map, one factor taken away at a time", "",
        "Each frame is a night query of the by-condition world re-rendered with one physical "
        "factor of the night capture removed, described with SIFT as a query is and "
        "localized on the full day-built map; keypoints, gain and exposure are medians; "
        f"a pose needs {out['min_inliers']} PnP inliers. Gain: the total scale from scene "
        "radiance to the image, 2 for a sunny noon frame.", "",
        tables_markdown(out),
        f"Command: `{out['provenance']['command']}`; {out['provenance']['date']}; "
        f"{out['provenance']['machine']}.", ""])


def main(argv: list[str] | None = None) -> int:
    """``python -m experiments.map_summarization.night_factors``."""
    import sys

    from experiments import cli

    def add_flags(parser) -> None:
        parser.add_argument("--seed", type=int, default=0, help="world seed (default 0)")
        parser.add_argument("--frames", type=int, default=30,
                            help="frames per condition, spread over its traversal (default 30)")
        parser.add_argument("--conditions", default=None, metavar="C,C,...",
                            help="query conditions (default: night,night-rain, those the "
                            "world's size renders)")
        parser.add_argument("--write-layouts", type=Path, default=None, metavar="DIR",
                            help="instead of measuring: write a copy of each world of --seeds "
                            "under DIR/synthetic/ whose frames of --conditions are rendered "
                            "with --factor taken away (run the by-condition experiment on "
                            "them with --data-dir DIR/tensorflow_datasets)")
        parser.add_argument("--factor", default=None, choices=list(FACTORS),
                            help="with --write-layouts: what the copies take away "
                            "(default still_noiseless)")
        parser.add_argument("--seeds", type=cli.seed_list, default=None, metavar="A,B,...",
                            help="with --write-layouts: the worlds (default: the by-condition "
                            "run's world seeds and its outcome scorer's label worlds)")

    config, workdir, args = cli.parse_flags(argv, NAME, cond_lib.get_config, __doc__,
                                            default_size="full", add_flags=add_flags,
                                            module="map_summarization.night_factors")
    prog = "python -m experiments.map_summarization.night_factors"
    wanted = (None if args.conditions is None
              else [c.strip() for c in args.conditions.split(",") if c.strip()])
    if wanted is not None and (not wanted or any(c not in rcs.QUERY_CONDITIONS for c in wanted)):
        print(f"{prog}: error: --conditions {args.conditions!r}: expected query conditions "
              f"of {rcs.DATASET} ({', '.join(rcs.QUERY_CONDITIONS)})", file=sys.stderr)
        return 2
    if args.manual_dir is not None:
        print(f"{prog}: error: --manual-dir {args.manual_dir}: a real download cannot be "
              "rendered again; this command re-renders a synthetic robotcar_seasons world "
              "(its own, or one on disk: --config.map.root DIR)", file=sys.stderr)
        return 2
    if args.write_layouts is None and (args.seeds is not None or args.factor is not None):
        print(f"{prog}: error: --seeds and --factor go with --write-layouts (to measure one "
              "world: --seed)", file=sys.stderr)
        return 2
    if args.seed < 0 or args.frames < 1:
        print(f"{prog}: error: --seed must be >= 0 and --frames >= 1 (got {args.seed}, "
              f"{args.frames})", file=sys.stderr)
        return 2
    from rp_jax import platform
    from rp_jax import progress as progress_lib

    if args.quiet:
        progress_lib.set_quiet()
    platform.configure_cpu()
    if args.write_layouts is not None:
        return _write_layouts(config, args, wanted, prog)
    try:
        out = run(config, workdir, seed=args.seed, frames=args.frames, conditions=wanted,
                  progress=not args.quiet)
    except cond_lib.LayoutError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    print(f"wrote {workdir}/metrics.json and report.md")
    print(tables_markdown(out))
    return 0


def _write_layouts(config, args, wanted: Sequence[str] | None, prog: str) -> int:
    """``--write-layouts``: a counterfactual copy of each world of the seeds."""
    import os
    import sys

    from rp_jax.datasets import builder as builder_lib

    m = config.map
    seeds = args.seeds if args.seeds is not None else (*m.seeds, *m.outcome_seeds)
    data_dir = args.write_layouts.absolute() / "tensorflow_datasets"
    try:
        for seed in seeds:
            src = cond_lib.ensure_layout(config, seed, progress=not args.quiet)
            world = synthetic_world(src)
            conditions = wanted or [c for c in NIGHT_CONDITIONS
                                    if c in rendered_conditions(world)]
            dst = builder_lib.synthetic_root(data_dir, "robotcar_seasons", m.synthetic_size, seed)
            n = write_counterfactual_layout(src, dst, args.factor or "still_noiseless", conditions,
                                            workers=int(m.workers) or os.cpu_count() or 1,
                                            progress=not args.quiet)
            print(f"{dst}: {', '.join(conditions)} {args.factor or 'still_noiseless'} "
                  f"({n} frames rendered)")
    except (cond_lib.LayoutError, ValueError) as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    print(f"then: python -m experiments.map_summarization.conditions --size "
          f"{m.synthetic_size} --data-dir {data_dir}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
