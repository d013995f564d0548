"""Presets of the synthetic world: the paper's three datasets, in their real write_layout.

The paper trains and tests on Webcam Clip Art and Extended CMU Seasons (Sec. IV-A-1) and
on Oxford RobotCar (Sec. IV-B-1, Table I). None can be downloaded here, so each preset
renders a synthetic stand-in with the same cameras, timestamps and cycles and writes it in
*exactly* the real on-disk layout (``DATA_FORMATS.md``), read by the same readers.

One module per preset writes its layout (each module's docstring shows it):
``plan_webcam`` (``webcam_clipart``: 8 static webcams, AMOS-style UTC names, a ``.mat`` of
sun angles per frame), ``plan_cmu`` (``cmu_seasons``: a car's two cameras on the paper's 12
dates, with the reference traversal's COLMAP model) and ``plan_robotcar`` (``robotcar``: the
9 traversals of Table I, raw Bayer frames near 23 viewpoints, ``ins.csv`` at 10 Hz); beyond
the paper, ``webcam_years`` (``plan_webcam.plan_years``: the webcams on the same days of
six years, the world's slow changes on, ``slow_changes``) and ``webcam_years_frozen`` (the
same frames without them), for the long-term decay of issue 17, and ``robotcar_seasons``
(``plan_robotcar_seasons``: RobotCar Seasons' overcast reference traversal and its nine
query conditions, three cameras, in the release's layout), ``robotcar_day``
(``plan_robotcar.plan_day``: the ``robotcar`` layout with one traversal per hour of the day,
for an RP over the whole day), and ``webcam_worlds`` /
``webcam_worlds_unseen`` (``plan_worlds``: the Webcam layout with every webcam in a city and
street of its own, for an RP trained on many worlds and judged on held-out ones). They
share the frame jobs and their rendering (``frame_jobs``). This module names the presets
and renders one (``plan``, ``generate``); the presets' public names stay importable from it.

Sizes: ``tiny`` is for tests (seconds: small images, 2 scenes/slices/traversals, a
handful of slots), ``small`` for a quick look, ``full`` the paper's scale.
"""

from __future__ import annotations

import functools
import json
import logging
import os
import shutil
import time
from collections.abc import Mapping
from pathlib import Path

from rp_jax.sources.synthetic import (
    plan_cmu,
    plan_robotcar,
    plan_robotcar_seasons,
    plan_webcam,
    plan_worlds,
    write_layout,
)
from rp_jax.sources.synthetic.frame_jobs import (
    EVALUATION_DIR,
    SYNTHETIC_DIR,
    FrameJob,
    Plan,
    SceneSpec,
    render_job,
    run_jobs,
)
from rp_jax.sources.synthetic.plan_cmu import (
    CMU_DATES,
    CMU_TIMEZONE,
    REFERENCE_DATE,
    REFERENCE_WEATHER,
    build_reference_model,
    cmu_cameras,
    write_reference_model,
)
from rp_jax.sources.synthetic.plan_robotcar import robotcar_traversals
from rp_jax.sources.synthetic.plan_webcam import WEBCAM_CITIES, webcam_days, webcam_times

__all__ = [
    "CMU_DATES",
    "CMU_TIMEZONE",
    "EVALUATION_DIR",
    "PRESET_NAMES",
    "REFERENCE_DATE",
    "REFERENCE_WEATHER",
    "SIZES",
    "SYNTHETIC_DIR",
    "WEBCAM_CITIES",
    "WORLD_VERSION",
    "world_version",
    "FrameJob",
    "Plan",
    "SceneSpec",
    "build_reference_model",
    "cmu_cameras",
    "default_workers",
    "discard_older_world",
    "generate",
    "plan",
    "render_job",
    "robotcar_traversals",
    "run_jobs",
    "webcam_days",
    "webcam_times",
    "world_marker",
    "write_reference_model",
]

log = logging.getLogger(__name__)

