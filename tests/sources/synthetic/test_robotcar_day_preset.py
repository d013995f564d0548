"""The ``robotcar_day`` preset: the RobotCar layout with one traversal per hour of the day,
read by ``rp_jax.sources.robotcar.read_day`` (beyond Sec. IV-B-1's 9:00-17:00)."""

import datetime as dt
from zoneinfo import ZoneInfo

import numpy as np

from rp_jax.schedule import preset
from rp_jax.sources import robotcar
from rp_jax.sources.synthetic import camera_effects, photometry, presets
from rp_jax.sources.synthetic.plan_robotcar import day_traversals
from tests.datasets._tiny import tiny_world_copy

LONDON = ZoneInfo("Europe/London")


def test_one_traversal_starts_a_minute_before_each_local_hour():
    traversals = day_traversals()
    assert [slot for _, slot in traversals] == list(range(24))
    months = []
    for folder, slot in traversals:
        utc = dt.datetime.strptime(folder, "%Y-%m-%d-%H-%M-%S").replace(tzinfo=dt.UTC)
        local = utc.astimezone(LONDON)
        # One minute before slot:00 on the local clock, across both sides of summer time.
        on_the_hour = local + dt.timedelta(minutes=1)
        assert (on_the_hour.hour, on_the_hour.minute) == (slot, 0)
        months.append(on_the_hour.month)
    assert sorted(set(months)) == list(range(1, 13)) and len(months) == 24
    assert any(t.astimezone(LONDON).utcoffset() for t in (
        dt.datetime.strptime(f, "%Y-%m-%d-%H-%M-%S").replace(tzinfo=dt.UTC)
        for f, _ in traversals))  # some in summer time: the slot is the local hour


def test_the_day_preset_takes_nights_as_the_seasons_preset_does(tmp_path):
    day = presets.plan("robotcar_day", tmp_path / "d", size="tiny", seed=0)
    paper = presets.plan("robotcar", tmp_path / "p", size="tiny", seed=0)
    assert {j.lighting for j in day.jobs} == {photometry.EN_13201.name}
    # Its windows are lit by the hour on Oxford's clock, as the seasons preset's are.
    seasons = presets.plan("robotcar_seasons", tmp_path / "s", size="tiny", seed=0)
    assert {j.clock for j in day.jobs} == {j.clock for j in seasons.jobs} == {"Europe/London"}
    assert {j.sensor for j in day.jobs} == {camera_effects.BUMBLEBEE_XB3_16HZ.name}
    assert all(j.velocity is not None and np.hypot(*j.velocity[:2]) > 5 for j in day.jobs)
    # Another street than the paper's preset of the same seed; that preset is unchanged.
    assert {j.scene for j in day.jobs}.isdisjoint({j.scene for j in paper.jobs})
    assert {(j.lighting, j.sensor, j.velocity) for j in paper.jobs} == {(None, None, None)}


def test_the_stereo_camera_exposes_at_most_one_frame_of_16_hz():
    xb3, side = camera_effects.BUMBLEBEE_XB3_16HZ, camera_effects.GRASSHOPPER2_11HZ
    assert xb3.max_exposure_s == 1 / 16 and xb3.exposure_s(xb3.max_gain) == 1 / 16
    # Same lens and amplification assumed: shorter frames reach proportionally less gain.
    assert np.isclose(xb3.max_gain / side.max_gain, 11.1 / 16)
    assert camera_effects.sensor_named(xb3.name) is xb3


def test_read_day_puts_each_image_in_the_slot_of_its_local_hour(tmp_path_factory, tmp_path):
    # presets.generate's tiny world, rendered once in the session (the tiny build's).
    root = tiny_world_copy(tmp_path_factory, "robotcar_day", tmp_path / "rcd")
    caps = robotcar.read_day(root)
    schedule = preset("robotcar_day")
    assert len(caps) == 8 and {c.viewpoint for c in caps} == {"vp00", "vp01"}
    for c in caps:
        local = c.time.astimezone(LONDON)
        assert c.slot == round(local.hour + local.minute / 60) % 24
        assert schedule.slot_of(local)[1] == c.slot
    assert {c.slot for c in caps} == {1, 13}
    # The paper's schedule (9:00-17:00) on the same files keeps the 13:00 traversal only,
    # in its slot 4: the night is what the whole-day schedule adds.
    paper = robotcar.read(root)
    assert len(paper) == 4 and {c.slot for c in paper} == {4}
