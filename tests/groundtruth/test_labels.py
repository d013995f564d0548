"""Tests of the repeatability vector y^j and its mask (Sec. III-D)."""

import numpy as np
import pytest

from rp_jax.groundtruth.labels import images_per_timestamp, repeatability_labels


def test_hand_made_case_two_cycles_and_an_empty_slot():
    # T = 4; images (cycle, slot): 0:(0,0) 1:(0,1) 2:(1,1) 3:(1,0) 4:(1,3); slot 2 has none.
    slots = np.array([0, 1, 1, 0, 3])
    # Two interest points of image 1 (slot 1).
    inliers = np.array(
        [
            [True, False, False, False, True],  # own column False: still counted
            [False, True, True, True, False],  # own column True: counted once, not twice
        ]
    )
    label, mask = repeatability_labels(inliers, slots, own_image=1, num_timestamps=4)
    # m_j summed over cycles: slot0 = 2, slot1 = 2, slot2 = 0, slot3 = 1.
    expected = np.array(
        [
            [1 / 2, 1 / 2, 0.0, 1.0],  # slot1: itself only; slot0: image 0; slot3: image 4
            [1 / 2, 2 / 2, 0.0, 0.0],  # slot1: itself + image 2; slot0: image 3
        ],
        np.float32,
    )
    np.testing.assert_allclose(label, expected, rtol=0, atol=1e-7)
    np.testing.assert_array_equal(mask, [[True, True, False, True]] * 2)
    assert label.dtype == np.float32 and mask.dtype == bool


def test_own_image_alone_gives_one_in_its_slot():
    label, mask = repeatability_labels(np.zeros((3, 1), bool), np.array([2]), 0, 3)
    np.testing.assert_array_equal(label, [[0, 0, 1]] * 3)
    np.testing.assert_array_equal(mask, [[False, False, True]] * 3)


def test_images_per_timestamp_rejects_bad_slots():
    np.testing.assert_array_equal(images_per_timestamp(np.array([0, 0, 2]), 3), [2, 0, 1])
    with pytest.raises(ValueError, match="timestamp indices"):
        images_per_timestamp(np.array([3]), 3)


def test_shape_mismatch_is_refused():
    with pytest.raises(ValueError, match="one column per image"):
        repeatability_labels(np.zeros((2, 3), bool), np.array([0, 1]), 0, 2)


def test_groundtruth_does_not_import_jax():
    import subprocess
    import sys

    code = (
        "import sys, rp_jax.groundtruth, rp_jax.groundtruth.sfm;"
        "sys.exit(1 if 'jax' in sys.modules else 0)"
    )
    root = __import__("pathlib").Path(__file__).resolve().parents[2]
    assert subprocess.run([sys.executable, "-c", code], cwd=root, check=False).returncode == 0
