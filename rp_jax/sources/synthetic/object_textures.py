"""Textures of the objects in the synthetic street: trees, cars, people, street furniture.

The surfaces' textures (facades, walls, roofs, ground) are ``textures``; this module paints
the objects standing on them, with the same conventions (RGBA ``uint8``, the fourth channel
the material's *aux*: alpha of cut-outs, emission of car lights; sizes multiples of 16).
A tree billboard is split into a season-independent structure (``tree_structure``) and its
look in a season (``tree_texture``: leaf density, autumn colour, snow).
"""

from __future__ import annotations

import cv2
import numpy as np

from rp_jax.sources.synthetic.textures import (
    LETTERS,
    finish,
    pad16,
    put_text,
    rand_colour,
    value_noise,
)

__all__ = ["car_textures", "person_texture", "plain_texture", "tree_structure", "tree_texture"]


# ---------------------------------------------------------------- trees


def tree_structure(seed: int, height_m: float, crown_r_m: float, texel: float = 0.03) -> dict:
    """The season-independent part of a tree billboard: trunk/branches and leaf clusters.

    Returns:
      A dict with ``wood`` (H, W) float32 coverage of trunk and branches, ``leaf_rank``
      (H, W) uint8 (a leaf texel appears when its rank is below the season's density),
      ``leaf_shade`` (H, W) float32 and ``leaf_hue`` (H, W) float32 per-leaf variation,
      ``bark`` (3,) colour.
    """
    rng = np.random.default_rng(seed)
    width_m = 2 * crown_r_m + 0.4
    W, H = pad16(width_m / texel), pad16(height_m / texel)
    ppm = W / width_m
    wood = np.zeros((H, W), np.float32)
    trunk_top = H - int(rng.uniform(0.3, 0.45) * height_m * ppm)
    cx = W // 2
    tw = max(3, int(rng.uniform(0.12, 0.2) * ppm))
    cv2.line(wood, (cx, H), (cx, trunk_top), 1.0, tw, cv2.LINE_AA)

    def branch(x, y, ang, length, th, depth):
        if depth == 0 or length < 6:
            return
        x2, y2 = x + length * np.sin(ang), y - length * np.cos(ang)
        cv2.line(wood, (int(x), int(y)), (int(x2), int(y2)), 1.0, max(1, int(th)), cv2.LINE_AA)
        for _ in range(2 if depth > 1 else 3):
            branch(
                x2,
                y2,
                ang + rng.normal(0, 0.55),
                length * rng.uniform(0.55, 0.8),
                th * 0.65,
                depth - 1,
            )

    crown_h = trunk_top
    for _ in range(int(rng.integers(3, 6))):
        branch(cx, trunk_top, rng.normal(0, 0.6), crown_h * rng.uniform(0.3, 0.45), tw * 0.7, 5)
    wood = np.clip(wood, 0, 1)
    # Leaf clusters: many blobs inside the crown ellipse, each with its own rank and shade.
    rank = np.full((H, W), 255, np.uint8)
    shade = np.zeros((H, W), np.float32)
    hue = np.zeros((H, W), np.float32)
    ccx, ccy = cx, trunk_top * 0.5
    ax, ay = W * 0.45, trunk_top * 0.52
    n = int(ax * ay / 9)
    for _ in range(n):
        r = np.sqrt(rng.random())
        a = rng.uniform(0, 2 * np.pi)
        px, py = int(ccx + ax * r * np.cos(a)), int(ccy + ay * r * np.sin(a))
        rad = int(rng.integers(2, 6))
        rk = int(rng.integers(0, 250))
        cv2.circle(rank, (px, py), rad, rk, -1)
        cv2.circle(
            shade,
            (px, py),
            rad,
            float(0.55 + 0.45 * (1 - r) * rng.uniform(0.6, 1.0) + 0.2 * (py < ccy)),
            -1,
        )
        cv2.circle(hue, (px, py), rad, float(rng.random()), -1)
    return {
        "wood": wood,
        "leaf_rank": rank,
        "leaf_shade": shade,
        "leaf_hue": hue,
        "bark": np.float32([0.30, 0.25, 0.20]) * rng.uniform(0.7, 1.2),
    }