PRESET_NAMES = (
    "webcam_clipart",
    "cmu_seasons",
    "robotcar",
    "webcam_years",
    "webcam_years_frozen",
    "robotcar_seasons",
    "robotcar_day",
    "webcam_worlds",
    "webcam_worlds_unseen",
)
# Bumped whenever the same (preset, size, seed) renders different pixels or file names; a
# layout rendered by another version is rendered again
# (``rp_jax.datasets.builder.ensure_synthetic``).
# 2: foliage moves in the wind (``render.FOLIAGE_SWAY_M``).
# 3: webcam frames are named on the UTC clock (the camera's wall clock before), with a v7.3
#    .mat of sun angles each; CMU query poses also in slice{N}/camera-poses/; the CMU
#    reference traversal as the real one is described (Apr 4, sunny, no foliage) and
#    traversals starting between 9:00 and 16:00 (9:30-14:30 before); brick walls, lawns,
#    lawn paths and flat roofs textured with real photographs of brick, grass and gravel
#    (``photo_textures``, from scikit-image; windows, signs and snow where they were).
# 4: parked cars stay with their street's dwell times (``traffic.parked_car``; a new car every
#    4 hours before) and window glass mirrors the sky (``sky.reflect_sky_in_glass``).
WORLD_VERSION = 4
# Presets whose pixels moved further than ``WORLD_VERSION`` (the others render as before):
# 5: robotcar_seasons' nights in physical units (``photometry.EN_13201``) taken by the
#    RobotCar's Grasshopper2 at 11.1 Hz with its exposure limit and motion blur
#    (``camera_effects.GRASSHOPPER2_11HZ``).
# robotcar_day renders its nights as robotcar_seasons' version 5 does, from its first version.
# 6: in both, Oxford's own climate (``conditions.CLIMATE_NORMALS``; the latitude's froze
#    their winters), the passing cars' and the camera's own car's dipped headlamps at night
#    and, in rain at night, the wet road mirroring the lamps and headlamps
#    (``night_lights``); robotcar_seasons' snow traversal a documented snowy day.
# 7: webcam_clipart's and the many-worlds presets' cities in their own climates
#    (``conditions.CLIMATE_NORMALS``): the latitude's gave London, Paris, Seattle, Dublin or
#    Rome continental winters, with snow lying on their winter capture days.
# 8: robotcar (the paper's Table I traversals) in Oxford's own climate too: the latitude's
#    laid snow on four of its nine traversals (February 13, March 17, November 18 and 28:
#    the 9:00, 11:00, 12:00 and 13:00 slots), none of them snowy in Oxford's.
# 9: robotcar_seasons and robotcar_day light their windows by a published household
#    lighting profile on Oxford's clock (``household_lighting``; a step function of the
#    hour before): several times more lit windows at dawn, dusk and on the snow morning
#    (the sun below 8 degrees), about as many at night.
_PRESET_WORLD_VERSIONS = {"robotcar_seasons": 9, "robotcar_day": 9, "webcam_clipart": 7,
                          "webcam_worlds": 7, "webcam_worlds_unseen": 7, "robotcar": 8}


def world_version(preset: str | None) -> int:
    """The world version that renders ``preset`` now (``WORLD_VERSION`` unless the preset
    moved on alone)."""
    return _PRESET_WORLD_VERSIONS.get(preset, WORLD_VERSION)


SIZES = ("tiny", "small", "full")


def world_marker(root: str | Path, preset: str | None = None) -> dict | None:
    """The generator's marker of the synthetic world at ``root`` (``preset``, ``size`` and
    ``seed``, an int), if this world version rendered it; None for a real download (no
    marker), another version, another preset than ``preset`` or an unreadable seed.

    The one test of "a synthetic world of this version" for readers that re-derive what the
    renderer drew from its parameters (``datasets.capture_conditions``' weather,
    ``datasets.camera_frame``'s rotations).
    """
    from rp_jax.sources.synthetic import output_folder

    marker = output_folder.folder_parameters(Path(root)) or {}
    if (marker.get("preset") not in PRESET_NAMES
            or marker.get("world") != world_version(marker.get("preset"))):
        return None
    if preset is not None and marker["preset"] != preset:
        return None
    try:
        return {**marker, "seed": int(marker["seed"])}
    except (KeyError, TypeError, ValueError):
        return None

# --------------------------------------------------------------------------- entry points

_PLANNERS = {
    "webcam_clipart": plan_webcam.plan,
    "cmu_seasons": plan_cmu.plan,
    "robotcar": plan_robotcar.plan,
    # Beyond the paper: the Webcam layout over six years, with and without slow changes.
    "webcam_years": plan_webcam.plan_years,
    "webcam_years_frozen": functools.partial(plan_webcam.plan_years, slow_changes=False),
    # Beyond the paper: RobotCar Seasons' reference and nine conditions (dawn to snow).
    "robotcar_seasons": plan_robotcar_seasons.plan,
    # Beyond the paper: the RobotCar layout at every hour of the day, for a 24-hour RP.
    "robotcar_day": plan_robotcar.plan_day,
    # Beyond the paper: many worlds for a "universal" RP, and held-out worlds to judge it.
    "webcam_worlds": plan_worlds.plan,
    "webcam_worlds_unseen": plan_worlds.plan_unseen,
}


