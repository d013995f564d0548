"""Renderer of the synthetic world: pinhole/OpenCV cameras, sun, shadows, weather, sensor.

Stand-in for the photographs of Sec. IV-A: every downstream stage (SIFT ground truth of
Sec. III-C, training, the localization of Sec. IV-C) runs on these pixels. The renderer is
exact in geometry so that triangulation and PnP work as on real data: a quad's texture is
mapped to the image by its plane homography (``cv2.warpPerspective``), depth comes from the
plane equation (1/z is affine in pixel coordinates), and the image is rendered at 2x and
box-downsampled. Cast shadows are exact too: occluders are projected along the sun
direction onto each receiving plane (box silhouettes with ``cv2.fillPoly``, tree and people
cut-outs as textured quads), then drawn through the receiving plane's homography.

Speed (about 0.08-0.1 s of CPU per 640x480 frame on one core): quads are rasterised front
to back so that each texture is warped only over its still-visible pixels; masked writes,
lookups and tone mapping run as single OpenCV passes; the per-pixel lighting comes from one
gather of a per-quad table; soft cloud shadows are traced at half resolution.

Conventions: ``View`` follows ``rp_jax.sources.capture`` (OpenCV pixels with the centre of
the top-left pixel at (0, 0), ``x_cam = R X + t``, camera looking along +z). A non-zero
``distortion`` renders the image the lens records (undistorted render, then ``cv2.remap``).

This module is one frame's pipeline (rasterisation and the frame's assembly); what stands
alone lives apart: the plane geometry and texture warps (``plane_warp``), cast shadows
(``shadows``), ``conditions``, ``photometry``, ``sky``, ``camera_effects``, ``scene``,
``quads``, ``traffic`` and the textures.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import functools

import cv2
import numpy as np

from rp_jax import categories
from rp_jax.sources.synthetic import (
    camera_effects,
    household_lighting,
    night_lights,
    photometry,
    sky,
    traffic,
)
from rp_jax.sources.synthetic import conditions as condlib
from rp_jax.sources.synthetic.plane_warp import NEAR, poly_region, warp
from rp_jax.sources.synthetic.quads import Material, QuadSet, TextureState
from rp_jax.sources.synthetic.scene import Scene
from rp_jax.sources.synthetic.shadows import cast_shadows, object_shadow
from rp_jax.sources.synthetic.traffic import dynamic_quads

__all__ = ["View", "Frame", "render", "project", "look_at"]

SS = 2  # supersampling factor
# Leaves move in the wind: each frame displaces a crown's texels by a smooth random field
# (std: calm sway + per m/s of the day's wind; correlation length: a leaf cluster), so
# foliage never looks the same in two frames, as on a real webcam. Beaufort 4 (about
# 7 m/s, "small branches move") gives about 5 cm.
FOLIAGE_SWAY_M = (0.02, 0.004)
FOLIAGE_CLUSTER_M = 0.35
# Street-lamp intensity of the default lighting: about 6e-3 under a lamp, 1/150 of the noon
# sun (``photometry.LEGACY``; ``photometry.EN_13201`` states lamps in candelas).
LAMP_POWER = photometry.LEGACY.lamp_power


@dataclasses.dataclass(frozen=True)
class View:
    """A camera: intrinsics, world-to-camera pose, image size, OpenCV distortion."""

    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    width: int
    height: int
    distortion: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(4))

    def __post_init__(self):
        object.__setattr__(self, "K", np.asarray(self.K, np.float64).reshape(3, 3))
        object.__setattr__(self, "R", np.asarray(self.R, np.float64).reshape(3, 3))
        object.__setattr__(self, "t", np.asarray(self.t, np.float64).reshape(3))
        d = np.zeros(4)
        dist = np.asarray(self.distortion, np.float64).ravel()
        if dist.size not in (0, 4):
            raise ValueError(f"View.distortion must hold (k1, k2, p1, p2), got {dist}")
        d[: dist.size] = dist
        object.__setattr__(self, "distortion", d)

    @property
    def center(self) -> np.ndarray:
        """Camera centre in world coordinates."""
        return -self.R.T @ self.t


@dataclasses.dataclass
class Frame:
    """One rendered capture.

    Attributes:
      rgb: uint8 (H, W, 3), RGB order.
      depth: float32 (H, W), z along the optical axis in metres, ``np.inf`` for sky.
      category: uint8 (H, W), ids of ``rp_jax.categories``.
      meta: sun angles, weather, snow, foliage, gain...
    """

    rgb: np.ndarray
    depth: np.ndarray
    category: np.ndarray
    meta: dict


def look_at(
    eye,
    target,
    *,
    width: int = 640,
    height: int = 480,
    fov_deg: float = 60.0,
    up=(0.0, 0.0, 1.0),
    distortion=None,
) -> View:
    """A level-ish pinhole view from ``eye`` looking at ``target`` (world frame).

    Args:
      eye, target: world points.
      width, height: image size.
      fov_deg: horizontal field of view.
      up: world up direction.
      distortion: optional (k1, k2, p1, p2).

    Returns:
      ``View``.
    """
    eye, target, up = (np.asarray(a, np.float64) for a in (eye, target, up))
    z = target - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    f = 0.5 * width / np.tan(np.radians(fov_deg) / 2)
    K = np.array([[f, 0, (width - 1) / 2], [0, f, (height - 1) / 2], [0, 0, 1.0]])
    return View(K, R, -R @ eye, width, height, np.zeros(4) if distortion is None else distortion)


def project(view: View, X: np.ndarray) -> np.ndarray:
    """World points to pixels of the recorded (distorted) image.

    Args:
      view: the camera.
      X: (N, 3) world points.

    Returns:
      (N, 2) pixel coordinates (points behind the camera give meaningless values).
    """
    Xc = np.asarray(X, np.float64) @ view.R.T + view.t
    x, y = Xc[:, 0] / Xc[:, 2], Xc[:, 1] / Xc[:, 2]
    k1, k2, p1, p2 = view.distortion
    if np.any(view.distortion):
        r2 = x * x + y * y
        radial = 1 + k1 * r2 + k2 * r2 * r2
        x, y = (
            x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
            y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y,
        )
    K = view.K
    return np.stack([K[0, 0] * x + K[0, 1] * y + K[0, 2], K[1, 1] * y + K[1, 2]], -1)


# ---------------------------------------------------------------- rasterisation


@dataclasses.dataclass
class _GBuffer:
    albedo: np.ndarray  # (H, W, 4) uint8 (RGB + aux)
    invz: np.ndarray  # (H, W) float32
    qid: np.ndarray  # (H, W) int32, N for sky
    plane: np.ndarray  # (N, 3) n_c / d_c per quad (1/z = plane . K^-1 [u, v, 1])
    drawn: np.ndarray  # (N,) bool
    roi: dict  # quad -> roi


_STRIP_ROWS = 48


def _visible_strips(m: np.ndarray) -> list[tuple[int, int, int, int]]:
    """Rectangles (x, y, w, h) covering the nonzero pixels of a mask, one per band of rows.

    A large quad seen partly behind others (a ground tile behind parked cars) is textured
    over these tighter rectangles instead of its whole bounding box.
    """
    h, w = m.shape
    if h <= 2 * _STRIP_ROWS or h * w < 40_000:
        return [(0, 0, w, h)]
    rects = []
    for r0 in range(0, h, _STRIP_ROWS):
        rx, ry, rw, rh = cv2.boundingRect(m[r0 : r0 + _STRIP_ROWS])
        if rw and rh:
            rects.append((rx, r0 + ry, rw, rh))
    return rects


def _flutter(
    warped: np.ndarray, amp_px: float, step_px: float, rng: np.random.Generator
) -> np.ndarray:
    """``warped`` (RGBA) resampled through a smooth random displacement of std ``amp_px``
    pixels, correlated over ``step_px`` pixels (bicubic upsampling of a coarse normal grid)."""
    h, w = warped.shape[:2]
    if amp_px < 0.2 or h < 2 or w < 2:
        return warped
    step = max(step_px, 2.0)
    gh, gw = int(np.ceil(h / step)) + 2, int(np.ceil(w / step)) + 2
    grid = rng.normal(0.0, amp_px, (gh, gw, 2)).astype(np.float32)
    field = cv2.resize(grid, (int(gw * step), int(gh * step)), interpolation=cv2.INTER_CUBIC)[
        :h, :w
    ]
    xs, ys = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    return cv2.remap(
        warped,
        xs + field[..., 0],
        ys + field[..., 1],
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
    )


def _rasterize(
    quads: QuadSet,
    scene: Scene,
    state: TextureState,
    K,
    R,
    t,
    W: int,
    H: int,
    flutter: tuple[int, float] | None = None,
) -> _GBuffer:
    """Z-buffered rasterisation of textured quads, front to back.

    Quads are drawn nearest first, so the depth test runs before texturing and a quad's
    texture is warped only over the bounding box of its still-visible pixels (fully hidden
    quads cost a polygon fill and a compare). Masked writes use ``cv2.copyTo``.
    ``flutter`` = (frame key, sway in metres) moves foliage texels (see ``FOLIAGE_SWAY_M``).
    """
    N = quads.n
    C = -R.T @ t
    o, u, v = quads.origin, quads.u, quads.v
    corners = np.stack([o, o + u, o + u + v, o + v], 1)
    cam = corners @ R.T + t
    nrm = quads.normal
    two_sided = (quads.material == Material.FOLIAGE) | (quads.material == Material.CUTOUT)
    facing = np.einsum("ij,ij->i", nrm, C - o) > 1e-6
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    zc = cam[..., 2]
    xc, yc = cam[..., 0], cam[..., 1]
    out = (
        np.all(zc < NEAR, 1)
        | np.all(xc < zc * (-0.5 - cx) / fx, 1)
        | np.all(xc > zc * (W - 0.5 - cx) / fx, 1)
        | np.all(yc < zc * (-0.5 - cy) / fy, 1)
        | np.all(yc > zc * (H - 0.5 - cy) / fy, 1)
        | np.all(zc > 400.0, 1)
    )
    visible = np.flatnonzero(~out & (facing | two_sided))
    visible = visible[
        np.argsort(np.maximum(zc[visible].min(1), NEAR), kind="stable")
    ]  # front to back
    # Plane of each quad in camera space: (R n) . X_c = n . o + (R n) . t.
    n_c = nrm @ R.T
    d_c = np.einsum("ij,ij->i", nrm, o) + n_c @ t
    with np.errstate(divide="ignore", invalid="ignore"):
        plane = np.where(np.abs(d_c)[:, None] > 1e-9, n_c / d_c[:, None], 0.0)
    Kinv = np.linalg.inv(K)
    coef = (plane @ Kinv).astype(np.float32)  # 1/z = coef . [u, v, 1]
    # Projection, bounding box, fill points and area of every quad at once (near-clipped
    # quads go through ``poly_region``).
    needs_clip = np.any(zc[visible] < NEAR, 1)
    pc = cam[visible] @ K.T
    with np.errstate(divide="ignore", invalid="ignore"):
        pix_all = pc[..., :2] / pc[..., 2:3]  # (V, 4, 2)
        lo_all = np.floor(pix_all.min(1))
        hi_all = np.ceil(pix_all.max(1)) + 1
    lo_all = np.where(needs_clip[:, None], 0, lo_all)
    hi_all = np.where(needs_clip[:, None], 1, hi_all)
    box_all = np.concatenate([np.maximum(lo_all, 0), np.minimum(hi_all, [W, H])], 1).astype(int)
    pts_all = np.round((pix_all - box_all[:, None, :2]) * 16.0)
    pts_all = np.where(needs_clip[:, None, None], 0, pts_all).astype(np.int32)
    px, py = pix_all[..., 0], pix_all[..., 1]
    with np.errstate(invalid="ignore"):  # (near-clipped quads: unused values)
        area_all = 0.5 * np.abs(np.sum(px * np.roll(py, 1, 1) - py * np.roll(px, 1, 1), 1))
    zb = np.zeros((H, W), np.float32)
    gb = np.zeros((H, W, 4), np.uint8)
    qid = np.full((H, W), N, np.int32)
    xs = np.arange(W, dtype=np.float32)
    ys = np.arange(H, dtype=np.float32)
    drawn = np.zeros(N, bool)
    rois = {}
    for j, i in enumerate(visible):
        if abs(d_c[i]) < 1e-6:
            continue
        if needs_clip[j]:
            reg = poly_region(cam[i], K, W, H)
            if reg is None:
                continue
            (x0, y0, x1, y1), mask, pix = reg
        else:
            x0, y0, x1, y1 = box_all[j]
            if x1 <= x0 or y1 <= y0:
                continue
            pix = pix_all[j]
            mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
            cv2.fillPoly(mask, [pts_all[j]], 255, lineType=cv2.LINE_8, shift=4)
        a, b, c = coef[i]
        iz = (a * xs[x0:x1])[None, :] + (b * ys[y0:y1] + c)[:, None]
        m = cv2.compare(iz, zb[y0:y1, x0:x1], cv2.CMP_GT)
        cv2.bitwise_and(m, mask, dst=m)
        bx, by, bw, bh = cv2.boundingRect(m)
        if bw == 0 or bh == 0:
            continue  # hidden behind nearer quads
        m, iz = m[by : by + bh, bx : bx + bw], iz[by : by + bh, bx : bx + bw]
        x0, y0 = x0 + bx, y0 + by
        alpha = bool(two_sided[i])
        pyr = scene.textures.pyramid(quads.tex[i], state)
        area = None if needs_clip[j] else area_all[j]
        # Moving leaves are warped over the whole box at once: a displacement field
        # continuous across strips.
        moving = flutter is not None and quads.material[i] == Material.FOLIAGE
        for rx, ry, rw, rh in [(0, 0, bw, bh)] if moving else _visible_strips(m):
            sm, siz = m[ry : ry + rh, rx : rx + rw], iz[ry : ry + rh, rx : rx + rw]
            sx0, sy0 = x0 + rx, y0 + ry
            warped = warp(
                pyr, o[i], u[i], v[i], K, R, t, (sx0, sy0, sx0 + rw, sy0 + rh), pix, alpha, area
            )
            if moving:
                z = max(float(zc[i].mean()), NEAR)
                rng = np.random.default_rng((scene.seed, int(i), flutter[0]))
                warped = _flutter(
                    warped, flutter[1] * K[0, 0] / z, FOLIAGE_CLUSTER_M * K[0, 0] / z, rng
                )
            if alpha:
                # (numpy: cv2 reads tiny arrays as scalars)
                sm = sm & np.greater(warped[..., 3], 127).view(np.uint8)
            cv2.copyTo(siz, sm, zb[sy0 : sy0 + rh, sx0 : sx0 + rw])
            cv2.copyTo(warped, sm, gb[sy0 : sy0 + rh, sx0 : sx0 + rw])
            cv2.copyTo(np.full((rh, rw), i, np.int32), sm, qid[sy0 : sy0 + rh, sx0 : sx0 + rw])
        drawn[i] = True
        rois[i] = (x0, y0, x0 + bw, y0 + bh)
    return _GBuffer(gb, zb, qid, plane, drawn, rois)


# ---------------------------------------------------------------- distortion canvas


@functools.lru_cache(maxsize=16)
def _canvas(kbytes: bytes, dbytes: bytes, width: int, height: int):
    K = np.frombuffer(kbytes).reshape(3, 3)
    dist = np.frombuffer(dbytes)
    u, v = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    # Invert the OpenCV distortion by fixed-point iteration (as cv2.undistortPoints does).
    xd = (u - K[0, 2] - K[0, 1] * (v - K[1, 2]) / K[1, 1]) / K[0, 0]
    yd = (v - K[1, 2]) / K[1, 1]
    k1, k2, p1, p2 = dist[:4]
    x, y = xd.copy(), yd.copy()
    for _ in range(60):
        r2 = x * x + y * y
        radial = 1 + k1 * r2 + k2 * r2 * r2
        x = (xd - (2 * p1 * x * y + p2 * (r2 + 2 * x * x))) / radial
        y = (yd - (p1 * (r2 + 2 * y * y) + 2 * p2 * x * y)) / radial
    und = np.stack([K[0, 0] * x + K[0, 1] * y + K[0, 2], K[1, 1] * y + K[1, 2]], -1)
    ox = int(np.floor(und[..., 0].min())) - 2
    oy = int(np.floor(und[..., 1].min())) - 2
    wc = int(np.ceil(und[..., 0].max())) - ox + 3
    hc = int(np.ceil(und[..., 1].max())) - oy + 3
    Kc = K.copy()
    Kc[0, 2] -= ox
    Kc[1, 2] -= oy
    mx = (und[..., 0] - ox).astype(np.float32)
    my = (und[..., 1] - oy).astype(np.float32)
    return Kc, wc, hc, mx, my


# ---------------------------------------------------------------- the frame


def _world_points(Kc_inv: np.ndarray, R: np.ndarray, t: np.ndarray, depth: np.ndarray, step: int):
    """World points (H', W', 3) float32 seen at every ``step``-th pixel, and where they are
    finite."""
    d = depth[::step, ::step]
    uu = np.arange(0, depth.shape[1], step, dtype=np.float32)[None, :]
    vv = np.arange(0, depth.shape[0], step, dtype=np.float32)[:, None]
    rays = np.stack(np.broadcast_arrays(uu, vv, np.ones_like(uu)), -1) @ Kc_inv.T.astype(np.float32)
    finite = np.isfinite(d)
    Xc = rays * np.where(finite, d, 0.0)[..., None]
    return (Xc - t.astype(np.float32)) @ R.astype(np.float32), finite  # R^T (X_c - t)


def _plane_depth(coef: np.ndarray, q: np.ndarray, u: np.ndarray, v: np.ndarray,
                 background: int) -> np.ndarray:
    """Depth at pixels (u, v) seen on quads ``q``: 1/z is affine in the pixel on a plane
    (row ``coef[q]``); inf where no quad (``q == background``) is seen."""
    iz = np.take(coef[:, 0], q) * u + np.take(coef[:, 1], q) * v + np.take(coef[:, 2], q)
    with np.errstate(divide="ignore"):
        return np.where(q == background, np.inf, 1.0 / np.maximum(iz, 1e-12)).astype(np.float32)


def _srgb_to_linear_lut() -> np.ndarray:
    x = np.arange(256) / 255.0
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4).astype(np.float32)


_LIN = _srgb_to_linear_lut()


def _window_threshold(
    n_owners: int, scene_seed: int, day: int, hour: float, prob: float
) -> np.ndarray:
    """Per building, the aux value at or above which a window is lit (see ``textures._window``)."""
    rng = np.random.default_rng([scene_seed, 41, day, int(hour * 2)])
    p = np.clip(prob * rng.uniform(0.6, 1.4, n_owners), 0.0, 1.0)
    return (255.0 - 127.0 * p).astype(np.float32)


def _lit_window_share(scene: Scene, when: dt.datetime, cond: condlib.Conditions,
                      lighting: photometry.StreetLighting, clock: dt.tzinfo | None) -> float:
    """The share of the street's windows lit at ``when``: the household lighting profile on
    the place's clock where the lighting follows it, else the conditions' step function."""
    if not lighting.household_profile:
        return cond.window_lit_prob
    local = when if clock is None else when.astimezone(clock)
    return household_lighting.lit_window_share(local, scene.latitude, scene.longitude)


def _vehicle_lights(scene: Scene, when: dt.datetime, vehicle, C: np.ndarray,
                    lighting: photometry.StreetLighting) -> tuple[np.ndarray, np.ndarray]:
    """The headlamps lighting the street near the camera at ``when`` (positions, forwards):
    the passing cars' and the camera's own car's, none without ``lighting.vehicle_lights``."""
    if not lighting.vehicle_lights:
        return np.zeros((0, 3)), np.zeros((0, 3))
    pos, fwd = traffic.headlamps(traffic.passing_cars(scene, when))
    if vehicle is not None:
        own_pos, own_fwd = traffic.car_headlamps(*vehicle, traffic.OWN_CAR_LENGTH_M,
                                                 traffic.OWN_CAR_WIDTH_M)
        pos, fwd = np.concatenate([pos, own_pos]), np.concatenate([fwd, own_fwd])
    keep = np.linalg.norm(pos - C, axis=1) < night_lights.REACH_M
    return pos[keep], fwd[keep]


