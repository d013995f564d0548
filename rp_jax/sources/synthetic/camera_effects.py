"""What a real webcam does to scene radiance: auto-exposure, vignetting, noise, tone curve.

The paper's daily repeatability curves (Sec. IV-B, Fig. 5a) fall at dusk and night because
images get dark and noisy there: a webcam's auto-exposure raises its gain as the light
falls, up to a maximum, after which frames stay dark and the noise rises. This module
models that pipeline on linear radiance so that the synthetic world's night frames lose
interest points the way real ones do.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

__all__ = ["expose", "TARGET_MEAN", "MAX_GAIN", "MIN_GAIN"]

TARGET_MEAN = 0.2  # linear mean luminance auto-exposure aims at
MIN_GAIN = 0.5
MAX_GAIN = 40.0  # the sensor's limit: beyond it dusk and night frames stay dark
_DAY_GAIN = 2.0  # the gain of a sunny noon frame: noise is defined relative to it
_SHOT = 4e-4
_READ = 6e-4


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
    radiance: np.ndarray, K: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, dict]:
    """Turns linear scene radiance into a webcam's 8-bit RGB image.

    Vignetting and gain are one multiply by a cached map; the noise and the quantisation
    run in place on the frame (no full-frame temporaries but the noise and its sigma).

    Args:
      radiance: (H, W, 3) float32 linear radiance (modified in place).
      K: 3x3 intrinsics (vignetting is radial around the principal point).
      rng: generator of this frame's sensor noise.

    Returns:
      (rgb uint8 (H, W, 3), meta with ``gain``, ``exposure_mean``, ``noise_sigma``).
    """
    h, w = radiance.shape[:2]
    # (the lens PSF is applied to the albedo by the renderer)
    img = np.ascontiguousarray(radiance, np.float32)
    vig = _vignette3(w, h, float(K[0, 0]), float(K[0, 2]), float(K[1, 2]))
    lum = (img[::4, ::4] * vig[::4, ::4]) @ np.float32([0.2126, 0.7152, 0.0722])
    mean = float(np.mean(np.minimum(lum, 2.0)))
    gain = float(np.clip(TARGET_MEAN / max(mean, 1e-6), MIN_GAIN, MAX_GAIN))
    cv2.multiply(img, vig, dst=img, scale=gain)
    rel = max(gain / _DAY_GAIN, 1.0)
    # sigma = sqrt(max(img, 0) * shot + read^2), then img += sigma * N(0, 1).
    sigma = cv2.max(img, 0.0)
    cv2.addWeighted(sigma, _SHOT * rel, sigma, 0.0, (_READ * rel) ** 2, dst=sigma)
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
    return rgb, {"gain": gain, "exposure_mean": mean, "noise_sigma_dark": float(_READ * rel)}
