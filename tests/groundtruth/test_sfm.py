"""Per-viewpoint SfM with COLMAP on our features and matches (Sec. III-D step 4)."""

import numpy as np

from rp_jax.groundtruth.features import detect_and_describe
from rp_jax.groundtruth.matching import PairwiseMatches, match_all_pairs, prepare_descriptors
from rp_jax.groundtruth.sfm import mutual_matches, reconstruct_viewpoint
from tests.groundtruth import _scenes
from tests.groundtruth.test_viewpoint_pose import K, _posed_viewpoint


def test_mutual_matches_keep_cross_checked_ratio_matches():
    nn = [np.array([[-1, 0], [-1, 1], [-1, 1]]), np.array([[0, -1], [2, -1]])]
    ok = [
        np.array([[False, True], [False, True], [False, True]]),
        np.array([[True, False], [True, False]]),
    ]
    m = PairwiseMatches(nn, nn, nn, ok)
    # 0<->0 mutual; 1->1 but 1->2: not mutual; 2->1 and 1->2: mutual.
    np.testing.assert_array_equal(mutual_matches(m, 0, 1), [[0, 0], [2, 1]])


def _angle_deg(R):
    return np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))


def test_reconstruction_recovers_relative_poses():
    caps = _posed_viewpoint("sfm_unit", wrong_pose=False)
    images = [_scenes.load_from_registry(c) for c in caps]
    feats = [detect_and_describe(im, max_keypoints=300) for im in images]
    matches = match_all_pairs([prepare_descriptors(f.descriptor, "l2") for f in feats])
    poses = reconstruct_viewpoint(
        [c.image_id for c in caps],
        [(im.shape[1], im.shape[0]) for im in images],
        [K] * len(caps),
        [f.xy for f in feats],
        matches,
    )
    assert poses is not None and len(poses) == len(caps)
    for (R_est, t_est), c in zip(poses[1:], caps[1:]):
        R0_est, t0_est = poses[0]
        # Relative pose of image i w.r.t. image 0: rotation exact, translation up to scale.
        R_rel_est = R_est @ R0_est.T
        R_rel_true = c.R @ caps[0].R.T
        assert _angle_deg(R_rel_est @ R_rel_true.T) < 1.0
        t_rel_est = t_est - R_rel_est @ t0_est
        t_rel_true = c.t - R_rel_true @ caps[0].t
        cos = t_rel_est @ t_rel_true / np.linalg.norm(t_rel_est) / np.linalg.norm(t_rel_true)
        assert cos > 0.98