def tree_texture(structure: dict, density: float, autumn: float, snow: int = 0) -> np.ndarray:
    """Composes a tree billboard for a season.

    Args:
      structure: from ``tree_structure``.
      density: fraction of leaf texels present (0 bare winter tree .. 1 full summer crown).
      autumn: 0 green .. 1 full autumn colours (yellow, orange, red, brown).
      snow: snow level; whitens the upper side of branches when > 0.

    Returns:
      RGBA uint8, aux = alpha.
    """
    wood, rank, shade, hue = (
        structure["wood"],
        structure["leaf_rank"],
        structure["leaf_shade"],
        structure["leaf_hue"],
    )
    leaf = (rank.astype(np.float32) < density * 250.0).astype(np.float32)
    green = np.stack([0.16 + 0.08 * hue, 0.30 + 0.14 * hue, 0.08 + 0.05 * hue], -1)
    fall = np.stack([0.55 + 0.25 * hue, 0.20 + 0.35 * hue, 0.05 + 0.04 * hue], -1)
    # Each leaf turns at its own time: leaves with low hue change first.
    turn = np.clip((autumn * 1.4 - hue) * 4.0, 0.0, 1.0)[..., None]
    leaf_col = (green * (1 - turn) + fall * turn) * shade[..., None]
    bark = structure["bark"]
    if snow > 0:
        bark = bark * 0.5 + 0.45
    rgb = np.where(leaf[..., None] > 0, leaf_col, bark * (0.7 + 0.3 * wood[..., None]))
    alpha = np.maximum(leaf, wood)
    return finish(rgb.astype(np.float32), (alpha * 255).astype(np.uint8), blur=0.5)


# ---------------------------------------------------------------- cars, people, furniture


_CAR_COLOURS = np.array(
    [
        [0.85, 0.85, 0.85],
        [0.08, 0.08, 0.09],
        [0.45, 0.46, 0.48],
        [0.60, 0.10, 0.10],
        [0.10, 0.18, 0.45],
        [0.75, 0.75, 0.78],
        [0.20, 0.30, 0.22],
        [0.80, 0.65, 0.20],
        [0.35, 0.20, 0.15],
    ],
    np.float32,
)


