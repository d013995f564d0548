"""Per-viewpoint Structure-from-Motion when no poses are known (Sec. III-D step 4, IV-B-1).

The paper's step 4 is "perform SfM and accept the matching pair if it can form a 3D
point"; on Oxford RobotCar it runs SfM per viewpoint and keeps only the viewpoints whose
images all register. Here COLMAP (``pycolmap``) reconstructs the viewpoint from *our*
interest points and mutual-nearest-neighbour ratio-test matches (COLMAP's own two-view
geometric verification, then incremental mapping); the recovered poses then feed the same
pose-based check as known poses (``verification.epipolar_inliers`` and
``triangulation.triangulation_inliers``).

Coordinates: COLMAP puts the centre of the top-left pixel at (0.5, 0.5), OpenCV (and
``rp_jax``) at (0, 0); keypoints and principal points are shifted by 0.5 on the way in and
out. Intrinsics are held fixed at the given K (known cameras), so the poses are in the
images' own pixel frame; the reconstruction's scale is arbitrary, which neither check
depends on.
"""

from __future__ import annotations

import logging
import shutil
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rp_jax.groundtruth.matching import PairwiseMatches

__all__ = ["mutual_matches", "reconstruct_viewpoint"]

logger = logging.getLogger(__name__)


def mutual_matches(matches: PairwiseMatches, a: int, b: int) -> np.ndarray:
    """Ratio-test matches of the pair (a, b) that are also each other's nearest neighbour.

    Returns:
      uint32 [M, 2] of (index in a, index in b).
    """
    i = np.flatnonzero(matches.ratio_ok[a][:, b])
    j = matches.nn[a][i, b]
    back_ok = matches.ratio_ok[b][j, a] & (matches.nn[b][j, a] == i)
    return np.stack([i[back_ok], j[back_ok]], axis=1).astype(np.uint32)


def reconstruct_viewpoint(
    names: Sequence[str],
    image_sizes: Sequence[tuple[int, int]],
    intrinsics: Sequence[np.ndarray],
    xys: Sequence[np.ndarray],
    matches: PairwiseMatches,
    *,
    work_dir: str | Path | None = None,
    min_pair_matches: int = 15,
    seed: int = 0,
    num_threads: int = 1,
) -> list[tuple[np.ndarray, np.ndarray]] | None:
    """World-to-camera poses (R, t) of every image of a viewpoint, or None.

    Args:
      names: unique image names.
      image_sizes: (W, H) per image.
      intrinsics: 3x3 pinhole K per image (OpenCV pixel convention), held fixed.
      xys: [N_i, 2] interest point coordinates per image (OpenCV pixel convention).
      matches: nearest neighbours + ratio test of all ordered pairs.
      work_dir: where COLMAP's database and model go (a temporary folder if None; it is
        removed afterwards either way).
      min_pair_matches: COLMAP's minimum inliers of a verified pair.
      seed: COLMAP's random seed (reproducible labels).
      num_threads: COLMAP threads.

    Returns:
      one (R [3,3], t [3]) per image, in the order given, if a single reconstruction
      registers *every* image (the paper keeps only such viewpoints); else None.
    """
    import pycolmap

    from rp_jax.sources.colmap_model import colmap_xy

    n = len(names)
    if n < 2:
        return None
    root = Path(tempfile.mkdtemp(prefix="rp_sfm_", dir=work_dir))
    log_level = pycolmap.logging.minloglevel
    pycolmap.logging.minloglevel = 1  # COLMAP's INFO lines would flood a labelling run
    try:
        db_path = root / "database.db"
        db = pycolmap.Database.open(str(db_path))
        ids = []
        for name, (w, h), K, xy in zip(names, image_sizes, intrinsics, xys):
            cam = pycolmap.Camera(
                model="PINHOLE",
                width=int(w),
                height=int(h),
                params=[K[0, 0], K[1, 1], *colmap_xy(K[:2, 2])],
            )
            cam_id = db.write_camera(cam)
            sensor = pycolmap.sensor_t(pycolmap.SensorType.CAMERA, cam_id)
            rig = pycolmap.Rig()
            rig.add_ref_sensor(sensor)
            rig_id = db.write_rig(rig)
            image_id = db.write_image(pycolmap.Image(name=name, camera_id=cam_id))
            frame = pycolmap.Frame()
            frame.rig_id = rig_id
            frame.add_data_id(pycolmap.data_t(sensor, image_id))
            db.write_frame(frame)
            db.write_keypoints(image_id, colmap_xy(xy).astype(np.float32).reshape(-1, 2))
            ids.append(image_id)
        pairs = []
        for a in range(n):
            for b in range(a + 1, n):
                m = mutual_matches(matches, a, b)
                if len(m) >= min_pair_matches:
                    db.write_matches(ids[a], ids[b], m)
                    pairs.append(f"{names[a]} {names[b]}")
        db.close()
        if not pairs:
            return None
        (root / "pairs.txt").write_text("\n".join(pairs) + "\n")

        tvg = pycolmap.TwoViewGeometryOptions()
        tvg.min_num_inliers = min_pair_matches
        tvg.detect_watermark = False  # a static background is content here, not a watermark
        tvg.ransac.random_seed = seed
        pycolmap.verify_matches(str(db_path), str(root / "pairs.txt"), tvg)

        opts = pycolmap.IncrementalPipelineOptions()
        opts.multiple_models = False
        opts.random_seed = seed
        opts.num_threads = num_threads
        opts.min_model_size = 2
        opts.ba_refine_focal_length = False
        opts.ba_refine_principal_point = False
        opts.ba_refine_extra_params = False
        (root / "sparse").mkdir()
        recs = pycolmap.incremental_mapping(str(db_path), str(root), str(root / "sparse"), opts)
        if not recs:
            return None
        rec = max(recs.values(), key=lambda r: r.num_reg_images())
        posed = {}
        for image in rec.images.values():
            if image.has_pose:
                pose = image.cam_from_world()
                posed[image.name] = (
                    np.asarray(pose.rotation.matrix(), np.float64),
                    np.asarray(pose.translation, np.float64).reshape(3),
                )
        missing = [nm for nm in names if nm not in posed]
        if missing:
            logger.info(
                "SfM registered %d of %d images (missing e.g. %s)", n - len(missing), n, missing[:3]
            )
            return None
        return [posed[nm] for nm in names]
    finally:
        pycolmap.logging.minloglevel = log_level
        shutil.rmtree(root, ignore_errors=True)