def _night_lights_on(X: list, Nk: list, finite: np.ndarray, qfull: np.ndarray, mat: np.ndarray,
                     C: np.ndarray, lamps: np.ndarray, headlamps: tuple,
                     lighting: photometry.StreetLighting, light: np.ndarray, *,
                     wet: bool) -> np.ndarray | None:
    """Adds the headlamps' light to ``light`` (in place) and returns the wet road's gloss
    (H, W, 3; None where the road is dry or the lighting has none), ``night_lights``; ``X``
    and ``Nk``: each pixel's surface point and normal, three arrays each."""
    pos, fwd = headlamps
    if len(pos):
        E = night_lights.headlamp_illuminance(X, Nk, pos, fwd)
        light += (E / np.float32(photometry.LUX_PER_UNIT) * finite)[..., None] * np.float32(
            photometry.HEADLAMP_RGB)
    if not (wet and lighting.wet_reflections) or not (len(lamps) or len(pos)):
        return None
    road = (np.take(np.append(mat, -1), qfull) == Material.GROUND) & finite.astype(bool)
    gloss = np.zeros(road.shape + (3,), np.float32)
    gloss[road] = night_lights.wet_road_radiance(
        [c[road] for c in X], [c[road] for c in Nk], C, lamps, lighting.lamp_intensity_cd,
        lighting.lamp_rgb, pos, fwd)
    return gloss


