"""What a real webcam does to scene radiance: auto-exposure, vignetting, noise, tone curve.

The paper's daily repeatability curves (Sec. IV-B, Fig. 5a) fall at dusk and night because
images get dark and noisy there: a webcam's auto-exposure raises its gain as the light
falls, up to a maximum, after which frames stay dark and the noise rises. This module
models that pipeline on linear radiance so that the synthetic world's night frames lose
interest points the way real ones do.

A ``Sensor`` says how far a camera can go: the longest exposure its frame rate allows and
the amplification beyond it. Below the exposure limit a darker scene is met with a longer
exposure (the same photons per pixel, so the same noise as by day, but motion blur for a
moving camera); beyond it, with gain, which raises the noise with it. ``WEBCAM`` is the
pipeline's original camera (all of its range above a sunny noon counts as gain, no blur);
``GRASSHOPPER2_11HZ`` is the Oxford RobotCar's Grasshopper2 at the dataset's frame rate.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import cv2
import numpy as np

__all__ = ["expose", "motion_blur", "motion_field", "Sensor", "WEBCAM", "GRASSHOPPER2_11HZ",
           "BUMBLEBEE_XB3_16HZ", "with_exposure_limit",
           "sensor_named", "TARGET_MEAN", "MAX_GAIN", "MIN_GAIN"]

TARGET_MEAN = 0.2  # linear mean luminance auto-exposure aims at
MIN_GAIN = 0.5
MAX_GAIN = 40.0  # the sensor's limit: beyond it dusk and night frames stay dark
_DAY_GAIN = 2.0  # the gain of a sunny noon frame: noise is defined relative to it
_SHOT = 4e-4
_READ = 6e-4


@dataclasses.dataclass(frozen=True)
class Sensor:
    """How far a camera's auto-exposure can brighten a dark scene.

    Gains are the total scale from scene radiance to the linear image (exposure time times
    amplification), in the units where a sunny noon frame takes ``_DAY_GAIN``.

    Attributes:
      name: the sensor's name (``sensor_named`` finds it back).
      min_gain, max_gain: the range of the total gain.
      exposure_gain: the total gain reached by the longest exposure without amplification;
        above it the noise grows with the gain.
      max_exposure_s: the longest exposure (s), for motion blur; None: no blur modelled.
      noise: the scale of the sensor's shot and read noise: 1 for every real camera here;
        0 renders the same frame without noise (a counterfactual, e.g.
        ``experiments.map_summarization.night_factors``).
    """

    name: str
    min_gain: float
    max_gain: float
    exposure_gain: float
    max_exposure_s: float | None = None
    noise: float = 1.0

    def exposure_s(self, gain: float) -> float:
        """The exposure time of a frame taken at ``gain`` (0 when no blur is modelled)."""
        if self.max_exposure_s is None:
            return 0.0
        return self.max_exposure_s * min(gain / self.exposure_gain, 1.0)


WEBCAM = Sensor("webcam", MIN_GAIN, MAX_GAIN, _DAY_GAIN)


def _grasshopper2_11hz() -> Sensor:
    """The RobotCar's side and rear cameras (Maddern et al., "1 Year, 1000 km: The Oxford
    RobotCar Dataset", IJRR 2017): Point Grey Grasshopper2 GS2-FW-14S5C-C, 2/3" Sony ICX285
    CCD, global shutter, Sunex DSL315B fisheye at f/2.3, 11.1 Hz.

    - Longest exposure: one frame period, 1 / 11.1 s.
    - A sunny noon frame's exposure from the exposure equation N² / t = L S / K (ISO 2720,
      K = 12.5) for the "sunny 16" scene (L of about 3,200 cd/m²) at N = 2.3 and a base
      sensitivity S = ISO 100 (assumed: the order of a colour 2/3" CCD of its generation,
      not read from the sensor's data sheet here): about 0.2 ms, so the exposure alone
      spans about 430 times a sunny noon frame's.
    - Amplification: 0-24 dB (the Grasshopper2's gain range), a factor of 15.8 beyond.
    """
    frame_s = 1.0 / 11.1
    noon_s = 12.5 * 2.3**2 / (3200.0 * 100.0)
    exposure_gain = _DAY_GAIN * frame_s / noon_s
    return Sensor("grasshopper2_11hz", MIN_GAIN, exposure_gain * 10 ** (24.0 / 20.0),
                  exposure_gain, frame_s)


GRASSHOPPER2_11HZ = _grasshopper2_11hz()


def _bumblebee_xb3_16hz() -> Sensor:
    """The RobotCar's stereo camera (Maddern et al., IJRR 2017): Point Grey Bumblebee XB3
    BBX3-13S2C-38, 1/3" Sony ICX445 CCD, global shutter, 3.8 mm lens, 16 Hz.

    - Longest exposure: one frame period, 1 / 16 s.
    - The noon exposure, the base sensitivity and the 0-24 dB of amplification are the
      side cameras' (``_grasshopper2_11hz``): assumed, the dataset's documentation gives no
      f-number or gain range for this camera.
    """
    side = GRASSHOPPER2_11HZ
    frame_s = 1.0 / 16.0
    exposure_gain = side.exposure_gain * frame_s / side.max_exposure_s
    return Sensor("bumblebee_xb3_16hz", MIN_GAIN,
                  side.max_gain * exposure_gain / side.exposure_gain, exposure_gain, frame_s)


BUMBLEBEE_XB3_16HZ = _bumblebee_xb3_16hz()
_SENSORS = {s.name: s for s in (WEBCAM, GRASSHOPPER2_11HZ, BUMBLEBEE_XB3_16HZ)}


def with_exposure_limit(sensor: Sensor, seconds: float) -> Sensor:
    """``sensor`` with its auto-exposure stopped at ``seconds`` (a blur-limiting exposure
    policy): beyond it the same amplification makes up the rest, so the whole gain range
    shrinks in proportion and a dark frame gets darker and noisier instead of longer.

    Raises:
      ValueError: the sensor models no exposure time, or ``seconds`` is not in
        (0, its longest exposure].
    """
    if sensor.max_exposure_s is None or not 0 < seconds <= sensor.max_exposure_s:
        raise ValueError(f"an exposure limit of {seconds} s for {sensor.name}: expected "
                         f"(0, {sensor.max_exposure_s}] s")
    k = seconds / sensor.max_exposure_s
    return dataclasses.replace(sensor, exposure_gain=sensor.exposure_gain * k,
                               max_gain=sensor.max_gain * k, max_exposure_s=seconds)


def sensor_named(name: str | None) -> Sensor:
    """The sensor called ``name`` (None: ``WEBCAM``)."""
    if name is None:
        return WEBCAM
    try:
        return _SENSORS[name]
    except KeyError:
        raise ValueError(f"unknown sensor {name!r}; known: {', '.join(_SENSORS)}") from None


def motion_field(K: np.ndarray, R: np.ndarray, depth: np.ndarray, velocity: np.ndarray,
                 seconds: float) -> np.ndarray:
    """The image displacement (H, W, 2) of the static scene while a camera moving at
    ``velocity`` (world, m/s) exposes for ``seconds``, centred on the frame's instant (the
    camera moves by ``velocity * seconds``; points at infinity do not move)."""
    h, w = depth.shape
    uu, vv = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    finite = np.isfinite(depth)
    z = np.where(finite, depth, 1.0).astype(np.float32)
    rays = np.stack([uu, vv, np.ones_like(uu)], -1) @ np.linalg.inv(K).T.astype(np.float32)
    Xc = rays * z[..., None] - (R @ np.asarray(velocity, np.float64) * seconds).astype(np.float32)
    x = Xc @ K.T.astype(np.float32)
    zc = np.maximum(x[..., 2], np.float32(1e-3))
    out = np.stack([x[..., 0] / zc - uu, x[..., 1] / zc - vv], -1)
    out[~finite | (Xc[..., 2] <= 1e-3)] = 0.0
    return np.ascontiguousarray(out, np.float32)


def motion_blur(img: np.ndarray, motion: np.ndarray, fraction: float) -> np.ndarray:
    """Averages each pixel along the path the scene point behind it takes in the image
    while the shutter is open (a gather approximation of the blur of a translating camera).

    Args:
      img: (H, W, C) float32 linear radiance.
      motion: (H, W, 2) float32 image displacement (px) over the sensor's longest
        exposure, centred on the frame's instant (from ``-motion/2`` to ``+motion/2``).
      fraction: this frame's exposure over the longest one.

    Returns:
      The blurred image (a new array; ``img`` itself when there is no motion to speak of).
    """
    length = float(np.abs(motion).max(initial=0.0)) * fraction
    samples = min(int(math.ceil(length)) + 1, 32)
    if samples < 2:
        return img
    h, w = img.shape[:2]
    gx, gy = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    out = np.zeros_like(img)
    for s in np.linspace(-0.5, 0.5, samples, dtype=np.float32) * np.float32(fraction):
        out += cv2.remap(img, gx + s * motion[..., 0], gy + s * motion[..., 1],
                         cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    out *= np.float32(1.0 / samples)
    return out


@functools.lru_cache(maxsize=16)
def _vignette(width: int, height: int, fx: float, cx: float, cy: float) -> np.ndarray:
    xs = (np.arange(width, dtype=np.float32) - cx) / fx
    ys = (np.arange(height, dtype=np.float32) - cy) / fx
    r2 = xs[None, :] ** 2 + ys[:, None] ** 2
    cos4 = 1.0 / (1.0 + r2) ** 2
    return (1.0 - 0.55 * (1.0 - cos4)).astype(np.float32)


@functools.lru_cache(maxsize=16)
def _vignette3(width: int, height: int, fx: float, cx: float, cy: float) -> np.ndarray:
    """The vignetting map repeated over the three colour channels (H, W, 3), contiguous."""
    return np.ascontiguousarray(
        np.repeat(_vignette(width, height, fx, cx, cy)[..., None], 3, axis=-1)
    )


@functools.lru_cache(maxsize=1)
def _srgb_lut() -> np.ndarray:
    x = np.linspace(0.0, 1.0, 4096)
    x = x * 1.25 / (1.0 + 0.25 * x)  # gentle highlight roll-off
    x = np.clip(x, 0, 1)
    y = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.clip(y * 255.0 + 0.5, 0, 255).astype(np.uint8)


@functools.lru_cache(maxsize=1)
def _noise_bank() -> np.ndarray:
    return np.random.default_rng(1234).standard_normal(1 << 22, dtype=np.float32)


def _gaussian_noise(shape: tuple, rng: np.random.Generator) -> tuple[np.ndarray, float]:
    """Unit Gaussian noise: a random window of a cached bank and a random sign (cheap,
    contiguous)."""
    n = int(np.prod(shape))
    bank = _noise_bank()
    if n > bank.size // 2:
        return rng.standard_normal(shape, dtype=np.float32), 1.0
    start = int(rng.integers(0, bank.size - n))
    return bank[start : start + n].reshape(shape), (-1.0 if rng.random() < 0.5 else 1.0)


@functools.lru_cache(maxsize=1)
def _srgb_lut_image() -> np.ndarray:
    """The tone curve as a 1 x 4096 uint8 image, for ``cv2.remap`` lookups."""
    return _srgb_lut().reshape(1, -1)


@functools.lru_cache(maxsize=8)
def _zero_map(height: int, width: int) -> np.ndarray:
    return np.zeros((height, width), np.float32)


def expose(
    radiance: np.ndarray,
    K: np.ndarray,
    rng: np.random.Generator,
    sensor: Sensor = WEBCAM,
    motion: np.ndarray | None = None,
) -> tuple[np.ndarray, dict]:
    """Turns linear scene radiance into a webcam's 8-bit RGB image.

    Vignetting and gain are one multiply by a cached map; the noise and the quantisation
    run in place on the frame (no full-frame temporaries but the noise and its sigma).

    Args:
      radiance: (H, W, 3) float32 linear radiance (modified in place).
      K: 3x3 intrinsics (vignetting is radial around the principal point).
      rng: generator of this frame's sensor noise.
      sensor: the camera's exposure and gain range.
      motion: (H, W, 2) image displacement over the sensor's longest exposure (a moving
        camera), or None.

    Returns:
      (rgb uint8 (H, W, 3), meta with ``gain``, ``exposure_mean``, ``noise_sigma_dark`` and,
      for a sensor with an exposure limit, ``exposure_s``).
    """
    h, w = radiance.shape[:2]
    # (the lens PSF is applied to the albedo by the renderer)
    img = np.ascontiguousarray(radiance, np.float32)
    vig = _vignette3(w, h, float(K[0, 0]), float(K[0, 2]), float(K[1, 2]))
    lum = (img[::4, ::4] * vig[::4, ::4]) @ np.float32([0.2126, 0.7152, 0.0722])
    mean = float(np.mean(np.minimum(lum, 2.0)))
    gain = float(np.clip(TARGET_MEAN / max(mean, 1e-6), sensor.min_gain, sensor.max_gain))
    exposure_s = sensor.exposure_s(gain)
    if motion is not None and exposure_s > 0:
        img = motion_blur(img, motion, exposure_s / sensor.max_exposure_s)
    cv2.multiply(img, vig, dst=img, scale=gain)
    rel = max(gain / sensor.exposure_gain, 1.0)
    # sigma = sqrt(max(img, 0) * shot + read^2), then img += sigma * N(0, 1).
    sigma = cv2.max(img, 0.0)
    cv2.addWeighted(sigma, _SHOT * rel * sensor.noise**2, sigma, 0.0,
                    (_READ * rel * sensor.noise) ** 2, dst=sigma)
    cv2.sqrt(sigma, dst=sigma)
    noise, sign = _gaussian_noise(img.shape, rng)
    cv2.multiply(sigma, noise, dst=sigma, scale=sign)
    cv2.add(img, sigma, dst=img)
    # Tone curve: a lookup of the 12-bit code in a 1 x 4096 image (remap clamps to its ends).
    codes = img.reshape(h, w * 3)
    codes *= 4095.0
    rgb = cv2.remap(
        _srgb_lut_image(),
        codes,
        _zero_map(h, w * 3),
        cv2.INTER_NEAREST,
        borderMode=cv2.BORDER_REPLICATE,
    ).reshape(h, w, 3)
    meta = {"gain": gain, "exposure_mean": mean,
            "noise_sigma_dark": float(_READ * rel * sensor.noise)}
    if sensor.max_exposure_s is not None:
        meta["exposure_s"] = exposure_s
    return rgb, meta
