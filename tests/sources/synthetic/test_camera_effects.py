"""A camera's exposure range, its noise and motion blur (``camera_effects``)."""

import dataclasses

import numpy as np
import pytest

from rp_jax.sources.synthetic import camera_effects as ce

K = np.array([[100.0, 0, 64], [0, 100.0, 48], [0, 0, 1]])


def _radiance(level, seed=0):
    rng = np.random.default_rng(seed)
    return (level * rng.uniform(0.5, 1.5, (96, 128, 3))).astype(np.float32)


def test_the_webcam_sensor_is_the_default_pipeline():
    a, meta_a = ce.expose(_radiance(0.05), K, np.random.default_rng(1))
    b, meta_b = ce.expose(_radiance(0.05), K, np.random.default_rng(1), ce.WEBCAM)
    np.testing.assert_array_equal(a, b)
    assert meta_a == meta_b and "exposure_s" not in meta_a
    _, dark = ce.expose(_radiance(1e-5), K, np.random.default_rng(1))
    assert dark["gain"] == ce.MAX_GAIN


def test_grasshopper2_exposure_range_from_its_frame_rate_lens_and_gain():
    g = ce.GRASSHOPPER2_11HZ
    assert g.max_exposure_s == pytest.approx(1 / 11.1)
    # about 0.2 ms at sunny noon: the exposure alone spans ~430x, 24 dB of gain 15.8x more
    assert 300 < g.exposure_gain / ce._DAY_GAIN < 600
    assert g.max_gain / g.exposure_gain == pytest.approx(10 ** 1.2)
    assert g.exposure_s(g.exposure_gain / 2) == pytest.approx(g.max_exposure_s / 2)
    assert g.exposure_s(g.max_gain) == g.max_exposure_s
    assert ce.sensor_named("grasshopper2_11hz") is g and ce.sensor_named(None) is ce.WEBCAM
    with pytest.raises(ValueError, match="unknown sensor"):
        ce.sensor_named("bumblebee")


def test_a_night_scene_is_exposed_longer_before_its_noise_rises():
    g = ce.GRASSHOPPER2_11HZ
    night = _radiance(5e-4)  # ~1/200 of a bright day: within the exposure range
    img_w, meta_w = ce.expose(night.copy(), K, np.random.default_rng(2), ce.WEBCAM)
    img_g, meta_g = ce.expose(night.copy(), K, np.random.default_rng(2), g)
    assert meta_w["gain"] == ce.MAX_GAIN and img_w.mean() < 40  # the webcam stays dark
    assert meta_g["gain"] < g.exposure_gain and 0 < meta_g["exposure_s"] < g.max_exposure_s
    assert img_g.mean() > 3 * img_w.mean()
    assert meta_g["noise_sigma_dark"] == pytest.approx(ce._READ)  # no gain: day's noise
    _, deeper = ce.expose(_radiance(2e-6), K, np.random.default_rng(2), g)
    assert deeper["exposure_s"] == g.max_exposure_s and deeper["noise_sigma_dark"] > 10 * ce._READ


def test_motion_blur_smears_an_edge_along_the_motion_and_keeps_the_light():
    img = np.zeros((20, 40, 1), np.float32)
    img[:, 20:] = 1.0
    motion = np.zeros((20, 40, 2), np.float32)
    motion[..., 0] = 8.0  # 8 px to the right over the longest exposure
    half = ce.motion_blur(img.copy()[..., 0:1].repeat(3, -1), motion, 0.5)[..., 0]
    row = half[10]
    ramp = np.flatnonzero((row > 0.02) & (row < 0.98))
    assert 2 <= len(ramp) <= 5 and abs(ramp.mean() - 19.5) < 1.0  # 4 px wide, centred
    assert row.sum() == pytest.approx(20.0, abs=0.05)
    still = np.zeros_like(motion)
    same = img[..., 0:1].repeat(3, -1)
    assert ce.motion_blur(same, still, 1.0) is same


def test_a_noiseless_sensor_is_the_same_camera_without_its_noise():
    g = ce.GRASSHOPPER2_11HZ
    quiet = dataclasses.replace(g, noise=0.0)
    dark = 2e-5  # a night scene: long exposure and high gain, where the noise is strong
    noisy_a, meta = ce.expose(_radiance(dark), K, np.random.default_rng(1), g)
    noisy_b, _ = ce.expose(_radiance(dark), K, np.random.default_rng(2), g)
    same_a, _ = ce.expose(_radiance(dark), K, np.random.default_rng(1),
                          dataclasses.replace(g, noise=1.0))
    np.testing.assert_array_equal(noisy_a, same_a)  # noise 1 is the camera as it is
    assert not np.array_equal(noisy_a, noisy_b)
    clean_a, clean_meta = ce.expose(_radiance(dark), K, np.random.default_rng(1), quiet)
    clean_b, _ = ce.expose(_radiance(dark), K, np.random.default_rng(2), quiet)
    np.testing.assert_array_equal(clean_a, clean_b)  # nothing left that the noise draws
    assert clean_meta["gain"] == meta["gain"] and clean_meta["noise_sigma_dark"] == 0.0
    # The same exposure: the noiseless frame is the noisy one's mean, without its spread.
    assert abs(float(clean_a.mean()) - float(noisy_a.mean())) < 0.1 * float(noisy_a.mean())
    assert np.std(clean_a.astype(float) - noisy_a) > 1.0


def test_an_exposure_limit_trades_the_long_exposure_for_gain():
    g = ce.GRASSHOPPER2_11HZ
    short = ce.with_exposure_limit(g, g.max_exposure_s / 10)
    dark = 2e-6  # darker than either camera can bring to the target: both at their limits
    long_img, long_meta = ce.expose(_radiance(dark), K, np.random.default_rng(1), g)
    short_img, short_meta = ce.expose(_radiance(dark), K, np.random.default_rng(1), short)
    assert short_meta["exposure_s"] == pytest.approx(g.max_exposure_s / 10)
    assert long_meta["exposure_s"] == pytest.approx(g.max_exposure_s)
    # The same amplification at its top: the same noise relative to the signal's scale...
    assert short_meta["noise_sigma_dark"] == pytest.approx(long_meta["noise_sigma_dark"])
    assert short_meta["gain"] == pytest.approx(long_meta["gain"] / 10)
    # ...on a tenth of the light: a darker frame.
    assert short_img.mean() < long_img.mean()
    # A bright scene is taken as before (its exposure below either limit).
    a, ma = ce.expose(_radiance(0.05), K, np.random.default_rng(1), g)
    b, mb = ce.expose(_radiance(0.05), K, np.random.default_rng(1), short)
    np.testing.assert_array_equal(a, b)
    assert ma["gain"] == mb["gain"]
    for bad in (0.0, 2 * g.max_exposure_s):
        with pytest.raises(ValueError, match="exposure limit"):
            ce.with_exposure_limit(g, bad)
    with pytest.raises(ValueError, match="exposure limit"):
        ce.with_exposure_limit(ce.WEBCAM, 0.01)
