"""One home for quaternion <-> rotation (rp_jax.rotations)."""

import numpy as np
import pytest

from rp_jax.rotations import quaternion_to_rotation, rotation_to_quaternion


def test_a_quarter_turn_about_z_by_hand():
    s = np.sqrt(0.5)
    Rz = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(quaternion_to_rotation([s, 0, 0, s]), Rz, atol=1e-12)
    np.testing.assert_allclose(rotation_to_quaternion(Rz), [s, 0, 0, s], atol=1e-12)
    # Not normalised: the same rotation; the scalar part comes back non-negative.
    np.testing.assert_allclose(quaternion_to_rotation([2 * s, 0, 0, 2 * s]), Rz, atol=1e-12)
    np.testing.assert_allclose(rotation_to_quaternion(Rz.T), [s, 0, 0, -s], atol=1e-12)


def test_round_trip_of_random_rotations_including_half_turns():
    rng = np.random.default_rng(0)
    qs = rng.normal(size=(200, 4))
    qs = np.vstack([qs, [[0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]])  # trace -1: half turns
    for q in qs:
        q = q / np.linalg.norm(q) * (1 if q[0] >= 0 else -1)
        R = quaternion_to_rotation(q)
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
        back = rotation_to_quaternion(R)
        assert back[0] >= 0
        np.testing.assert_allclose(np.abs(back @ q), 1.0, atol=1e-12)


@pytest.mark.parametrize("q", [[0, 0, 0, 0], [1, float("nan"), 0, 0], [1, 0, 0]])
def test_no_rotation_from_a_bad_quaternion(q):
    with pytest.raises(ValueError, match="quaternion"):
        quaternion_to_rotation(q)
