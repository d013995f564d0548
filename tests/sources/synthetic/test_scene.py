"""Tests of the synthetic street's geometry (the world of the Sec. IV-A stand-in)."""

import datetime as dt

import numpy as np

from rp_jax import categories
from rp_jax.sources.synthetic.scene import build_scene
from rp_jax.sources.synthetic.traffic import dynamic_quads

TZ = dt.timezone(dt.timedelta(hours=-5))


def test_deterministic_and_seed_dependent():
    a, b, c = build_scene(5), build_scene(5), build_scene(6)
    np.testing.assert_array_equal(a.static.origin, b.static.origin)
    assert a.static.tex == b.static.tex
    assert a.static.n != c.static.n or not np.allclose(a.static.origin, c.static.origin)


def test_layout_and_normals_face_the_street():
    s = build_scene(1, length_m=120.0, vegetation=0.2)
    assert s.facade_y[0] < -s.road_half_width < 0 < s.road_half_width < s.facade_y[1]
    assert s.lanes_y["eastbound"] < 0 < s.lanes_y["westbound"]
    q = s.static
    fronts = np.flatnonzero(q.material == 1)
    n = q.normal[fronts]
    y = q.origin[fronts, 1]
    # street facades, not the buildings closing the ends (facing along x)
    inside = np.abs(n[:, 0]) < 0.5
    assert np.all(np.sign(n[inside, 1]) == -np.sign(y[inside]))
    ground = q.category == categories.GROUND
    np.testing.assert_allclose(q.normal[ground], [[0, 0, 1]] * int(ground.sum()), atol=1e-12)
    assert s.x_range[0] < 0 and s.x_range[1] > 120.0


def test_dynamic_objects_move_and_parked_cars_change_by_day():
    s = build_scene(2)
    t0 = dt.datetime(2024, 5, 3, 12, 0, 0, tzinfo=TZ)
    q1, b1, _ = dynamic_quads(s, t0)
    q2, b2, _ = dynamic_quads(s, t0 + dt.timedelta(seconds=2))
    q3, b3, _ = dynamic_quads(s, t0 + dt.timedelta(days=1))
    assert q1.n > 0
    assert q1.n != q2.n or not np.allclose(q1.origin, q2.origin)  # something moved
    assert q1.n != q3.n or not np.allclose(q1.origin, q3.origin)
    q1b, _, _ = dynamic_quads(s, t0)
    np.testing.assert_array_equal(q1.origin, q1b.origin)  # deterministic per instant


def test_only_lawn_tiles_are_drawn_again_when_the_season_changes():
    from rp_jax.sources.synthetic import ground_textures as gt
    from rp_jax.sources.synthetic.quads import TextureState

    s = build_scene(3, vegetation=0.8)  # lawns in the yards
    ground = {k: s.textures.specs[k] for k in s.textures.specs if k.startswith("ground:")}
    kinds = {spec[1]["kind"] for spec in ground.values()}
    assert kinds == {"road", "sidewalk", "grass"}
    for key, (_fn, kwargs, depends) in ground.items():
        assert ("season" in depends) == (kwargs["kind"] == "grass"), key
    # What makes that right: a road or sidewalk tile is the same texture in every season
    # (with and without snow), a lawn's is not.
    for kind in ("road", "sidewalk", "grass"):
        for snow in (0, 2):
            tiles = [gt.ground_texture(11, kind, 8.0, 3.0, season=season, snow=snow,
                                       snow_pattern=1 if snow else 0) for season in (0, 3)]
            assert np.array_equal(*tiles) == (kind != "grass"), (kind, snow)
    # So the texture cache draws a road tile once for two seasons.
    road = next(k for k, spec in ground.items() if spec[1]["kind"] == "road")
    summer, autumn = TextureState(season=1), TextureState(season=3)
    assert s.textures.pyramid(road, summer) is s.textures.pyramid(road, autumn)
