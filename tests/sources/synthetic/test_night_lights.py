"""Headlamps and a wet road's gloss at night (``night_lights``)."""

import numpy as np
import pytest

from rp_jax.sources.synthetic import night_lights, photometry


def _points(xyz):
    xyz = np.asarray(xyz, np.float32).reshape(-1, 3)
    return [np.ascontiguousarray(xyz[:, k]) for k in range(3)]


def test_a_headlamp_lights_a_wall_ahead_by_the_inverse_square_law():
    lamp, forward = np.array([[0.0, 0.0, 0.65]]), np.array([[1.0, 0.0, 0.0]])
    # A wall facing the lamp (normal -x) 10 and 20 m ahead, at the lamp's height minus the
    # hot spot's 1 deg drop, and one behind the lamp.
    X = _points([[10.0, 0.0, 0.65 - 10 * np.tan(np.radians(1.0))],
                 [20.0, 0.0, 0.65 - 20 * np.tan(np.radians(1.0))],
                 [-10.0, 0.0, 0.65]])
    N = _points([[-1.0, 0.0, 0.0]] * 2 + [[1.0, 0.0, 0.0]])
    E = night_lights.headlamp_illuminance(X, N, lamp, forward)
    r2 = np.array([10.0, 20.0]) ** 2 / np.cos(np.radians(1.0)) ** 2 + 0.3
    expected = photometry.low_beam_cd(0.0, -1.0) * np.cos(np.radians(1.0)) / r2
    np.testing.assert_allclose(E[:2], expected, rtol=0.02)
    assert E[2] == 0.0  # behind the lamp
    assert E[0] / E[1] == pytest.approx(4.0, rel=0.05)


def test_the_kerb_side_is_to_the_right_of_the_direction_of_travel():
    lamp = np.array([[0.0, 0.0, 0.65]])
    road_right = _points([[20.0, -2.0, 0.0]])  # heading +x, the right is -y
    road_left = _points([[20.0, 2.0, 0.0]])
    up = _points([[0.0, 0.0, 1.0]])
    east = np.array([[1.0, 0.0, 0.0]])
    right = night_lights.headlamp_illuminance(road_right, up, lamp, east)
    left = night_lights.headlamp_illuminance(road_left, up, lamp, east)
    assert right[0] > left[0] > 0
    west = night_lights.headlamp_illuminance(_points([[-20.0, 2.0, 0.0]]), up, lamp, -east)
    assert west[0] == pytest.approx(right[0], rel=1e-4)  # heading -x, the right is +y


def test_a_wet_road_mirrors_a_lamp_where_the_mirror_ray_meets_it():
    camera = np.array([0.0, 0.0, 1.5])
    lamp = np.array([[30.0, 0.0, 6.0]])
    # The mirror point on the road between camera and lamp: heights 1.5 and 6 split 30 m.
    x_mirror = 30.0 * 1.5 / (1.5 + 6.0)
    xs = np.array([x_mirror - 3.0, x_mirror, x_mirror + 3.0, x_mirror])
    ys = np.array([0.0, 0.0, 0.0, 3.0])
    X = _points(np.stack([xs, ys, np.zeros(4)], 1))
    N = _points([[0.0, 0.0, 1.0]] * 4)
    none = np.zeros((0, 3))
    rad = night_lights.wet_road_radiance(X, N, camera, lamp, 1000.0, (1.0, 0.5, 0.25),
                                         none, none)
    assert rad.shape == (4, 3)
    # Brightest at the mirror point; a streak along the line of sight (the lobe stretches at
    # grazing angles); nothing 3 m to the side.
    assert rad[1, 0] > rad[2, 0] > 10 * rad[0, 0] > 0
    assert rad[3, 0] < 1e-3 * rad[1, 0]
    np.testing.assert_allclose(rad[1] / rad[1, 0], [1.0, 0.5, 0.25], rtol=1e-5)
    # The headlamps' own colour; nothing from a lamp pointing away from the mirror point.
    head = night_lights.wet_road_radiance(X, N, camera, none, 0.0, (1, 1, 1),
                                          lamp - [0, 0, 5.35], np.array([[-1.0, 0, 0]]))
    np.testing.assert_allclose(head[1] / head[1, 0], photometry.HEADLAMP_RGB, rtol=1e-5)
    away = night_lights.wet_road_radiance(X, N, camera, none, 0.0, (1, 1, 1),
                                          lamp - [0, 0, 5.35], np.array([[1.0, 0, 0]]))
    assert not away.any()
