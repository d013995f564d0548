"""Tests of the world's slow changes over the years (issue 17's long-term decay)."""

import dataclasses
import datetime as dt
import hashlib
import json

import numpy as np
import pytest

from rp_jax.sources.synthetic import slow_changes as sc
from rp_jax.sources.synthetic import textures as tx
from rp_jax.sources.synthetic.plan_webcam import YEARS, YEARS_REFERENCE_DATE, plan_years
from rp_jax.sources.synthetic.render import look_at, render
from rp_jax.sources.synthetic.scene import build_scene

REFERENCE = "2012-01-01"
TZ = dt.timezone(dt.timedelta(hours=1))


def _world_hash(scene) -> str:
    """sha1 of everything ``build_scene`` drew: quads, texture recipes, boxes, slots."""
    h = hashlib.sha1()
    s = scene.static
    for a in (s.origin, s.u, s.v, s.category, s.material, s.receiver, s.shadow_pt, s.owner,
              s.emit):
        h.update(np.ascontiguousarray(a).tobytes())
    h.update(json.dumps(s.tex).encode())
    for key in sorted(scene.textures.specs):
        fn, kwargs, depends = scene.textures.specs[key]
        h.update(json.dumps([key, fn.__name__, sorted((k, repr(v)) for k, v in kwargs.items()),
                             list(depends)]).encode())
    for a in (scene.buildings, scene.furniture_boxes, scene.lamps, scene.parking_slots):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def _build_worlds():
    """An urban street (shops) without and with slow changes."""
    return build_scene(11, vegetation=0.3), build_scene(
        11, vegetation=0.3, slow_changes=sc.SlowChanges(REFERENCE)
    )


@pytest.fixture(scope="module")
def worlds():
    return _build_worlds()


def test_off_by_default_and_the_world_built_is_the_world_as_it_was():
    # Built here, not taken from ``worlds``: a world with slow changes adds the recipes of
    # later shop fronts to its textures when a later date is asked of it, as the tests
    # after this one do, and this hash is of the world as built.
    still, changing = _build_worlds()
    assert still.slow_changes is None and changing.slow_changes is not None
    # The hash of seed 11's world as the recipe drew it before slow changes existed
    # (computed from the tree before them); a world that asks for them is built the same.
    # A change of the world itself (a WORLD_VERSION bump) updates it. It hashes the texture
    # makers' names too: when they moved to quads.py as tree_tex / plain_tex / sign_tex
    # (_tree_tex / _plain / _sign_tex in scene.py before), the old names in their place gave
    # the old hash f6042c191b2f3926e548c864f3320bc73e12ec44, and rendered frames of four
    # presets were byte-identical. Likewise when road and sidewalk tiles stopped naming the
    # season among what their texture depends on (only a lawn's does): with it, the old hash
    # 43c220a397e0f13131f56fb0964ed64fd60ee579, and the same byte-identical frames.
    assert _world_hash(still) == "a3654cf186c233ccf7c46ed4f6f353a2608645ec"
    assert _world_hash(changing) == _world_hash(still)
    # On and before the reference date the world stands as built.
    for day in (dt.date(2011, 6, 1), dt.date(2012, 1, 1)):
        assert changing.slow_changes.static_at(day) is changing.static


def test_deterministic_from_seed_element_and_date(worlds):
    _, changing = worlds
    again = build_scene(11, vegetation=0.3, slow_changes=sc.SlowChanges(REFERENCE))
    other = build_scene(12, vegetation=0.3, slow_changes=sc.SlowChanges(REFERENCE))
    day = dt.date(2019, 5, 3)
    a, b = changing.slow_changes.static_at(day), again.slow_changes.static_at(day)
    assert a.tex == b.tex and np.array_equal(a.origin, b.origin) and np.array_equal(a.u, b.u)
    assert changing.slow_changes.counts(day) == again.slow_changes.counts(day)
    assert changing.slow_changes.counts(day) != other.slow_changes.counts(day)
    # A whole day is one state: morning and evening of the same local date.
    morning = dt.datetime(2019, 5, 3, 8, tzinfo=TZ)
    evening = dt.datetime(2019, 5, 3, 19, tzinfo=TZ)
    assert changing.slow_changes.static_at(morning).tex == changing.slow_changes.static_at(
        evening
    ).tex


