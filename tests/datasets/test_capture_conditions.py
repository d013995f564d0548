"""The synthetic CMU world's weather as the per-pair sidecar reports it: the renderer's own."""

import dataclasses
import datetime as dt

import numpy as np
import pytest

from rp_jax.datasets import capture_conditions
from rp_jax.sources import cmu_seasons
from rp_jax.sources.capture import Camera, Capture
from rp_jax.sources.synthetic import conditions, output_folder, plan_cmu, presets


def _captures(root, jobs):
    """The captures a reader makes of the planned frames (the time from the image name)."""
    camera = Camera("PINHOLE", 4, 3, np.eye(3))
    out = []
    for job in jobs:
        _, _, unix_us = cmu_seasons.parse_image_name(job.image_path.name)
        out.append(Capture(job.image_path, cmu_seasons.capture_time(unix_us), camera,
                           str(job.image_path.parent.relative_to(root)),
                           meta={"slice": int(job.image_path.parent.parent.name[5:])}))
    return out


SEED = 3


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    """The tiny CMU world's frames (planned, not rendered) and the folder they name."""
    root = tmp_path_factory.mktemp("cmu_tiny")
    return root, presets.plan("cmu_seasons", root, size="tiny", seed=SEED).jobs


def test_cmu_weather_is_what_the_renderer_drew_reference_traversal_included(planned):
    tmp_path, jobs = planned
    seed = SEED
    output_folder.mark(tmp_path, {"generator": output_folder.GENERATOR, "preset": "cmu_seasons",
                                  "size": "tiny", "seed": seed, "world": presets.WORLD_VERSION})
    got = capture_conditions.capture_conditions(_captures(tmp_path, jobs), "cmu_seasons")
    kinds = []
    for i, job in enumerate(jobs):
        # What render.render_frame computes for this frame.
        drawn = conditions.conditions_at(job.scene.seed, job.scene.latitude,
                                         job.scene.longitude, job.when, job.weather)
        kinds.append(drawn.weather)
        assert capture_conditions.WEATHERS[got["weather"][i]] == drawn.weather
        assert got["cloud_cover"][i] == np.float32(drawn.cloud_cover)
        assert got["snow_cover"][i] == np.float32(drawn.snow / 4.0)
        assert got["precipitation"][i] == float(drawn.weather in ("rain", "snow"))
    reference = [k for job, k in zip(jobs, kinds) if job.when.date() == plan_cmu.REFERENCE_DATE]
    assert reference and set(reference) == {plan_cmu.REFERENCE_WEATHER}
    others = {k for job, k in zip(jobs, kinds) if job.when.date() != plan_cmu.REFERENCE_DATE}
    assert others - {plan_cmu.REFERENCE_WEATHER}, "every drawn day clear: the test shows nothing"


def test_no_cmu_weather_without_this_worlds_marker(planned, tmp_path):
    root, jobs = planned
    caps = [dataclasses.replace(c, image_path=tmp_path / c.image_path.relative_to(root))
            for c in _captures(root, jobs[:4])]
    real = capture_conditions.capture_conditions(caps, "cmu_seasons")  # no marker: a download
    assert (real["weather"] == -1).all() and np.isnan(real["cloud_cover"]).all()
    assert np.isfinite(real["sun_elevation_deg"]).all()  # the spec's place still gives the sun
    output_folder.mark(tmp_path, {"preset": "cmu_seasons", "size": "tiny", "seed": 0,
                                  "world": presets.WORLD_VERSION - 1})
    capture_conditions._synthetic_cmu_world.cache_clear()
    older = capture_conditions.capture_conditions(caps, "cmu_seasons")  # another renderer
    assert (older["weather"] == -1).all()
    when = dt.datetime(2011, 3, 4, 12, tzinfo=dt.UTC)
    assert capture_conditions.synthetic_cmu_conditions(tmp_path / "a.jpg", when) is None


def test_webcam_weather_is_drawn_in_the_scenes_own_climate(tmp_path):
    """``webcam_clipart``'s scenes are in their cities' own climates: the weather read back
    from a scene's ``scene.json`` is the renderer's, also on a day the latitude's climate
    put snow on (Paris in January, world seed 0)."""
    from rp_jax.sources.synthetic import write_layout

    jobs = presets.plan("webcam_clipart", tmp_path, size="full", seed=0).jobs
    paris = [j for j in jobs if j.image_path.parent.name == "scene_06"]
    january = [j for j in paris if j.when.month == 1]
    assert january and dict(paris[0].scene.extra)["climate"] == "local"
    scene = paris[0].scene
    write_layout.write_webcam_scene_sidecar(
        paris[0].image_path.parent, timezone="Europe/Paris", latitude=scene.latitude,
        longitude=scene.longitude,
        synthetic={"scene": dataclasses.asdict(scene)})
    capture_conditions._synthetic_scene.cache_clear()
    for job in january[:3] + paris[-3:]:
        drawn = conditions.conditions_at(scene.seed, scene.latitude, scene.longitude, job.when,
                                         climate="local")
        got = capture_conditions.weather_record(job.image_path, job.when)
        assert got["snow_cover"] == np.float32(drawn.snow / 4.0)
        assert capture_conditions.WEATHERS[int(got["weather"])] == drawn.weather
    when = january[0].when
    assert conditions.conditions_at(scene.seed, scene.latitude, scene.longitude, when).snow > 0
    assert capture_conditions.weather_record(january[0].image_path, when)["snow_cover"] == 0.0
    # A scene written before the climates (no "climate" entry) was drawn in the latitude's.
    older = tmp_path / "older_world" / "scene_06"
    write_layout.write_webcam_scene_sidecar(
        older, timezone="Europe/Paris", latitude=scene.latitude, longitude=scene.longitude,
        synthetic={"scene": dataclasses.asdict(dataclasses.replace(scene, extra=()))})
    got = capture_conditions.weather_record(older / january[0].image_path.name, when)
    assert got["snow_cover"] > 0.0