def plan(preset: str, out_dir: Path, *, size: str = "full", seed: int = 0) -> Plan:
    """The frames a preset renders and its metadata writer, without rendering anything.

    Raises:
      ValueError: an unknown preset or size.
    """
    if preset not in _PLANNERS:
        raise ValueError(f"unknown preset {preset!r}; known: {', '.join(PRESET_NAMES)}")
    if size not in SIZES:
        raise ValueError(f"unknown size {size!r}; known: {', '.join(SIZES)}")
    return _PLANNERS[preset](Path(out_dir), size, int(seed))


def default_workers() -> int:
    """One worker process per CPU core available to this process."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def discard_older_world(root: Path, marker: Mapping | None) -> bool:
    """Delete ``root`` if its generation marker says another world version than the one
    that renders its preset now (``world_version``) rendered it.

    ``marker`` is the parsed marker (``generation.json`` or a partial render's marker; a
    marker without ``"world"`` is version 1), None when there is none. The marker proves the
    folder is this module's own output, so it is removed whole: the renderer skips frames
    whose files exist and would otherwise keep the old pixels. Returns whether it deleted.
    """
    if marker is None:
        return False
    current = world_version(marker.get("preset"))
    if marker.get("world", 1) == current:
        return False
    log.warning(
        "%s was rendered by synthetic world version %s; rendering version %s",
        root,
        marker.get("world", 1),
        current,
    )
    shutil.rmtree(root)
    return True


def generate(
    preset: str,
    out_dir: Path,
    *,
    size: str = "full",
    seed: int = 0,
    workers: int | None = None,
    progress: bool = True,
    overwrite: bool = False,
) -> Path:
    """Render a preset into ``out_dir`` in its real dataset's layout.

    Resumable: frames whose files exist are skipped (each is written under a temporary
    name and renamed, so an existing file is complete); the metadata files are rewritten
    deterministically at the end. The same ``seed`` gives the same files.

    Only into its own folder: ``output_folder.claim`` refuses a non-empty folder the
    generator did not write, or one it rendered with other parameters, unless
    ``overwrite``; ``_synthetic/parameters.json`` names every parameter of the render.

    Args:
      preset: ``"webcam_clipart"``, ``"cmu_seasons"`` or ``"robotcar"``.
      out_dir: the dataset root to write.
      size: ``"tiny"`` (tests, seconds), ``"small"`` or ``"full"`` (the paper's scale).
      seed: world and capture seed.
      workers: processes rendering in parallel (default: one per available core).
      progress: show a tqdm progress bar.
      overwrite: write into a folder of other parameters (deleted first) or one the
        generator did not write (every frame rendered over its files).

    Returns:
      ``out_dir``.

    Raises:
      output_folder.OutputFolderError: ``out_dir`` is not the generator's folder for these
        parameters and ``overwrite`` is not set.
    """
    from rp_jax.sources.synthetic import output_folder

    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise NotADirectoryError(f"output {out_dir} exists and is not a directory")
    if workers is not None and workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    the_plan = plan(preset, out_dir, size=size, seed=seed)
    parameters = {"generator": output_folder.GENERATOR, "preset": preset, "size": size,
                  "seed": seed, "world": world_version(preset)}
    if output_folder.claim(out_dir, parameters, overwrite=overwrite):
        for job in the_plan.jobs:  # a folder not ours: no file of it passes for a frame
            for path in job.outputs:
                path.unlink(missing_ok=True)
    start = time.perf_counter()
    rendered = run_jobs(the_plan.jobs, workers=workers or default_workers(), progress=progress)
    the_plan.finalize()
    output_folder.mark(out_dir, parameters)
    log.info(
        "%s (%s, seed %d): %d frames, %d rendered, %.1f s -> %s",
        preset,
        size,
        seed,
        len(the_plan.jobs),
        rendered,
        time.perf_counter() - start,
        out_dir,
    )
    (out_dir / SYNTHETIC_DIR).mkdir(exist_ok=True)
    write_layout.write_text_atomic(
        out_dir / SYNTHETIC_DIR / "generation.json",
        json.dumps(
            {**parameters, "frames": len(the_plan.jobs)},
            indent=2,
        )
        + "\n",
    )
    return out_dir

