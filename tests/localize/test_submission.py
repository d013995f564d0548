"""Tests of rp_jax.localize.submission (visuallocalization.net format)."""

import numpy as np
import pytest

from rp_jax.localize import (
    quaternion_to_rotation,
    read_submission,
    rotation_to_quaternion,
    write_submission,
)


def _random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def test_quaternion_known_values():
    np.testing.assert_allclose(rotation_to_quaternion(np.eye(3)), [1, 0, 0, 0], atol=1e-12)
    # 90 degrees about z: q = (cos 45, 0, 0, sin 45).
    Rz = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    s = np.sqrt(0.5)
    np.testing.assert_allclose(rotation_to_quaternion(Rz), [s, 0, 0, s], atol=1e-12)
    np.testing.assert_allclose(quaternion_to_rotation([s, 0, 0, s]), Rz, atol=1e-12)
    # 180 degrees about x (w = 0).
    Rx = np.diag([1.0, -1, -1])
    np.testing.assert_allclose(np.abs(rotation_to_quaternion(Rx)), [0, 1, 0, 0], atol=1e-12)


def test_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    poses = {f"cam/img_{i}.jpg": (_random_rotation(rng), rng.normal(size=3)) for i in range(20)}
    poses["failed.jpg"] = None
    path = write_submission(tmp_path / "sub.txt", poses)
    lines = path.read_text().splitlines()
    assert len(lines) == 20 and all(len(line.split()) == 8 for line in lines)
    back = read_submission(path)
    assert set(back) == set(poses) - {"failed.jpg"}
    for name, (R, t) in back.items():
        np.testing.assert_allclose(R, poses[name][0], atol=1e-10)
        np.testing.assert_allclose(t, poses[name][1], atol=1e-12)
        assert float(lines[sorted(back).index(name)].split()[1]) >= 0  # qw >= 0


def test_bad_line_is_named(tmp_path):
    path = tmp_path / "bad.txt"
    path.write_text("img.jpg 1 0 0 0 0 0\n")
    with pytest.raises(ValueError, match="bad.txt:1"):
        read_submission(path)