def render(
    scene: Scene,
    view: View,
    when: dt.datetime,
    *,
    seed: int = 0,
    weather: str | None = None,
    lighting: photometry.StreetLighting = photometry.LEGACY,
    sensor: camera_effects.Sensor = camera_effects.WEBCAM,
    velocity: np.ndarray | None = None,
    vehicle: tuple[float, float, float] | None = None,
    clock: dt.tzinfo | None = None,
) -> Frame:
    """Renders the world as a camera records it at an instant.

    Args:
      scene: from ``build_scene``.
      view: the camera (a non-zero distortion gives the distorted image).
      when: timezone-aware capture instant. The sun comes from its UTC instant and the
        scene's latitude/longitude; weather from (scene seed, local date); passing cars and
        people from (scene seed, instant); a world with slow changes stands as on its
        local date (``slow_changes``).
      seed: sensor-noise seed of this frame (nothing else depends on it).
      weather: the day's sky when it is known (``conditions.conditions_at``); None draws it.
      lighting: the street's lamps, night sky and lit windows (``photometry``).
      sensor: the camera's exposure and gain range (``camera_effects``).
      velocity: the camera's velocity (world, m/s) for the motion blur of a sensor whose
        exposure is modelled; None: still. An undistorted view only.
      vehicle: the camera's own car, ``(x, y, heading)`` of its centre (heading in radians
        from +x), whose headlamps light the street where ``lighting.vehicle_lights``; None:
        the camera is not on a car.
      clock: the time zone of the place's clocks, which the people living there follow
        (the windows lit by ``household_lighting`` where ``lighting.household_profile``);
        None: ``when``'s own.

    Returns:
      ``Frame`` with rgb, depth, category and meta.
    """
    cond = condlib.conditions_at(scene.seed, scene.latitude, scene.longitude, when, weather,
                                 night_sky=lighting.night_sky, climate=scene.climate)
    state = TextureState(
        season=cond.grass,
        snow=cond.snow,
        snow_pattern=cond.snow_pattern,
        foliage=cond.foliage,
        autumn=cond.autumn,
    )
    dyn, dyn_boxes, dyn_alpha = dynamic_quads(scene, when)
    # The static world as it stands on the day (its slow changes, when it has them).
    static = scene.static if scene.slow_changes is None else scene.slow_changes.static_at(when)
    quads = QuadSet.concat([static, dyn])
    N = quads.n
    alpha_idx = np.concatenate(
        [scene.alpha_casters, static.n + np.asarray(dyn_alpha, np.int64)]
    ).astype(int)
    boxes = np.concatenate(
        [scene.buildings, scene.furniture_boxes, np.array(dyn_boxes, np.float64).reshape(-1, 2, 3)]
    )
    distorted = bool(np.any(view.distortion))
    if distorted and velocity is not None and sensor.max_exposure_s is not None:
        raise NotImplementedError("motion blur is modelled for undistorted views only")
    if distorted:
        Kc, Wc, Hc, mapx, mapy = _canvas(
            view.K.tobytes(), view.distortion.tobytes(), view.width, view.height
        )
    else:
        Kc, Wc, Hc = view.K, view.width, view.height
    R, t = view.R, view.t
    C = -R.T @ t
    S = np.array([[SS, 0, (SS - 1) / 2], [0, SS, (SS - 1) / 2], [0, 0, 1.0]])
    Kss = S @ Kc
    W2, H2 = Wc * SS, Hc * SS
    sway = FOLIAGE_SWAY_M[0] + FOLIAGE_SWAY_M[1] * cond.wind_speed
    gbuf = _rasterize(quads, scene, state, Kss, R, t, W2, H2, flutter=(int(when.timestamp()), sway))
    sun = cond.sun_dir
    nrm = quads.normal
    mat = quads.material
    # Per-quad light coefficients (last entry: sky).
    ndl = np.clip(nrm @ sun, 0.0, None)
    foliage = (mat == Material.FOLIAGE) | (mat == Material.CUTOUT)
    ndl = np.where(foliage, 0.55, ndl)
    obj = quads.receiver < 0
    if sun[2] > 0:
        occl = object_shadow(quads.shadow_pt[obj], sun, scene.buildings)
        ndl[obj] *= 1.0 - occl
    amb = np.where(foliage, 0.75, 0.55 + 0.45 * nrm[:, 2])
    wet = np.ones(N)
    if cond.wet:
        wet = np.where(mat == Material.GROUND, 0.6, np.where(mat == Material.CAR, 1.0, 0.85))
    shadow = cast_shadows(
        gbuf, gbuf.qid, quads, scene, state, sun, boxes, alpha_idx, Kss, R, t, W2, H2
    )
    # One gather gives every subsample's light (direct * sun + ambient * sky, RGB) and sky
    # flag: rows 0..N lit, rows N+1.. the same quads in a cast shadow.
    direct_q = np.append(ndl * wet, 0.0)
    amb_q = np.append(amb * wet, 0.0)
    table = np.zeros((2 * (N + 1), 4), np.float32)
    table[: N + 1, :3] = direct_q[:, None] * cond.sun_rgb + amb_q[:, None] * cond.sky_rgb
    table[N + 1 :, :3] = amb_q[:, None] * cond.sky_rgb
    table[N, 3] = table[2 * N + 1, 3] = 1.0
    idx = gbuf.qid.copy()
    cv2.add(idx, N + 1, dst=idx, mask=shadow)
    # np.take is several times faster with native indices and 16-byte elements
    idx = idx.astype(np.intp)
    terms_ss = np.take(table.view(np.complex128).ravel(), idx).view(np.float32).reshape(H2, W2, 4)
    clouds = cond.weather == "partly_cloudy" and sun[2] > 0
    if clouds:  # cloud shadows dim the direct part only: keep it apart
        direct_ss = np.take(np.concatenate([direct_q, np.zeros(N + 1)]).astype(np.float32), idx)
    del idx
    emis_ss = None
    lamp_scale = lighting.lamp_power / photometry.LEGACY.lamp_power
    if cond.lamps_on or cond.sun_elevation_deg < 8:
        qid = gbuf.qid.astype(np.intp)
        aux = gbuf.albedo[..., 3]
        mat_px = np.take(np.append(mat, -1).astype(np.int8), qid)
        emis_ss = np.zeros((H2, W2), np.float32)
        fac = mat_px == Material.FACADE
        if fac.any():
            owners = np.append(np.maximum(quads.owner, 0), 0)
            thr = _window_threshold(
                int(owners.max()) + 1,
                scene.seed,
                when.date().toordinal(),
                cond.local_hour,
                _lit_window_share(scene, when, cond, lighting, clock),
            )
            lit = fac & (aux >= np.take(thr, np.take(owners, qid)))
            emis_ss[lit] = 0.04 + 0.08 * (aux[lit] - 128) / 127.0
            window_scale = lighting.window_emission / photometry.LEGACY.window_emission
            if window_scale != 1.0:
                emis_ss[lit] *= window_scale
        if cond.lamps_on:
            lamp = mat_px == Material.LAMP
            # A lamp head's luminance follows its intensity (2.5 for the default lamps).
            emis_ss[lamp] = 2.5 * lamp_scale * aux[lamp] / 255.0
            car = (mat_px == Material.CAR) & (np.take(np.append(quads.emit, 0), qid) > 0)
            emis_ss[car] = 2.5 * aux[car] / 255.0
    # Down to the output resolution (box filter of the 2x render).
    size = (Wc, Hc)
    # 4 channels: contiguous, fast
    albedo = cv2.resize(gbuf.albedo, size, interpolation=cv2.INTER_AREA)
    albedo = cv2.cvtColor(albedo, cv2.COLOR_RGBA2RGB)
    albedo = cv2.GaussianBlur(albedo, (0, 0), 0.45)  # lens point-spread function
    alb = cv2.LUT(albedo, _LIN)  # sRGB -> linear, float32
    # (H, W, 4): light RGB, sky fraction
    terms = cv2.resize(terms_ss, size, interpolation=cv2.INTER_AREA)
    del terms_ss
    skyfrac = np.ascontiguousarray(terms[..., 3])
    light = cv2.cvtColor(terms, cv2.COLOR_RGBA2RGB)
    # Full-resolution geometry: depth from the plane of the surface seen at each pixel centre.
    qfull = gbuf.qid[SS // 2 :: SS, SS // 2 :: SS].astype(np.intp)
    Kc_inv = np.linalg.inv(Kc)
    coef = np.vstack([gbuf.plane @ Kc_inv, np.zeros((1, 3))]).astype(np.float32)
    uu = np.arange(Wc, dtype=np.float32)[None, :]
    vv = np.arange(Hc, dtype=np.float32)[:, None]
    depth = _plane_depth(coef, qfull, uu, vv, N)
    if clouds:
        # Cloud shadows are soft (blurred over ~2 px): trace them on every other pixel.
        Xh, _ = _world_points(Kc_inv, R, t, depth, 2)
        s = (sky.CLOUD_ALTITUDE - Xh[..., 2]) / max(sun[2], 0.05)
        dens = sky.cloud_density(
            scene.seed,
            Xh[..., 0] + sun[0] * s + cond.cloud_offset[0],
            Xh[..., 1] + sun[1] * s + cond.cloud_offset[1],
            cond.cloud_cover,
        )
        dens = cv2.GaussianBlur(dens.astype(np.float32), (0, 0), 1.0)
        dens = cv2.resize(dens, size, interpolation=cv2.INTER_LINEAR)
        direct = cv2.resize(direct_ss, size, interpolation=cv2.INTER_AREA)
        light -= (0.85 * dens * direct)[..., None] * cond.sun_rgb
    wet_gloss = None
    if cond.lamps_on:
        Xw, finite = _world_points(Kc_inv, R, t, depth, 1)
        near = scene.lamps[np.linalg.norm(scene.lamps - C, axis=1) < night_lights.REACH_M] if len(
            scene.lamps) else np.zeros((0, 3))
        nrm1 = np.vstack([nrm, np.zeros((1, 3))]).astype(np.float32)
        X = [np.ascontiguousarray(Xw[..., k]) for k in range(3)]
        Nk = [np.take(nrm1[:, k], qfull) for k in range(3)]
        if lighting.vehicle_lights or lighting.wet_reflections:
            wet_gloss = _night_lights_on(X, Nk, finite, qfull, mat, C, near,
                                         _vehicle_lights(scene, when, vehicle, C, lighting),
                                         lighting, light, wet=cond.wet)
        if len(scene.lamps):
            E = night_lights.lamp_geometry(X, Nk, near)
            light += (lighting.lamp_power * E * finite)[..., None] * np.float32(lighting.lamp_rgb)
    rad = cv2.multiply(alb, light)
    if wet_gloss is not None:
        rad += wet_gloss
    if emis_ss is not None:
        emis = cv2.resize(emis_ss, size, interpolation=cv2.INTER_AREA)
        rad += emis[..., None] * (np.float32([1.0, 0.8, 0.55]) * 0.5 + alb * 2.0)
    sky.reflect_sky_in_glass(rad, gbuf, quads, qfull, Kc_inv, R, C, cond, scene.seed)
    rows = np.flatnonzero(skyfrac.max(1) > 0)
    if len(rows):
        # The sky is smooth: evaluate it on every other pixel and interpolate.
        r0, r1 = rows[0], rows[-1] + 1
        su, sv = np.meshgrid(
            np.arange(0, Wc, 2, dtype=np.float32), np.arange(r0, r1, 2, dtype=np.float32)
        )
        sub = np.stack([su, sv, np.ones_like(su)], -1) @ (Kc_inv.T @ R).astype(np.float32)
        sub /= np.linalg.norm(sub, axis=-1, keepdims=True)
        sky_rad = sky.sky_radiance(cond, sub.reshape(-1, 3), C, scene.seed).reshape(sub.shape)
        sky_rad = cv2.resize(sky_rad, (Wc, 2 * sub.shape[0]), interpolation=cv2.INTER_LINEAR)
        rad[r0:r1] += skyfrac[r0:r1, :, None] * sky_rad[: r1 - r0]
    cat_q = np.append(quads.category, categories.SKY).astype(np.uint8)
    if distorted:
        rad = cv2.remap(rad, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        qd = cv2.remap(
            gbuf.qid[SS // 2 :: SS, SS // 2 :: SS],
            mapx,
            mapy,
            cv2.INTER_NEAREST,
            borderMode=cv2.BORDER_REPLICATE,
        ).astype(np.intp)
        depth = _plane_depth(coef, qd, mapx, mapy, N)
        category = np.take(cat_q, qd)
    else:
        category = np.take(cat_q, qfull)
    rng = np.random.default_rng(
        [seed & 0xFFFFFFFF, int(when.timestamp() * 1000) & 0xFFFFFFFF, scene.seed & 0xFFFF]
    )
    motion = None
    if velocity is not None and sensor.max_exposure_s is not None:
        motion = camera_effects.motion_field(view.K, R, depth, velocity, sensor.max_exposure_s)
    rgb, cam_meta = camera_effects.expose(
        np.ascontiguousarray(rad, np.float32), view.K, rng, sensor, motion
    )
    meta = cond.as_meta()
    meta.update(cam_meta)
    meta["n_dynamic_quads"] = int(dyn.n)
    return Frame(rgb=rgb, depth=depth, category=category, meta=meta)
