"""Cast shadows of the synthetic world: occluders projected along the sun direction onto
each receiving plane (box silhouettes with ``cv2.fillPoly``, tree and people cut-outs as
textured quads), then drawn through the receiving plane's homography (``plane_warp``); and
whether the ray from a point towards the sun hits a building (``object_shadow``).
"""

from __future__ import annotations

import cv2
import numpy as np

from rp_jax.sources.synthetic.plane_warp import poly_region, warp
from rp_jax.sources.synthetic.quads import QuadSet, TextureState
from rp_jax.sources.synthetic.scene import Scene

__all__ = ["box_corners", "cast_shadows", "object_shadow"]


def box_corners(boxes: np.ndarray) -> np.ndarray:
    lo, hi = boxes[:, 0], boxes[:, 1]
    sel = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
    return np.where(sel[None, :, :] == 0, lo[:, None, :], hi[:, None, :])


def object_shadow(points: np.ndarray, sun: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """1 where the ray from a point towards the sun hits a box (slab test), else 0."""
    if len(boxes) == 0 or len(points) == 0:
        return np.zeros(len(points), np.float32)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / np.where(np.abs(sun) < 1e-12, 1e-12, sun)
        t0 = (boxes[None, :, 0, :] - points[:, None, :]) * inv
        t1 = (boxes[None, :, 1, :] - points[:, None, :]) * inv
    tmin = np.minimum(t0, t1).max(-1)
    tmax = np.maximum(t0, t1).min(-1)
    hit = tmax >= np.maximum(tmin, 1e-3)
    return hit.any(1).astype(np.float32)


def cast_shadows(
    gbuf,
    qid: np.ndarray,
    quads: QuadSet,
    scene: Scene,
    state: TextureState,
    sun: np.ndarray,
    boxes: np.ndarray,
    alpha_idx: np.ndarray,
    K,
    R,
    t,
    W: int,
    H: int,
) -> np.ndarray:
    """uint8 (H, W) = 1 where a receiving plane's pixel lies in a cast shadow.

    ``gbuf`` is the frame's G-buffer (``render``: which quads were drawn, each one's pixel
    ROI); ``qid`` is ``gbuf.qid`` (int32, the quad seen at each pixel).
    """
    shadow = np.zeros((H, W), np.uint8)
    drawn_recv = np.flatnonzero(gbuf.drawn & (quads.receiver >= 0))
    if len(drawn_recv) == 0 or sun[2] <= 0.01:
        return shadow
    planes = np.unique(quads.receiver[drawn_recv])
    corners8 = box_corners(boxes) if len(boxes) else np.zeros((0, 8, 3))
    nrm_all = quads.normal
    alpha_idx = np.asarray(alpha_idx, np.int64)
    # Three corners (origin, origin + u, origin + v) of every cut-out caster.
    a_o = quads.origin[alpha_idx]
    a_oc = np.stack([a_o, a_o + quads.u[alpha_idx], a_o + quads.v[alpha_idx]], 1)  # (A, 3, 3)
    in_plane = np.zeros(quads.n + 1, np.uint8)
    for p in planes:
        members = drawn_recv[quads.receiver[drawn_recv] == p]
        q0 = members[0]
        n = nrm_all[q0]
        ns = float(n @ sun)
        if ns <= 0.02:
            continue  # the plane faces away from the sun: Lambert already darkens it
        d = float(n @ quads.origin[q0])
        rx0 = min(gbuf.roi[i][0] for i in members)
        ry0 = min(gbuf.roi[i][1] for i in members)
        rx1 = max(gbuf.roi[i][2] for i in members)
        ry1 = max(gbuf.roi[i][3] for i in members)
        # Receiver extent in plane coordinates (for culling occluders).
        e1 = quads.u[q0] / np.linalg.norm(quads.u[q0])
        e2 = np.cross(n, e1)
        mo, mu, mv = quads.origin[members], quads.u[members], quads.v[members]
        mc = np.concatenate([mo, mo + mu, mo + mv, mo + mu + mv])
        ext = np.stack([mc @ e1, mc @ e2], 1)
        elo, ehi = ext.min(0) - 0.1, ext.max(0) + 0.1
        tmp = np.zeros((ry1 - ry0, rx1 - rx0), np.uint8)
        Kroi = np.array([[1, 0, -rx0], [0, 1, -ry0], [0, 0, 1.0]]) @ K
        if len(corners8):
            lam = (corners8 @ n - d) / ns  # (B, 8)
            ok = np.all(lam >= -1e-6, 1) & np.any(lam > 1e-3, 1)
            proj = corners8 - lam[..., None] * sun
            c2 = np.stack([proj @ e1, proj @ e2], -1)  # (B, 8, 2)
            ok &= np.all(c2.max(1) >= elo, 1) & np.all(c2.min(1) <= ehi, 1)
            for b in np.flatnonzero(ok):
                hull = cv2.convexHull(c2[b].astype(np.float32)).reshape(-1, 2).astype(np.float64)
                poly = n * d + hull[:, :1] * e1 + hull[:, 1:2] * e2
                reg = poly_region(poly @ R.T + t, Kroi, rx1 - rx0, ry1 - ry0)
                if reg is not None:
                    (x0, y0, x1, y1), mask, _ = reg
                    cv2.bitwise_or(tmp[y0:y1, x0:x1], mask, dst=tmp[y0:y1, x0:x1])
        if len(alpha_idx):
            lam = (a_oc @ n - d) / ns  # (A, 3)
            pr = a_oc - lam[..., None] * sun  # projected origin, origin + u, origin + v
            # (A, 4, 3)
            quad = np.stack([pr[:, 0], pr[:, 1], pr[:, 1] + pr[:, 2] - pr[:, 0], pr[:, 2]], 1)
            q2 = np.stack([quad @ e1, quad @ e2], -1)  # (A, 4, 2)
            ok = np.all(lam >= -1e-6, 1) & np.all(q2.max(1) >= elo, 1) & np.all(q2.min(1) <= ehi, 1)
            for k in np.flatnonzero(ok):
                reg = poly_region(quad[k] @ R.T + t, Kroi, rx1 - rx0, ry1 - ry0)
                if reg is None:
                    continue
                roi, mask, pix = reg
                o2 = pr[k, 0]
                pyr = scene.textures.pyramid(quads.tex[alpha_idx[k]], state)
                warped = warp(
                    pyr, o2, pr[k, 1] - o2, pr[k, 2] - o2, Kroi, R, t, roi, pix, alpha=True
                )
                x0, y0, x1, y1 = roi
                tmp[y0:y1, x0:x1] |= mask & np.greater(warped[..., 3], 127).view(np.uint8)
        lo, hi = int(members.min()), int(members.max())
        if (
            hi - lo + 1 == len(members) and min(tmp.shape) > 1
        ):  # a contiguous id range (ground, walls)
            sel = cv2.inRange(qid[ry0:ry1, rx0:rx1], lo, hi) & 1
        else:
            in_plane[:] = 0
            in_plane[members] = 1
            sel = np.take(in_plane, qid[ry0:ry1, rx0:rx1].astype(np.intp))
        cv2.bitwise_and(tmp, sel, dst=tmp)  # mask values 255 & 1 -> 1
        cv2.bitwise_or(shadow[ry0:ry1, rx0:rx1], tmp, dst=shadow[ry0:ry1, rx0:rx1])
    return shadow