def test_ages_count_from_the_reference_date():
    assert sc.years_since(dt.date(2012, 1, 1), dt.date(2013, 1, 1)) == pytest.approx(366 / 365.25)
    assert sc.years_since(dt.date(2012, 1, 1), dt.date(2010, 1, 1)) == 0.0
    # The same age after another reference date is the same world (both spans hold one
    # 29 February).
    w2012 = build_scene(11, vegetation=0.3, slow_changes=sc.SlowChanges("2012-01-01"))
    w2013 = build_scene(11, vegetation=0.3, slow_changes=sc.SlowChanges("2013-01-01"))
    a = w2012.slow_changes.static_at(dt.date(2015, 6, 1))
    b = w2013.slow_changes.static_at(dt.date(2016, 6, 1))
    assert a.tex == b.tex and np.array_equal(a.v, b.v)
    assert a.tex != w2012.static.tex  # something did change in those 3.4 years
    with pytest.raises(ValueError):
        sc.SlowChanges("2012-13-01")
    with pytest.raises(ValueError):
        sc.SlowChanges(REFERENCE, kinds=("earthquake",))


def test_a_new_tenant_changes_the_shop_front_and_nothing_above():
    kwargs = dict(seed=4242, width_m=11.0, height_m=13.0, floor_h=3.3, style="plaster",
                  shopfront=True)
    first = tx.facade_texture(**kwargs)
    assert np.array_equal(first, tx.facade_texture(**kwargs, tenant=None))
    later = tx.facade_texture(**kwargs, tenant=1)
    ground = first.shape[0] - int(3.3 * first.shape[1] / 11.0)  # top row of the ground floor
    diff = np.abs(first.astype(int) - later).max(-1)
    assert diff[ground:].mean() > 10  # new windows, door and sign
    assert diff[: ground - 8].max() == 0  # the floors above as they were (past the blur)
    assert not np.array_equal(later, tx.facade_texture(**kwargs, tenant=2))
    # A repaint changes the wall colour and the trims.
    painted = tx.facade_texture(**kwargs, repaint=1)
    assert np.abs(first[..., :3].astype(int) - painted[..., :3]).mean() > 5


def test_shop_fronts_differ_between_years_in_the_world(worlds):
    _, changing = worlds
    world = changing.slow_changes
    shops = [f for f in world.facades if len(f.tenants)]
    assert shops, "an urban street has shop fronts"
    shop = min(shops, key=lambda f: f.tenants[0])
    ref = world.config.reference
    before = ref + dt.timedelta(days=int(shop.tenants[0] * sc.DAYS_PER_YEAR) - 2)
    after = ref + dt.timedelta(days=int(shop.tenants[0] * sc.DAYS_PER_YEAR) + 2)
    key_before = world.static_at(before).tex[shop.quad]
    key_after = world.static_at(after).tex[shop.quad]
    assert key_before != key_after
    state = changing.textures.pyramid
    from rp_jax.sources.synthetic.quads import TextureState

    assert not np.array_equal(state(key_before, TextureState())[0],
                              state(key_after, TextureState())[0])


