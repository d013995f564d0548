"""A capture's geo-aligned camera orientation: the renderer's own, a scene.json heading, or none."""

import json

import numpy as np
import pytest

from rp_jax import sun
from rp_jax.datasets import camera_frame
from rp_jax.sources.synthetic import output_folder, presets


def _mark(root, preset, world=None):
    world = presets.world_version(preset) if world is None else world
    output_folder.mark(root, {"generator": output_folder.GENERATOR, "preset": preset,
                              "size": "tiny", "seed": 2, "world": world})


@pytest.mark.parametrize("preset", ["webcam_clipart", "cmu_seasons"])
def test_synthetic_frames_get_the_renderers_rotation(tmp_path, preset):
    jobs = presets.plan(preset, tmp_path, size="tiny", seed=2).jobs
    _mark(tmp_path, preset)
    camera_frame._planned_rotations.cache_clear()
    camera_frame._world_root.cache_clear()
    for job in jobs[:: max(1, len(jobs) // 7)]:
        np.testing.assert_array_equal(camera_frame.camera_rotation(job.image_path), job.R)
    assert camera_frame.camera_rotation(tmp_path / jobs[0].image_path.parent.name / "x.jpg") is None


def test_another_world_version_or_no_marker_is_unknown(tmp_path):
    jobs = presets.plan("webcam_clipart", tmp_path, size="tiny", seed=2).jobs
    assert camera_frame.camera_rotation(jobs[0].image_path) is None  # a download: no marker
    _mark(tmp_path, "webcam_clipart", world=presets.world_version("webcam_clipart") - 1)
    camera_frame._planned_rotations.cache_clear()
    camera_frame._world_root.cache_clear()
    assert camera_frame.camera_rotation(jobs[0].image_path) is None


def test_scene_json_heading_gives_a_level_camera(tmp_path):
    scene = tmp_path / "my_webcam"
    scene.mkdir()
    (scene / "scene.json").write_text(json.dumps({"camera_heading_deg": 250.0}))
    R = camera_frame.camera_rotation(scene / "20120101_120000.jpg")
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    el, az = sun.sun_in_camera_frame(20.0, 250.0 + 30.0, R)  # 30 deg right of the view
    np.testing.assert_allclose([el, az], [20.0, 30.0], atol=1e-9)
    (scene / "scene.json").write_text(json.dumps({"camera_heading_deg": 0.0,
                                                  "camera_tilt_deg": 10.0}))
    camera_frame._scene_heading.cache_clear()
    el, az = sun.sun_in_camera_frame(10.0, 0.0, camera_frame.camera_rotation(scene / "a.jpg"))
    np.testing.assert_allclose([el, az], [0.0, 0.0], atol=1e-9)  # straight along the tilted axis
    (scene / "scene.json").write_text(json.dumps({"latitude": 40.0}))
    camera_frame._scene_heading.cache_clear()
    assert camera_frame.camera_rotation(scene / "a.jpg") is None


def test_capture_conditions_give_the_sun_in_the_renderers_camera_frame(tmp_path):
    """The per-pair sidecar's ``sun_camera_*`` of synthetic frames: the sun the renderer lit
    them with, as their own camera sees it; NaN without a geo-aligned orientation."""
    from rp_jax.datasets import capture_conditions
    from rp_jax.sources import cmu_seasons
    from rp_jax.sources.capture import Camera, Capture

    jobs = presets.plan("cmu_seasons", tmp_path, size="tiny", seed=2).jobs[::9]
    camera = Camera("PINHOLE", 4, 3, np.eye(3))
    captures = [Capture(job.image_path,
                        cmu_seasons.capture_time(cmu_seasons.parse_image_name(job.image_path.name)[2]),
                        camera, "v") for job in jobs]
    unknown = capture_conditions.capture_conditions(captures, "cmu_seasons")  # no marker yet
    assert np.isnan(unknown["sun_camera_azimuth_deg"]).all()
    assert np.isfinite(unknown["sun_azimuth_deg"]).all()
    _mark(tmp_path, "cmu_seasons")
    camera_frame._planned_rotations.cache_clear()
    camera_frame._world_root.cache_clear()
    got = capture_conditions.capture_conditions(captures, "cmu_seasons")
    for i, job in enumerate(jobs):
        el, az = sun.sun_in_camera_frame(got["sun_elevation_deg"][i], got["sun_azimuth_deg"][i],
                                         job.R)
        np.testing.assert_allclose([got["sun_camera_elevation_deg"][i],
                                    got["sun_camera_azimuth_deg"][i]], [el, az], atol=1e-3)
    assert np.ptp(got["sun_camera_azimuth_deg"]) > 10  # the cameras look different ways
