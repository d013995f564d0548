"""Passing cars and their headlamps (``traffic``)."""

import datetime as dt

import numpy as np
import pytest

from rp_jax.sources.synthetic import traffic
from rp_jax.sources.synthetic.quads import Material
from rp_jax.sources.synthetic.scene import build_scene

EVENING = dt.datetime(2014, 12, 10, 18, 10, tzinfo=dt.UTC)


@pytest.fixture(scope="module")
def scene():
    return build_scene(5, length_m=120.0, latitude=51.75, longitude=-1.26, vegetation=0.45)


def test_the_passing_cars_are_the_moving_cars_the_street_renders(scene):
    cars = traffic.passing_cars(scene, EVENING)
    assert cars and {c.direction for c in cars} <= {1.0, -1.0}
    assert {c.y for c in cars} <= {scene.lanes_y["eastbound"], scene.lanes_y["westbound"]}
    quads, _, _ = traffic.dynamic_quads(scene, EVENING)
    # A moving car's front and back faces emit (its lamps); parked cars' do not.
    lit = (quads.material == Material.CAR) & (quads.emit > 0)
    assert int(lit.sum()) == 2 * len(cars)
    assert traffic.passing_cars(scene, EVENING) == cars  # deterministic
    # Fewer cars in the small hours than in the evening.
    night = [len(traffic.passing_cars(scene, EVENING.replace(hour=3, minute=m)))
             for m in range(0, 60, 5)]
    evening = [len(traffic.passing_cars(scene, EVENING.replace(minute=m)))
               for m in range(0, 60, 5)]
    assert np.mean(night) < np.mean(evening)


def test_headlamps_sit_at_the_front_of_each_car_and_point_its_way():
    east = traffic.PassingCar(10.0, -2.0, 1.0, 0)
    west = traffic.PassingCar(30.0, 2.0, -1.0, 3)
    pos, fwd = traffic.headlamps([east, west])
    assert pos.shape == fwd.shape == (4, 3)
    np.testing.assert_allclose(pos[:2, 0], 10.0 + east.length / 2)
    np.testing.assert_allclose(pos[2:, 0], 30.0 - west.length / 2)
    np.testing.assert_allclose(fwd, [[1, 0, 0]] * 2 + [[-1, 0, 0]] * 2, atol=1e-12)
    assert abs(pos[0, 1] - pos[1, 1]) == pytest.approx(east.width - 2 * traffic.HEADLAMP_INSET_M)
    np.testing.assert_allclose(pos[:, 2], traffic.HEADLAMP_HEIGHT_M)
    own, own_fwd = traffic.car_headlamps(0.0, 0.0, np.pi / 2, 4.45, 1.77)  # heading north
    np.testing.assert_allclose(own[:, 1], 4.45 / 2)
    np.testing.assert_allclose(own_fwd, [[0, 1, 0]] * 2, atol=1e-12)
    empty_pos, empty_fwd = traffic.headlamps([])
    assert empty_pos.shape == empty_fwd.shape == (0, 3)
