"""Plane geometry of the renderer: near-plane clipping, a polygon's pixels, and a textured
quad warped into the image through its plane homography at the mip level whose texels are
about a pixel (shared by the rasteriser in ``render`` and the cast shadows in ``shadows``).

Conventions: ``render``'s (OpenCV pixels, ``x_cam = R X + t``, camera looking along +z);
a quad is ``origin + a u + b v`` for texture coordinates (a, b) in [0, 1]^2 (``quads``).
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["NEAR", "choose_level", "clip_near", "level_matrix", "poly_area", "poly_region",
           "texel_homography", "warp"]

NEAR = 0.05  # the camera's near plane (m)


def clip_near(poly: np.ndarray, near: float = NEAR) -> np.ndarray:
    """Sutherland-Hodgman clip of a camera-space polygon (M, 3) to z >= near."""
    z = poly[:, 2]
    if np.all(z >= near):
        return poly
    out = []
    m = len(poly)
    for i in range(m):
        a, b = poly[i], poly[(i + 1) % m]
        ina, inb = a[2] >= near, b[2] >= near
        if ina:
            out.append(a)
        if ina != inb:
            s = (near - a[2]) / (b[2] - a[2])
            out.append(a + s * (b - a))
    return np.array(out).reshape(-1, 3)


def poly_region(poly_cam: np.ndarray, K: np.ndarray, W: int, H: int):
    """ROI and coverage mask (uint8, 255 inside) of a camera-space polygon; None when not in
    the image."""
    poly = clip_near(poly_cam)
    if len(poly) < 3:
        return None
    pix = poly @ K.T
    pix = pix[:, :2] / pix[:, 2:3]
    x0, y0 = np.floor(pix.min(0)).astype(int)
    x1, y1 = np.ceil(pix.max(0)).astype(int) + 1
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, W), min(y1, H)
    if x1 <= x0 or y1 <= y0:
        return None
    mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
    pts = np.round((pix - [x0, y0]) * 16.0).astype(np.int32)
    cv2.fillPoly(mask, [pts], 255, lineType=cv2.LINE_8, shift=4)
    return (x0, y0, x1, y1), mask, pix


def texel_homography(o, u, v, Wt: int, Ht: int, K, R, t) -> np.ndarray:
    """Homography from level-0 texel coordinates (texel centres at integers) to pixels."""
    Ru, Rv = R @ u / Wt, R @ v / Ht
    c = R @ o + t + 0.5 * Ru + 0.5 * Rv
    return K @ np.stack([Ru, Rv, c], axis=1)


def level_matrix(level: int) -> np.ndarray:
    s = float(2**level)
    off = 0.5 * s - 0.5
    return np.array([[s, 0, off], [0, s, off], [0, 0, 1.0]])


def choose_level(Hm: np.ndarray, at: np.ndarray, n_levels: int) -> int:
    """Mip level with texels about the size of a pixel around image point ``at``."""
    Hinv = np.linalg.inv(Hm)
    p = np.array([[at[0], at[1], 1.0], [at[0] + 1, at[1], 1.0], [at[0], at[1] + 1, 1.0]]) @ Hinv.T
    p = p[:, :2] / p[:, 2:3]
    scale = max(np.linalg.norm(p[1] - p[0]), np.linalg.norm(p[2] - p[0]))
    return int(np.clip(np.floor(np.log2(max(scale, 1e-9)) + 0.3), 0, n_levels - 1))


def poly_area(pix: np.ndarray) -> float:
    x, y = pix[:, 0], pix[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1))))


def warp(
    tex_pyr, o, u, v, K, R, t, roi, pix, alpha: bool, area: float | None = None
) -> np.ndarray:
    Wt, Ht = tex_pyr[0].shape[1], tex_pyr[0].shape[0]
    Hm = texel_homography(o, u, v, Wt, Ht, K, R, t)
    if len(pix) == 4:  # unclipped: the mean texel footprint of the whole quad
        area = poly_area(pix) if area is None else area
        ratio = np.sqrt(Wt * Ht / max(area, 1e-6))
        level = int(np.clip(np.floor(np.log2(max(ratio, 1e-9)) + 0.3), 0, len(tex_pyr) - 1))
    else:
        level = choose_level(Hm, pix.mean(0), len(tex_pyr))
    x0, y0, x1, y1 = roi
    M = np.array([[1, 0, -x0], [0, 1, -y0], [0, 0, 1.0]]) @ Hm @ level_matrix(level)
    return cv2.warpPerspective(
        tex_pyr[level],
        M,
        (x1 - x0, y1 - y0),
        flags=cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT if alpha else cv2.BORDER_REPLICATE,
    )
