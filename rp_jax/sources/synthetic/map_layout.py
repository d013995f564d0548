"""The frames the map-summarization experiment needs, rendered in the Extended CMU layout.

Sec. IV-B of the paper localizes the queries of Extended CMU Seasons slice 8 against the
slice's reference model. A full synthetic render of the ``cmu_seasons`` preset takes
minutes; the experiment needs only one slice's reference traversal (the map) and its
queries, so ``ensure_cmu_map_layout`` renders just those into the same folder the
``cmu_seasons`` builder uses (a later full render resumes from them) and writes the slice's
metadata exactly as the real release lays it out.
"""

from __future__ import annotations

import datetime as dt
import json
import os
import zoneinfo
from collections.abc import Sequence
from pathlib import Path

from rp_jax.sources.capture import Camera
from rp_jax.sources.synthetic import presets, write_layout

__all__ = ["available_query_dates", "ensure_cmu_map_layout"]

CMU_TIMEZONE = presets.CMU_TIMEZONE


def _slice_jobs(size: str, seed: int, slice_id: int, root: Path):
    plan = presets.plan("cmu_seasons", root, size=size, seed=seed)
    slice_name = f"slice{slice_id}"
    in_slice = [j for j in plan.jobs if j.image_path.parent.parent.name == slice_name]
    if not in_slice:
        raise ValueError(f"the synthetic cmu_seasons preset ({size}) has no {slice_name}")
    return in_slice


def available_query_dates(size: str, seed: int = 0, slice_id: int = 8) -> list[dt.date]:
    """Local dates of the traversals other than the reference in ``slice_id`` (sorted).

    On the test slice these are its queries; on a training slice, its held-out traversals.
    """
    tz = zoneinfo.ZoneInfo(CMU_TIMEZONE)
    jobs = _slice_jobs(size, seed, slice_id, Path("/nonexistent-plan-only"))
    return sorted({j.when.astimezone(tz).date() for j in jobs if j.keypoints_path is None})


def ensure_cmu_map_layout(
    root: str | os.PathLike,
    *,
    size: str,
    seed: int,
    slice_id: int,
    query_dates: Sequence[dt.date],
    workers: int | None = None,
    progress: bool = True,
) -> Path:
    """Render the synthetic CMU frames the experiment needs, in the real layout.

    A finished full render (``_synthetic/generation.json``) is used as is. Otherwise only
    the test slice's reference traversal (the map) and its queries of ``query_dates`` are
    rendered (frames already there are skipped), and the slice's metadata is written for
    those frames: ``intrinsics.txt``, the database ground truth, ``test-images-slice{N}.txt``,
    the query ground truth in ``camera-poses/`` (and ``_evaluation/``) and the reference
    model ``sparse/``. On a training slice the other traversals stay in ``database/`` with
    their poses (held-out traversals for choosing settings). A later
    ``rp_jax.sources.synthetic.generate`` on the same folder renders the rest and rewrites
    the metadata.

    Args:
      root: the layout folder.
      size: synthetic size (``tiny``, ``small``, ``full``).
      seed: world seed.
      slice_id: the test slice (8 in the paper).
      query_dates: local dates of the queries to render.
      workers: rendering processes (default: one per core).
      progress: tqdm bars.

    Returns:
      ``root``.

    Raises:
      ValueError: a finished layout of another size/seed, or a date the preset lacks.
    """
    root = Path(root)
    done = root / presets.SYNTHETIC_DIR / "generation.json"
    marker = root / presets.SYNTHETIC_DIR / "map_subset.json"
    full = json.loads(done.read_text()) if done.is_file() else None
    if full is not None:
        want = {"preset": "cmu_seasons", "size": size, "seed": seed}
        if {k: full.get(k) for k in want} != want:
            raise ValueError(f"{root} holds the synthetic layout {full}, not {want}")
        if full.get("world", 1) == presets.WORLD_VERSION:
            return root
    want_marker = {
        "size": size,
        "seed": seed,
        "slice": slice_id,
        "query_dates": sorted(d.isoformat() for d in query_dates),
        "world": presets.WORLD_VERSION,
    }
    partial = json.loads(marker.read_text()) if marker.is_file() else None
    if partial == want_marker:
        return root
    presets.discard_older_world(root, full if full is not None else partial)
    tz = zoneinfo.ZoneInfo(CMU_TIMEZONE)
    slice_name = f"slice{slice_id}"
    in_slice = _slice_jobs(size, seed, slice_id, root)
    reference = [j for j in in_slice if j.keypoints_path is not None]
    # A test slice's other traversals are its queries (query/); a training slice keeps
    # them in database/ with their poses, where they serve as held-out queries.
    queries = [j for j in in_slice if j.keypoints_path is None]
    available = sorted({j.when.astimezone(tz).date() for j in queries})
    wanted = set(query_dates)
    missing = wanted - set(available)
    if missing:
        raise ValueError(
            f"the synthetic cmu_seasons preset ({size}) has no {slice_name} queries on "
            f"{sorted(d.isoformat() for d in missing)}; its query dates are "
            f"{[d.isoformat() for d in available]}"
        )
    queries = [j for j in queries if j.when.astimezone(tz).date() in wanted]
    presets.run_jobs(
        reference + queries, workers=workers or presets.default_workers(), progress=progress
    )

    def cam_id(job) -> str:
        return job.image_path.name.split("_")[2]

    cameras = {}
    for j in reference:
        cameras.setdefault(cam_id(j), Camera("OPENCV", j.width, j.height, j.K, j.distortion))
    cameras = dict(sorted(cameras.items()))
    write_layout.write_cmu_intrinsics(root / "intrinsics.txt", cameras)
    slice_dir = root / slice_name
    for folder in ("database", "query"):
        (slice_dir / folder).mkdir(parents=True, exist_ok=True)
    in_query = [j for j in queries if j.image_path.parent.name == "query"]
    in_database = reference + [j for j in queries if j.image_path.parent.name == "database"]
    write_layout.write_cmu_poses(
        slice_dir / f"ground-truth-database-images-{slice_name}.txt",
        [(j.image_path.name, j.R, j.t) for j in in_database],
    )
    write_layout.write_name_list(
        slice_dir / f"test-images-{slice_name}.txt", [j.image_path.name for j in in_query]
    )
    if in_query:
        # As the release ships them (slice{N}/camera-poses/), and in _evaluation/ as the full
        # synthetic render also writes them.
        entries = [(j.image_path.name, j.R, j.t) for j in in_query]
        write_layout.write_cmu_query_poses(slice_dir, entries)
        write_layout.write_cmu_poses(
            root / presets.EVALUATION_DIR / f"ground-truth-query-images-{slice_name}.txt",
            entries,
        )
    presets.write_reference_model(
        slice_dir / "sparse", [(j, cam_id(j)) for j in reference], cameras
    )
    write_layout.write_text_atomic(marker, json.dumps(want_marker, indent=2) + "\n")
    return root