def test_trees_grow_capped_and_are_replanted(worlds):
    _, changing = worlds
    world = changing.slow_changes
    h0 = np.array([t.height for t in world.trees])
    ref = world.config.reference
    h5 = world.tree_heights(ref + dt.timedelta(days=round(5 * sc.DAYS_PER_YEAR)))
    h80 = world.tree_heights(ref + dt.timedelta(days=round(80 * sc.DAYS_PER_YEAR)))
    replaced5 = set(world.counts(ref + dt.timedelta(days=round(5 * sc.DAYS_PER_YEAR)))[
        "tree_replacement"])
    grew = np.array([t.element not in replaced5 for t in world.trees])
    assert np.allclose(h5[grew], np.minimum(h0[grew] + 5 * sc.TREE_GROWTH_M_PER_YEAR,
                                            np.maximum(h0[grew], sc.TREE_MAX_HEIGHT_M)),
                       atol=0.01)
    assert np.all(h80 <= np.maximum(h0, sc.TREE_MAX_HEIGHT_M) + 1e-9)
    assert np.any(h80 < h0)  # 80 years at 3.5 % a year: some trees were replanted smaller
    # Growth alone (no replanting): every tree is at least as tall as built.
    growing = build_scene(11, vegetation=0.3, slow_changes=sc.SlowChanges(
        REFERENCE, kinds=("tree_growth",)))
    assert np.all(growing.slow_changes.tree_heights(dt.date(2040, 1, 1)) >= h0)
    assert growing.slow_changes.counts(dt.date(2040, 1, 1)) == {
        "tenant": {}, "repaint": {}, "sign": {}, "tree_replacement": {}}


@pytest.mark.parametrize(
    "kind, mean, periodic, horizon, expected",
    [
        # Half the tenants gone after the median stay.
        ("tenant", sc.TENANT_MEDIAN_STAY_YEARS / np.log(2), False, sc.TENANT_MEDIAN_STAY_YEARS,
         0.5),
        # 3.5 % of the trees die in a year (1 - exp(-0.035)).
        ("tree_replacement", 1 / sc.TREE_MORTALITY_PER_YEAR, False, 1.0,
         1 - np.exp(-sc.TREE_MORTALITY_PER_YEAR)),
        # A tenth of the facades repainted in any one year of a 10-year cycle.
        ("repaint", sc.REPAINT_INTERVAL_YEARS, True, 1.0, 1 / sc.REPAINT_INTERVAL_YEARS),
    ],
)
def test_event_rates_are_the_documented_ones(kind, mean, periodic, horizon, expected):
    first = np.array([
        (sc._event_times(7, kind, e, mean, periodic)[:1] <= horizon).any() for e in range(4000)
    ])
    assert first.mean() == pytest.approx(expected, abs=3 * np.sqrt(expected / 4000) + 0.005)


def test_same_instant_with_and_without_changes(worlds):
    still, changing = worlds
    view = look_at((10.0, still.sidewalk_y[0], 4.0), (16.0, still.facade_y[1], 5.0), width=96,
                   height=72, fov_deg=70.0)
    at_reference = dt.datetime(2012, 1, 1, 12, tzinfo=TZ)
    assert np.array_equal(render(still, view, at_reference).rgb,
                          render(changing, view, at_reference).rgb)
    later = dt.datetime(2018, 7, 1, 12, tzinfo=TZ)  # the same instant: the same weather
    a, b = render(still, view, later), render(changing, view, later)
    assert (np.abs(a.rgb.astype(int) - b.rgb).max(-1) > 20).mean() > 0.05


def test_years_preset_plans_the_same_days_of_every_year(tmp_path):
    on = plan_years(tmp_path / "on", "tiny", 0)
    off = plan_years(tmp_path / "off", "tiny", 0, slow_changes=False)
    assert on.preset == "webcam_years" and off.preset == "webcam_years_frozen"
    assert len(on.jobs) == len(off.jobs) == len(YEARS) * 2
    assert sorted({j.when.year for j in on.jobs}) == list(YEARS)
    assert len({(j.when.month, j.when.day) for j in on.jobs}) == 2  # the same days each year
    for a, b in zip(on.jobs, off.jobs):
        assert a.when == b.when and np.array_equal(a.R, b.R) and a.frame_seed == b.frame_seed
        assert a.image_path.relative_to(tmp_path / "on") == b.image_path.relative_to(
            tmp_path / "off")
        assert dataclasses.replace(a.scene, extra=()) == b.scene
    assert dict(on.jobs[0].scene.extra)["slow_changes"] == sc.SlowChanges(YEARS_REFERENCE_DATE)
    assert off.jobs[0].scene.extra == ()
