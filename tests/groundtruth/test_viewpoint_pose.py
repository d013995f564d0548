"""End-to-end ground truth with known poses: Sampson check + triangulation (Sec. IV-A-1)."""

import dataclasses
import json

import cv2
import numpy as np
import pytest

from rp_jax.groundtruth import GroundTruthConfig, label_viewpoint
from rp_jax.sources.capture import Camera
from tests.groundtruth import _scenes
from tests.groundtruth._scenes import HEIGHT, WIDTH, make_capture, textured_image

K = np.array([[180.0, 0, WIDTH / 2], [0, 180.0, HEIGHT / 2], [0, 0, 1]])
DEPTH = 10.0  # the textured plane Z = 10 in the frame of camera 0 (= world frame)


def _rotation(rx, ry, rz):
    R, _ = cv2.Rodrigues(np.radians([rx, ry, rz]))
    return R


def _render(texture, R, t):
    """Image of the plane Z = DEPTH (textured as seen by camera (I, 0)) from pose (R, t)."""
    n = np.array([0.0, 0.0, 1.0])
    H = K @ (R + np.outer(t, n) / DEPTH) @ np.linalg.inv(K)
    return cv2.warpPerspective(
        texture, H, (WIDTH, HEIGHT), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT_101
    )


def _posed_viewpoint(viewpoint="posed", wrong_pose=True):
    tex = textured_image(11)
    poses = [  # (id, cycle, slot, R, t, rendered from a different pose?)
        ("p0", 0, 0, np.eye(3), np.zeros(3), None),
        ("p1", 0, 1, _rotation(1, -2, 0.5), np.array([0.4, 0.05, 0.1]), None),
        ("p2", 1, 0, _rotation(-1.5, 1, 0), np.array([-0.3, 0.1, -0.2]), None),
        ("p3", 1, 1, _rotation(0.5, 2.5, -1), np.array([0.2, -0.2, 0.3]), None),
        # Recorded pose is wrong by 0.8 m across the recorded baseline (which is along x, so
        # its epipolar lines are near horizontal while the true motion is vertical).
        ("bad", 1, 2, _rotation(0, 1, 0), np.array([0.1, 0.0, 0.0]), np.array([0.1, 0.8, 0.0])),
    ]
    caps = []
    for image_id, cycle, slot, R, t, true_t in poses:
        if not wrong_pose and true_t is not None:
            t = true_t
        caps.append(make_capture(image_id, cycle, slot, viewpoint=viewpoint, R=R, t=t, K=K))
        _scenes.IMAGES[f"{viewpoint}/{image_id}"] = _render(tex, R, t if true_t is None else true_t)
    return caps


def test_known_poses_give_inliers_and_reject_a_wrong_pose():
    caps = _posed_viewpoint()
    config = GroundTruthConfig(max_keypoints=200, verification="auto")  # auto -> pose
    rec = label_viewpoint(
        caps,
        load_image=_scenes.load_from_registry,
        num_timestamps=3,
        config=config,
        camera_of=lambda c: K,
    )
    lab, iid = rec["label"], rec["image_id"]
    good = np.isin(iid, ["p0", "p1", "p2", "p3"])
    # Slots 0 and 1 hold two good images each: points of good images repeat there.
    assert lab[good][:, :2].mean() > 0.6
    # The image with a wrong recorded pose (alone in slot 2) is hardly ever an inlier...
    assert lab[good, 2].mean() < 0.1
    assert lab[iid == "bad"][:, :2].mean() < 0.1
    # ... its own points count themselves in their slot ...
    np.testing.assert_array_equal(lab[iid == "bad", 2], 1.0)
    # ... while with its true pose recorded it repeats like the others.
    right = label_viewpoint(
        _posed_viewpoint("posed_right", wrong_pose=False),
        load_image=_scenes.load_from_registry,
        num_timestamps=3,
        config=config,
        camera_of=lambda c: K,
    )
    right_good = np.isin(right["image_id"], ["p0", "p1", "p2", "p3"])
    assert right["label"][right_good, 2].mean() > 0.5

    # Without the 3D steps (static check would be wrong here: the camera moved) far fewer
    # correspondences survive: verification really depends on the poses.
    static = label_viewpoint(
        caps,
        load_image=_scenes.load_from_registry,
        num_timestamps=3,
        config=dataclasses.replace(config, verification="static"),
    )
    assert static["label"][good][:, :2].mean() < lab[good][:, :2].mean() - 0.2


@pytest.mark.parametrize("mode", ["fundamental", "sfm"])
def test_no_poses_two_view_and_sfm_modes(mode):
    caps = [dataclasses.replace(c, R=None, t=None) for c in _posed_viewpoint(f"noposes_{mode}")]
    config = GroundTruthConfig(max_keypoints=200, verification=mode)
    rec = label_viewpoint(
        caps,
        load_image=_scenes.load_from_registry,
        num_timestamps=3,
        config=config,
        camera_of=lambda c: K,
    )
    good = np.isin(rec["image_id"], ["p0", "p1", "p2", "p3"])
    assert good.sum() == 800
    # Without poses the wrong-pose image is a perfectly consistent view: it repeats too.
    assert rec["label"][good][:, :2].mean() > 0.6
    assert rec["label"][good, 2].mean() > 0.5


def test_auto_without_poses_is_sfm_and_drops_unregistered_viewpoints(tmp_path):
    caps = [dataclasses.replace(c, R=None, t=None) for c in _posed_viewpoint("sfm_drop")]
    # An unrelated texture cannot register: the viewpoint yields no records (the paper).
    _scenes.IMAGES["sfm_drop/p3"] = textured_image(99)
    rec = label_viewpoint(
        caps,
        load_image=_scenes.load_from_registry,
        num_timestamps=3,
        config=GroundTruthConfig(max_keypoints=200),
        cache_dir=tmp_path,
    )
    assert rec["xy"].shape == (0, 2) and rec["label"].shape == (0, 3)
    meta = json.loads(next(tmp_path.glob("labels/*/*.json")).read_text())
    assert meta["sfm_registered"] is False and meta["num_readable"] == 5


def test_distorted_camera_needs_camera_of():
    caps = _posed_viewpoint("dist")
    cam = Camera("OPENCV", WIDTH, HEIGHT, K, np.array([0.1, 0.0, 0.0, 0.0]))
    caps = [dataclasses.replace(c, camera=cam) for c in caps]
    with pytest.raises(ValueError, match="camera_of"):
        label_viewpoint(
            caps,
            load_image=_scenes.load_from_registry,
            num_timestamps=3,
            config=GroundTruthConfig(max_keypoints=50, verification="pose"),
        )


def test_images_from_the_same_centre_repeat():
    tex = textured_image(12)
    caps = []
    for image_id, slot, R in (("r0", 0, np.eye(3)), ("r1", 1, _rotation(1.0, -3.0, 2.0))):
        caps.append(make_capture(image_id, 0, slot, viewpoint="rot", R=R, t=np.zeros(3), K=K))
        _scenes.IMAGES[f"rot/{image_id}"] = _render(tex, R, np.zeros(3))
    rec = label_viewpoint(
        caps,
        load_image=_scenes.load_from_registry,
        num_timestamps=2,
        config=GroundTruthConfig(max_keypoints=200, verification="pose"),
    )
    # No baseline: the infinite-homography check applies; most points repeat.
    assert rec["label"][rec["slot"] == 0, 1].mean() > 0.6
    assert rec["label"][rec["slot"] == 1, 0].mean() > 0.6
