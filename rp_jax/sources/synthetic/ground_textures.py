"""Textures of the ground in the synthetic street: road, sidewalk, grass, lawn paths.

The ground's materials, with the conventions of ``textures`` (RGBA ``uint8``; the fourth
channel is the snow susceptibility of the texel, which ``apply_snow`` reads with the day's
snow depth). Grass and gravel take their light and dark structure from real photographs
(``photo_textures``) where scikit-image is installed; road markings, curbs and cracks are
drawn here.
"""

from __future__ import annotations

import cv2
import numpy as np

from rp_jax.sources.synthetic import photo_textures as pt
from rp_jax.sources.synthetic.textures import TEXEL_M, apply_snow, finish, pad16, value_noise

__all__ = ["ground_texture"]


def ground_texture(
    seed: int,
    kind: str,
    length_m: float,
    width_m: float,
    *,
    lanes: int = 2,
    season: int = 1,
    snow: int = 0,
    crosswalk: bool = False,
    texel: float = TEXEL_M,
    snow_pattern: int = 0,
) -> np.ndarray:
    """A ground tile: rows run along world -y (north at the top), columns along +x (east).

    Args:
      seed: per-tile seed.
      kind: ``"road"`` (asphalt, lane markings), ``"sidewalk"`` (concrete slabs with a curb
        on the road side), ``"grass"`` (lawn, with paths/driveways), ``"plaza"``.
      length_m, width_m: size along x and along y.
      lanes: number of lanes (road only).
      season: grass colour state 0 winter, 1 spring/summer, 2 late summer, 3 autumn.
      snow: snow level 0..4 (0 none).
      crosswalk: paint a zebra crossing (road only).
      texel: metres per texel.
      snow_pattern: id of the snow pack (``conditions.snow_state``): its drift pattern.

    Returns:
      RGBA uint8 whose aux channel holds snow susceptibility (road 10..50, up to 180
      along the curbs; sidewalk 90..180; grass 200..255).
    """
    rng = np.random.default_rng(seed)
    W, H = pad16(length_m / texel), pad16(width_m / texel)
    ppm = W / length_m
    texel_yx = (width_m / H, length_m / W)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    fine = value_noise((H, W), rng, cell=3, octaves=2)[..., None]
    blot = value_noise((H, W), rng, cell=2.5 * ppm, octaves=3)[..., None]
    if kind == "road":
        # Asphalt stays procedural: no photograph of asphalt ships here, and the gravel
        # photo is no stand-in. Its loose 20 mm stones with black gaps between them would,
        # area-averaged over 25 mm texels, give grainy high-contrast mottling, where an
        # asphalt wearing course is 6-14 mm chippings bound in bitumen and rolled flat:
        # darker and of lower contrast, which the fine noise and sparse specks draw.
        base = np.float32([0.30, 0.30, 0.31]) * rng.uniform(0.85, 1.15)
        speck = (rng.random((H, W), dtype=np.float32) ** 6)[..., None]
        rgb = base * (0.75 + 0.35 * fine + 0.4 * speck) * (0.85 + 0.3 * blot)
        # Snow lies first along the curbs, where the plough piles it.
        curb = np.clip(1.0 - np.minimum(yy, H - 1 - yy) / (1.2 * ppm), 0.0, 1.0)
        aux = (10 + 40 * blot[..., 0] + 130 * curb**1.5).astype(np.uint8)
        # Patches and cracks.
        for _ in range(rng.integers(0, 4)):
            pw, ph = int(rng.uniform(0.5, 3) * ppm), int(rng.uniform(0.5, 2) * ppm)
            px, py = rng.integers(0, W - pw), rng.integers(0, H - ph)
            rgb[py : py + ph, px : px + pw] *= rng.uniform(0.7, 1.2)
        for _ in range(rng.integers(2, 8)):
            pts = np.cumsum(rng.normal(0, 0.25 * ppm, (rng.integers(3, 9), 2)), axis=0) + [
                rng.integers(0, W),
                rng.integers(0, H),
            ]
            cv2.polylines(rgb, [pts.astype(np.int32)], False, (0.12, 0.12, 0.12), 2, cv2.LINE_AA)
        if rng.random() < 0.4:  # manhole cover
            cx, cy, r = (
                rng.integers(int(ppm), W - int(ppm)),
                rng.integers(int(ppm), H - int(ppm)),
                int(0.35 * ppm),
            )
            cv2.circle(rgb, (int(cx), int(cy)), r, (0.22, 0.21, 0.2), -1, cv2.LINE_AA)
            for k in range(-r, r, 6):
                cv2.line(
                    rgb,
                    (int(cx - r), int(cy + k)),
                    (int(cx + r), int(cy + k)),
                    (0.3, 0.29, 0.28),
                    1,
                )
            cv2.circle(rgb, (int(cx), int(cy)), r, (0.15, 0.15, 0.15), 2, cv2.LINE_AA)
        lane_w = H / lanes
        paint_w = max(3, int(0.12 * ppm))
        white = np.float32([0.85, 0.85, 0.82])
        yellow = np.float32([0.85, 0.70, 0.20])
        wear = (0.75 + 0.25 * value_noise((H, W), rng, cell=12, octaves=2))[..., None]
        paint = np.zeros((H, W), np.float32)
        col = np.zeros((H, W, 3), np.float32)
        for k in range(1, lanes):
            yc = int(k * lane_w)
            if lanes == 2:  # double yellow centre line
                for off in (-paint_w, paint_w):
                    paint[yc + off - paint_w // 2 : yc + off + paint_w // 2 + 1] = 1
                    col[yc + off - paint_w // 2 : yc + off + paint_w // 2 + 1] = yellow
            else:
                dash = ((xx[0] % (6 * ppm)) < 3 * ppm).astype(np.float32)
                paint[yc - paint_w // 2 : yc + paint_w // 2 + 1] = dash
                col[yc - paint_w // 2 : yc + paint_w // 2 + 1] = white
        for yc in (int(0.3 * ppm), H - int(0.3 * ppm)):  # edge lines
            paint[yc - paint_w // 2 : yc + paint_w // 2 + 1] = 1
            col[yc - paint_w // 2 : yc + paint_w // 2 + 1] = white
        if crosswalk:
            x0 = int(rng.uniform(0.2, 0.5) * W)
            stripe = ((yy[:, 0] % (1.0 * ppm)) < 0.5 * ppm).astype(np.float32)
            paint[:, x0 : x0 + int(3 * ppm)] = np.maximum(
                paint[:, x0 : x0 + int(3 * ppm)], stripe[:, None]
            )
            col[:, x0 : x0 + int(3 * ppm)] = white
        p = (paint * wear[..., 0])[..., None]
        rgb = rgb * (1 - p) + col * p * (0.9 + 0.1 * fine)
    elif kind == "sidewalk":
        base = np.float32([0.66, 0.64, 0.60]) * rng.uniform(0.85, 1.1)
        slab = rng.uniform(1.2, 1.8) * ppm
        joint = ((xx % slab) < 2) | ((yy % slab) < 2)
        sid = np.floor(xx / slab) * 7 + np.floor(yy / slab)
        hsh = np.sin(sid * 12.9898 + seed % 97) * 43758.5453
        hsh = (hsh - np.floor(hsh))[..., None]
        rgb = (
            base
            * (0.85 + 0.15 * hsh)
            * (0.85 + 0.25 * fine)
            * (0.85 + 0.25 * blot)
            * np.where(joint, 0.7, 1.0)[..., None]
        )
        aux = (90 + 90 * blot[..., 0]).astype(np.uint8)
        curb = int(0.2 * ppm)  # curb on the road side: the tile's top rows (north) by convention
        rgb[:curb] = np.float32([0.75, 0.74, 0.71]) * (0.9 + 0.1 * fine[:curb])
        rgb[curb : curb + 2] *= 0.6
        for _ in range(rng.integers(0, 5)):  # stains, gum
            cx, cy = rng.integers(0, W), rng.integers(curb, H)
            cv2.circle(
                rgb,
                (int(cx), int(cy)),
                int(rng.integers(2, 12)),
                (0.35, 0.34, 0.33),
                -1,
                cv2.LINE_AA,
            )
    else:  # grass / lawn
        greens = {
            0: [0.42, 0.38, 0.26],
            1: [0.26, 0.42, 0.16],
            2: [0.34, 0.42, 0.18],
            3: [0.45, 0.40, 0.20],
        }
        base = np.float32(greens[int(season)])
        blade = rng.random((H, W), dtype=np.float32)[..., None]
        photos = pt.available()
        if photos:
            # The grass photograph gives the lawn's structure below ~0.5 m (blades, clumps,
            # weeds: the procedural fine noise and blades); the 2.5 m blotches stay.
            # (0.975: the mean of the procedural modulation below, so the lawn's mean colour stays.)
            rgb = pt.grass_tile(seed, H, W, texel_yx, base * 0.975) * (0.8 + 0.4 * blot)
        else:
            rgb = base * (0.7 + 0.3 * fine + 0.25 * blade) * (0.8 + 0.4 * blot)
        aux = (205 + 50 * blot[..., 0]).astype(np.uint8)
        if rng.random() < 0.5:  # a path or driveway across the lawn (gravel with the photos)
            px, pw = rng.integers(0, max(1, W - int(3 * ppm))), int(rng.uniform(1.0, 3.0) * ppm)
            if photos:
                rgb[:, px : px + pw] = pt.gravel_tile(
                    seed, H, pw, texel_yx, np.float32([0.58, 0.56, 0.52]) * 0.975
                )
            else:
                rgb[:, px : px + pw] = np.float32([0.58, 0.56, 0.52]) * (
                    0.85 + 0.25 * fine[:, px : px + pw]
                )
            aux[:, px : px + pw] = 90
        if season == 3:
            leaves = rng.random((H, W)) < 0.01
            rgb[leaves] = np.float32([0.65, 0.35, 0.1])
    rgb = apply_snow(rgb, aux, snow, seed, snow_pattern)
    return finish(rgb, aux, blur=0.6)