def car_textures(
    seed: int, length_m: float, width_m: float, body_h: float, cabin_h: float, texel: float = 0.03
) -> dict:
    """Textures of one car's box faces: ``side_l``, ``side_r``, ``front``, ``back``, ``top``,
    ``cabin_side_l/r``, ``cabin_front``, ``cabin_back``, ``cabin_top``. Aux = light emission."""
    rng = np.random.default_rng(seed)
    body = _CAR_COLOURS[rng.integers(len(_CAR_COLOURS))] * rng.uniform(0.85, 1.1)

    def panel(wm, hm):
        W, H = pad16(wm / texel), pad16(hm / texel)
        g = value_noise((H, W), rng, cell=20, octaves=2)[..., None]
        grad = np.linspace(1.1, 0.75, H, dtype=np.float32)[:, None, None]
        return body * (0.92 + 0.12 * g) * grad, np.zeros((H, W), np.uint8), W / wm

    out = {}
    for side in ("side_l", "side_r"):
        rgb, aux, ppm = panel(length_m, body_h)
        H, W = aux.shape
        for wx in (0.18, 0.78):  # wheels
            cx = int(wx * W) if side == "side_l" else int((1 - wx) * W)
            cv2.circle(rgb, (cx, H), int(0.36 * ppm), (0.05, 0.05, 0.05), -1, cv2.LINE_AA)
            cv2.circle(rgb, (cx, H), int(0.2 * ppm), (0.55, 0.55, 0.56), -1, cv2.LINE_AA)
        for dx in (0.38, 0.6):
            cv2.line(rgb, (int(dx * W), 0), (int(dx * W), H), (0.05, 0.05, 0.05), 1, cv2.LINE_AA)
            cv2.line(
                rgb,
                (int((dx + 0.12) * W), int(0.25 * H)),
                (int((dx + 0.17) * W), int(0.25 * H)),
                (0.2, 0.2, 0.2),
                2,
            )
        rgb[H - int(0.12 * ppm) :] *= 0.35
        out[side] = finish(rgb, aux)
    for end in ("front", "back"):
        rgb, aux, ppm = panel(width_m, body_h)
        H, W = aux.shape
        lc = (0.95, 0.95, 0.85) if end == "front" else (0.7, 0.05, 0.05)
        for lx in (0.12, 0.88):
            cv2.ellipse(
                rgb,
                (int(lx * W), int(0.3 * H)),
                (int(0.1 * W), int(0.1 * H)),
                0,
                0,
                360,
                lc,
                -1,
                cv2.LINE_AA,
            )
            cv2.ellipse(
                aux,
                (int(lx * W), int(0.3 * H)),
                (int(0.1 * W), int(0.1 * H)),
                0,
                0,
                360,
                255 if end == "front" else 140,
                -1,
            )
        rgb[int(0.55 * H) : int(0.8 * H), int(0.38 * W) : int(0.62 * W)] = (0.9, 0.9, 0.85)  # plate
        put_text(
            rgb,
            "".join(rng.choice(list(LETTERS), 5)),
            (int(0.39 * W), int(0.76 * H)),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.25 * W / 60,
            np.float32([0.1, 0.1, 0.2]),
            1,
        )
        if end == "front":
            rgb[int(0.35 * H) : int(0.5 * H), int(0.3 * W) : int(0.7 * W)] = 0.1
        out[end] = finish(rgb, aux)
    rgb, aux, _ = panel(length_m, width_m)
    out["top"] = finish(rgb, aux)
    glass = np.float32([0.12, 0.14, 0.17])
    for name, (wm, hm) in {
        "cabin_side_l": (length_m * 0.55, cabin_h),
        "cabin_side_r": (length_m * 0.55, cabin_h),
        "cabin_front": (width_m * 0.9, cabin_h),
        "cabin_back": (width_m * 0.9, cabin_h),
    }.items():
        rgb, aux, ppm = panel(wm, hm)
        H, W = aux.shape
        b = max(2, int(0.06 * ppm))
        sky = np.linspace(0.9, 0.5, H - 2 * b, dtype=np.float32)[:, None, None]
        rgb[b : H - b, b : W - b] = glass * (1 + sky)
        if name.startswith("cabin_side"):
            rgb[b : H - b, W // 2 - b : W // 2 + b] = body * 0.5
            if rng.random() < 0.5:  # a head in the car
                cv2.circle(
                    rgb,
                    (int(W * rng.uniform(0.2, 0.4)), int(H * 0.55)),
                    int(0.1 * ppm),
                    (0.2, 0.15, 0.12),
                    -1,
                )
        out[name] = finish(rgb, aux)
    rgb, aux, _ = panel(length_m * 0.55, width_m * 0.9)
    out["cabin_top"] = finish(rgb, aux)
    return out


def person_texture(seed: int, texel: float = 0.02) -> np.ndarray:
    """A pedestrian cut-out 0.7 m x 1.75 m: head, torso, legs; aux = alpha."""
    rng = np.random.default_rng(seed)
    W, H = pad16(0.7 / texel), pad16(1.75 / texel)
    rgb = np.zeros((H, W, 3), np.float32)
    a = np.zeros((H, W), np.uint8)
    cx = W // 2
    skin = np.float32([0.85, 0.65, 0.5]) * rng.uniform(0.35, 1.05)
    top = rand_colour(rng, 0.7)
    legs = (
        np.float32([0.15, 0.18, 0.3]) * rng.uniform(0.5, 1.5)
        if rng.random() < 0.6
        else rand_colour(rng, 0.4)
    )
    hr = int(0.11 / 1.75 * H)
    cv2.circle(rgb, (cx, hr + 2), hr, skin.tolist(), -1, cv2.LINE_AA)
    cv2.circle(a, (cx, hr + 2), hr, 255, -1)
    cv2.ellipse(rgb, (cx, hr - 2), (hr, hr // 2 + 2), 0, 180, 360, (0.1, 0.07, 0.05), -1)
    sh = int(0.22 * W)
    torso = np.array(
        [
            [cx - sh, 2 * hr + 6],
            [cx + sh, 2 * hr + 6],
            [cx + sh - 2, int(0.55 * H)],
            [cx - sh + 2, int(0.55 * H)],
        ]
    )
    cv2.fillPoly(rgb, [torso], top.tolist())
    cv2.fillPoly(a, [torso], 255)
    for sgn in (-1, 1):  # arms and legs
        cv2.line(
            rgb,
            (cx + sgn * sh, 2 * hr + 10),
            (cx + sgn * (sh + 4), int(0.52 * H)),
            (top * 0.8).tolist(),
            7,
        )
        cv2.line(a, (cx + sgn * sh, 2 * hr + 10), (cx + sgn * (sh + 4), int(0.52 * H)), 255, 7)
        lx = cx + sgn * int(rng.uniform(0.04, 0.12) * W)
        cv2.line(rgb, (cx + sgn * 6, int(0.55 * H)), (lx, H - 4), legs.tolist(), 9)
        cv2.line(a, (cx + sgn * 6, int(0.55 * H)), (lx, H - 4), 255, 9)
        cv2.line(rgb, (lx, H - 4), (lx + 6, H - 4), (0.05, 0.05, 0.05), 5)
    if rng.random() < 0.3:  # a bag
        cv2.rectangle(
            rgb,
            (cx + sh, int(0.45 * H)),
            (cx + sh + 10, int(0.6 * H)),
            rand_colour(rng, 0.5).tolist(),
            -1,
        )
        cv2.rectangle(a, (cx + sh, int(0.45 * H)), (cx + sh + 10, int(0.6 * H)), 255, -1)
    return finish(rgb, a, blur=0.5)


def plain_texture(
    seed: int,
    colour: tuple[float, float, float],
    w: int = 16,
    h: int = 64,
    aux: int = 0,
    bands: int = 0,
) -> np.ndarray:
    """Small painted-metal/concrete texture for poles, bins, hydrants, lamp heads."""
    rng = np.random.default_rng(seed)
    g = value_noise((h, w), rng, cell=4, octaves=2)[..., None]
    rgb = np.float32(colour) * (0.85 + 0.3 * g)
    for k in range(bands):
        y = int((k + 1) * h / (bands + 1))
        rgb[y : y + max(1, h // 32)] *= 0.6
    return finish(rgb.astype(np.float32), np.full((h, w), aux, np.uint8), blur=0.5)
