"""A global descriptor of an image's appearance: the conditions read from the image itself.

The paper's discussion (Sec. V) notes that the weather at the query time matters ("12:00
rainy and cloudy may look darker than 17:00 sunny"), which the time alone cannot tell. A
localization query has no weather record, but it has its pixels: this descriptor reads from
them what the sun, the clouds, the rain, the snow and the night change (issue 17, the
``appearance`` condition). It is deterministic, cheap (NumPy and one OpenCV resize, a few
milliseconds per image) and needs nothing but the image. Each entry, in ``APPEARANCE_KEYS``
order (luma Y = 0.299 R + 0.587 G + 0.114 B of the 8-bit values / 255, on the image
area-resized to at most ``WORKING_SIDE`` pixels a side):

* ``appearance_log_luma``: log2 of the mean luma, / 8 (-1 for a black image, 0 white).
  Night and dusk are darker by several stops, overcast and rain by about one; a camera's
  auto exposure compresses but does not remove it (the log: exposure is multiplicative).
* ``appearance_contrast``: the standard deviation of the luma / the mean luma (coefficient
  of variation, capped at 4). Direct sun casts hard shadows (high), an overcast sky flattens
  the light (low); it does not change with exposure.
* ``appearance_saturation``: the mean HSV-style saturation ``(max - min) / max`` of the
  pixels with a maximum above 8/255. Sunlit colours are saturated; overcast, rain, fog and
  snow are grey; so is the lamp-lit night on a sensor.
* ``appearance_blue_minus_red``, ``appearance_green_minus_magenta``: the colour balance,
  mean (B - R) and mean (G - (R + B) / 2) of the normalised channels. Blue sky light and
  shade against the warm low sun and sodium lamps; green leaves and grass in summer against
  bare trees, brown autumn and white snow.
* ``appearance_luma_<row>_<col>`` for the 2 x 2 grid (top/bottom, left/right): the mean
  luma of each quarter / the mean luma (1 everywhere for a uniform image). Where the light
  comes from: a bright sky above a dark street, the sunlit against the shaded side of a
  street, a lit road under street lamps at night.
* ``appearance_bright_share``: the share of pixels with a channel at or above 250/255
  (clipped): the sun's disc and its specular highlights, a bright sky, sunlit snow.
* ``appearance_dark_share``: the share of pixels with luma at or below 10/255: night, deep
  cast shadows under a low sun.

Entries are floats of order 1; an image that cannot be read has none (NaN: unknown, as
the other conditions, ``rp_jax.conditional.inputs``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = ["APPEARANCE_KEYS", "WORKING_SIDE", "describe", "describe_files", "unknown"]

APPEARANCE_KEYS = (
    "appearance_log_luma",
    "appearance_contrast",
    "appearance_saturation",
    "appearance_blue_minus_red",
    "appearance_green_minus_magenta",
    "appearance_luma_top_left",
    "appearance_luma_top_right",
    "appearance_luma_bottom_left",
    "appearance_luma_bottom_right",
    "appearance_bright_share",
    "appearance_dark_share",
)
WORKING_SIDE = 128  # pixels: the image is area-resized to at most this a side
_EPS = 1.0 / 255.0
_BRIGHT, _DARK, _COLOURED = 250.0 / 255.0, 10.0 / 255.0, 8.0 / 255.0
_MAX_CONTRAST = 4.0


def _working(image: np.ndarray) -> np.ndarray:
    """float32 [h, w, 3] in [0, 1], at most ``WORKING_SIDE`` a side (grey -> 3 channels)."""
    import cv2

    image = np.asarray(image)
    if image.ndim == 2:
        image = np.repeat(image[..., None], 3, axis=-1)
    if image.ndim != 3 or image.shape[-1] not in (3, 4) or min(image.shape[:2]) < 2:
        raise ValueError(f"expected an RGB image [h >= 2, w >= 2, 3], got shape {image.shape}")
    image = image[..., :3]
    scale = 255.0 if image.dtype == np.uint8 else 1.0
    image = image.astype(np.float32) / scale
    h, w = image.shape[:2]
    factor = WORKING_SIDE / max(h, w)
    if factor < 1.0:
        size = (max(2, round(w * factor)), max(2, round(h * factor)))
        image = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
    return np.clip(image, 0.0, 1.0)


def describe(image: np.ndarray) -> dict[str, float]:
    """The appearance descriptor of one RGB image (uint8, or float in [0, 1]).

    Returns:
      ``APPEARANCE_KEYS`` -> float (see the module docstring for each entry).

    Raises:
      ValueError: not an RGB (or grey) image of at least 2 x 2 pixels.
    """
    rgb = _working(image)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    luma = 0.299 * r + 0.587 * g + 0.114 * b
    mean = float(luma.mean())
    top = max(mean, _EPS)
    hi, lo = rgb.max(axis=-1), rgb.min(axis=-1)
    coloured = hi > _COLOURED
    saturation = float(((hi - lo) / np.maximum(hi, _EPS))[coloured].mean()) if coloured.any() \
        else 0.0
    h, w = luma.shape
    rows, cols = (slice(0, h // 2), slice(h // 2, h)), (slice(0, w // 2), slice(w // 2, w))
    grid = [float(luma[rs, cs].mean()) / top for rs in rows for cs in cols]
    values = [
        float(np.log2(top)) / 8.0,
        min(float(luma.std()) / top, _MAX_CONTRAST),
        saturation,
        float((b - r).mean()),
        float((g - 0.5 * (r + b)).mean()),
        *grid,
        float((hi >= _BRIGHT).mean()),
        float((luma <= _DARK).mean()),
    ]
    return dict(zip(APPEARANCE_KEYS, values, strict=True))


def unknown(n: int) -> dict[str, np.ndarray]:
    """float32 [n] NaN per key: the appearance of ``n`` images not read."""
    return {k: np.full(n, np.nan, np.float32) for k in APPEARANCE_KEYS}


def describe_files(paths: Sequence, *, readable: Sequence[bool] | None = None
                   ) -> dict[str, np.ndarray]:
    """float32 [n] per key of the image files at ``paths``, as stored (not undistorted:
    the descriptor is global), NaN where one cannot be read or ``readable`` says so."""
    from rp_jax.sources import images

    out = unknown(len(paths))
    for i, path in enumerate(paths):
        if readable is not None and not readable[i]:
            continue
        image = images.read_rgb(path)
        if image is None:
            continue
        for k, v in describe(image).items():
            out[k][i] = v
    return out
