"""The sky a camera sees and window glass mirrors: its colour by sun and weather, clouds.

Moved out of ``render`` (one idea per module): the sky's radiance for view directions
(``sky_radiance``: the conditions' horizon-to-zenith gradient, the sun's glow and disc on
clear days, clouds lit by the sun, the sky and, at night, the city), the cloud field whose
shadows the renderer also casts (``cloud_density``), and window panes mirroring that sky
(``reflect_sky_in_glass``).
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

from rp_jax.sources.synthetic import conditions as condlib
from rp_jax.sources.synthetic import textures as tx
from rp_jax.sources.synthetic.quads import Material, QuadSet

__all__ = ["CLOUD_ALTITUDE", "GLASS_F0", "cloud_density", "cloud_texture",
           "reflect_sky_in_glass", "sky_radiance"]

CLOUD_ALTITUDE = 1500.0
_CLOUD_M_PER_TEXEL = 12.0
GLASS_F0 = 0.04  # normal-incidence reflectance of glass, ((n - 1) / (n + 1))^2 with n = 1.5


@functools.lru_cache(maxsize=8)
def cloud_texture(seed: int) -> np.ndarray:
    """A 512x512 cloud field with a uniform value distribution (rank-normalised noise)."""
    rng = np.random.default_rng([seed, 31])
    n = tx.value_noise((512, 512), rng, cell=96, octaves=6)
    ranks = np.argsort(np.argsort(n.ravel())).reshape(n.shape)
    return (ranks / ranks.size).astype(np.float32)


def cloud_density(scene_seed: int, qx: np.ndarray, qy: np.ndarray, cover: float) -> np.ndarray:
    tex = cloud_texture(scene_seed)
    period = 2 * 512
    mx = np.mod(qx / _CLOUD_M_PER_TEXEL, period)
    my = np.mod(qy / _CLOUD_M_PER_TEXEL, period)
    mx = (511.0 - np.abs(mx - 511.0)).astype(np.float32)  # mirror-fold: seamless tiling
    my = (511.0 - np.abs(my - 511.0)).astype(np.float32)
    shape = mx.shape
    flat = mx.size
    pad = (-flat) % 1024  # remap wants 2-D maps under 32767 rows
    mx = np.pad(mx.ravel(), (0, pad)).reshape(-1, 1024)
    my = np.pad(my.ravel(), (0, pad)).reshape(-1, 1024)
    val = (
        cv2.remap(tex, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
        .ravel()[:flat]
        .reshape(shape)
    )
    return np.clip((val - (1.0 - cover)) / 0.12, 0.0, 1.0)


def sky_radiance(
    cond: condlib.Conditions, dirs: np.ndarray, C: np.ndarray, scene_seed: int
) -> np.ndarray:
    """Sky radiance (N, 3) for unit view directions (N, 3)."""
    dz = dirs[:, 2]
    up = np.clip(dz, 0.0, 1.0)[:, None]
    sky = cond.horizon_rgb + (cond.zenith_rgb - cond.horizon_rgb) * np.sqrt(up)
    sky = np.where(dz[:, None] < 0, cond.horizon_rgb * 0.8, sky)
    cosang = dirs @ cond.sun_dir
    vis = np.clip(cond.sun_elevation_deg + 4.0, 0.0, 4.0) / 4.0
    if cond.weather in ("clear", "partly_cloudy"):
        glow = 0.35 * np.exp((cosang - 1.0) * 10.0) + 6.0 * np.exp((cosang - 1.0) * 3000.0)
        sky = sky + vis * glow[:, None] * (cond.sun_rgb + 0.05)
    if cond.cloud_cover > 0.02:
        s = np.where(dz > 0.02, (CLOUD_ALTITUDE - C[2]) / np.maximum(dz, 0.02), 0.0)
        qx = C[0] + dirs[:, 0] * s + cond.cloud_offset[0]
        qy = C[1] + dirs[:, 1] * s + cond.cloud_offset[1]
        dens = cloud_density(scene_seed, qx, qy, cond.cloud_cover)
        dens = dens * np.clip(dz / 0.08, 0.0, 1.0)
        # (the last term: the city's lights on the cloud base at night)
        glow = np.float32([0.003, 0.002, 0.001])
        if cond.night_glow != 1.0:
            glow = glow * np.float32(cond.night_glow)
        lit = cond.sun_rgb * 0.55 + cond.sky_rgb * 1.6 + glow
        under = lit * (0.55 if cond.cloud_cover < 0.8 else 0.9)
        cloud_col = under[None, :] + (lit - under)[None, :] * np.clip(cosang, 0, 1)[:, None] ** 4
        sky = sky * (1 - dens[:, None]) + cloud_col * dens[:, None]
    return sky.astype(np.float32)


def reflect_sky_in_glass(
    rad: np.ndarray,
    gbuf,
    quads: QuadSet,
    qfull: np.ndarray,
    Kc_inv: np.ndarray,
    R: np.ndarray,
    C: np.ndarray,
    cond: condlib.Conditions,
    scene_seed: int,
) -> None:
    """Window glass mirrors the sky it faces, in place on ``rad`` (H, W, 3) radiance.

    A window pane is a dielectric mirror: it reflects the fraction F of the radiance coming
    from the mirrored view direction and transmits the rest (the room behind, the glass
    texture). F follows Fresnel's equations in Schlick's approximation for glass (refractive
    index 1.5: F0 = ((1.5 - 1) / (1.5 + 1))^2 = 0.04, F = F0 + (1 - F0)(1 - cos)^5). What
    the pane mirrors is the sky model of ``sky_radiance`` (its clouds and the sun's disc: a glint
    when the sun stands in the mirrored direction) or, below the horizon, the street's dim
    horizon colour. Glass is the facade's texels marked as glass (aux >= 128).
    """
    # Glass texels carry aux >= 128; only those few subsamples need their quad's material.
    cand = np.flatnonzero(gbuf.albedo[..., 3].ravel() >= 128)
    if len(cand) == 0:
        return
    is_glass = np.append(quads.material, -1)[gbuf.qid.ravel()[cand]] == Material.FACADE
    glass_ss = np.zeros(gbuf.qid.size, bool)
    glass_ss[cand[is_glass]] = True
    glass_ss = glass_ss.reshape(gbuf.qid.shape)
    if not is_glass.any():
        return
    Hc, Wc = rad.shape[:2]
    glass = cv2.resize(glass_ss.astype(np.float32), (Wc, Hc), interpolation=cv2.INTER_AREA)
    ys, xs = np.nonzero((glass > 0) & (qfull < quads.n))
    if len(ys) == 0:
        return
    pix = np.stack([xs, ys, np.ones_like(xs)], -1).astype(np.float64)
    d = pix @ (Kc_inv.T @ R)  # world view directions
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    n = quads.normal[qfull[ys, xs]]
    cos = np.clip(-(d * n).sum(1), 0.0, 1.0)
    fresnel = GLASS_F0 + (1.0 - GLASS_F0) * (1.0 - cos) ** 5
    mirrored = d + 2.0 * cos[:, None] * n
    mirrored /= np.linalg.norm(mirrored, axis=1, keepdims=True)
    sky = sky_radiance(cond, mirrored, C, scene_seed)
    w = (fresnel * glass[ys, xs]).astype(np.float32)[:, None]
    rad[ys, xs] = rad[ys, xs] * (1.0 - w) + w * sky
