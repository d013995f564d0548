"""Tests of the many-worlds presets (rp_jax/sources/synthetic/plan_worlds.py)."""

from __future__ import annotations

import datetime as dt
import zoneinfo
from pathlib import Path

import pytest

from rp_jax.sources import webcam_clipart
from rp_jax.sources.synthetic import plan_webcam, plan_worlds, presets


def _city(job) -> tuple[float, float]:
    return job.scene.latitude, job.scene.longitude


def test_the_city_pools_share_no_city_with_each_other_or_the_shipped_worlds():
    train = {c[0] for c in plan_worlds.WORLD_CITIES}
    unseen = {c[0] for c in plan_worlds.UNSEEN_CITIES}
    shipped = {c[0] for c in plan_webcam.WEBCAM_CITIES}
    assert len(train) == len(plan_worlds.WORLD_CITIES)
    assert not train & unseen and not train & shipped and not unseen & shipped
    places = {(c[1], c[2]) for c in plan_worlds.WORLD_CITIES + plan_worlds.UNSEEN_CITIES}
    places |= {(c[1], c[2]) for c in plan_webcam.WEBCAM_CITIES}
    assert len(places) == len(train) + len(unseen) + len(shipped)
    for c in plan_worlds.WORLD_CITIES + plan_worlds.UNSEEN_CITIES:
        zoneinfo.ZoneInfo(c[3])  # a real zone
    assert min(c[1] for c in plan_worlds.WORLD_CITIES) < -30  # both hemispheres
    assert max(c[1] for c in plan_worlds.WORLD_CITIES) > 55


def test_a_world_draws_its_webcams_from_its_own_pool_on_streets_of_its_own():
    sites = plan_worlds.world_sites(3, 8, plan_worlds.WORLD_CITIES, 21)
    assert [s.name for s in sites] == [f"scene_{i:02d}" for i in range(8)]
    pool = {c[0]: c for c in plan_worlds.WORLD_CITIES}
    assert len({s.city for s in sites}) == 8  # without replacement
    for s in sites:
        assert (s.latitude, s.longitude, s.timezone) == pool[s.city][1:]
        assert s.facade_azimuth in (0.0, 180.0)
        assert dict(s.scene.extra)["lanes"] in (2, 4)
    assert sites == plan_worlds.world_sites(3, 8, plan_worlds.WORLD_CITIES, 21)
    other = plan_worlds.world_sites(4, 8, plan_worlds.WORLD_CITIES, 21)
    assert {s.scene.seed for s in sites}.isdisjoint({s.scene.seed for s in other})
    # The same seed of webcam_clipart watches other streets.
    clipart = plan_webcam.webcam_sites(3, 8)
    assert {s.scene.seed for s in sites}.isdisjoint({s.scene.seed for s in clipart})
    # More webcams than cities: the pool is used again.
    many = plan_worlds.world_sites(3, 30, plan_worlds.WORLD_CITIES, 21)
    assert {s.city for s in many} == set(pool)


@pytest.mark.parametrize("seed", [0, 1, 7])
def test_a_webcams_days_fall_one_in_each_quarter_of_one_year(seed):
    days = plan_worlds.world_days(seed, 2, 4)
    assert days == sorted(days) and len({d.year for d in days}) == 1
    assert sorted((d.month - 1) // 3 for d in days) == [0, 1, 2, 3]
    assert 2012 <= days[0].year <= 2016
    assert [d.month % 3 for d in days] == [days[0].month % 3] * 4  # the same month of each
    two = plan_worlds.world_days(seed, 2, 2)  # tiny: winter and summer quarters
    assert sorted((d.month - 1) // 3 for d in two) == [0, 2]


def test_the_held_out_preset_draws_only_held_out_cities():
    plan = presets.plan("webcam_worlds_unseen", Path("/nonexistent"), size="full", seed=2)
    unseen = {(c[1], c[2]) for c in plan_worlds.UNSEEN_CITIES}
    assert {_city(j) for j in plan.jobs} <= unseen
    assert len({j.image_path.parent.name for j in plan.jobs}) == 4
    train = presets.plan("webcam_worlds", Path("/nonexistent"), size="full", seed=2)
    assert {_city(j) for j in train.jobs} <= {(c[1], c[2]) for c in plan_worlds.WORLD_CITIES}
    assert len({j.image_path.parent.name for j in train.jobs}) == 8
    assert len(train.jobs) == 8 * 4 * (21 + 3)  # M = 4 days of 21 slots and 3 off-slot frames
    assert plan_worlds.webcams_per_world("webcam_worlds", "full") == 8
    assert plan_worlds.webcams_per_world("webcam_worlds_unseen", "full") == 4


def test_a_tiny_world_is_read_by_the_webcam_clip_art_reader(tmp_path):
    root = presets.generate("webcam_worlds", tmp_path / "w", size="tiny", seed=5, workers=1,
                            progress=False)
    captures = webcam_clipart.read(root)
    assert {c.viewpoint for c in captures} == {"scene_00", "scene_01"}
    assigned = [c for c in captures if c.slot is not None]
    assert assigned and all(c.slot % 5 == 0 for c in assigned)  # tiny: every 5th slot
    for c in assigned:  # the slots are the webcam's own wall clock, 8:00-18:00
        assert dt.time(7, 50) <= c.time.time() <= dt.time(18, 10)
    assert presets.world_marker(root, "webcam_worlds")["seed"] == 5
