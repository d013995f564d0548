"""Emergent repeatability effects of the synthetic world, measured with SIFT (Sec. III-C, IV-B).

The paper learns *when* an interest point is repeatable: a point re-detected at the same
place in other images of a fixed viewpoint (Sec. III-C), which depends on the time of day
(the daily cycle of Webcam Clip Art, Fig. 5a), on the season (CMU Seasons) and on the
semantic category of the point (Fig. 9). The synthetic world does not label any of this:
it renders pixels under a sun, weather and seasons. This module checks that the effects
*emerge* from those pixels, using only SIFT detections (``cv2.SIFT_create``) and the
per-pixel category map, never a hidden per-keypoint label:

* daytime frames have hundreds of keypoints spread over the scene, night frames far fewer;
* a keypoint is re-detected at the same pixel (static camera, within ``TOLERANCE_PX``) more
  often at the same time on another day than a few hours away on the same day;
* facade (BUILDING) keypoints of midday are re-detected far more often at midday than at
  dusk of another day;
* keypoints on the ground along a shadow boundary at 10:00 are gone at 15:00 (the shadow
  moved with the sun) but come back at 10:00 on another clear day; the shadow boundary is
  found from pixels (a pixel darker than its brightest state of the day);
* tree (VEGETATION) keypoints of July are mostly lost in January (bare trees);
* car (VEHICLE) keypoints are not there in other captures (parked cars change).

Run ``python -m rp_jax.sources.synthetic.emergence OUT_DIR`` for the figure
(``OUT_DIR/emergent_effects.png``) and the numbers (``OUT_DIR/emergent_effects.json``).

Why this module is over 600 lines: each effect above is one small measurement (its scenes,
its pairs of instants, its SIFT counts) and they share the re-detection and masking
helpers; the six together are the world's evidence, read and re-run as one.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as dt
import json
from pathlib import Path

import cv2
import numpy as np

from rp_jax import categories, files
from rp_jax.progress import bar as tqdm  # the one progress helper
from rp_jax.sources.synthetic.conditions import weather_of_day
from rp_jax.sources.synthetic.render import View, look_at, render
from rp_jax.sources.synthetic.scene import Scene, build_scene

__all__ = [
    "TOLERANCE_PX",
    "EmergenceSetup",
    "EmergentEffects",
    "default_setup",
    "detect",
    "redetected",
    "redetection_rate",
    "movers_mask",
    "away_from_movers",
    "shadow_boundary",
    "measure",
    "plot",
    "main",
]

TOLERANCE_PX = 2.5  # a keypoint is re-detected when another image has one this close
TZ = dt.timezone(dt.timedelta(hours=-5))  # local standard time of the default place (Pittsburgh)
DUSK_HOUR = 19.75  # July at 40.4 N, standard time: the sun about 1 deg above the horizon
_SIFT = None


def detect(rgb: np.ndarray) -> np.ndarray:
    """SIFT keypoint positions of an RGB image.

    Args:
      rgb: uint8 (H, W, 3).

    Returns:
      float64 (N, 2) pixel coordinates (x, y), OpenCV convention.
    """
    global _SIFT
    if _SIFT is None:
        _SIFT = cv2.SIFT_create()
    kps = _SIFT.detect(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY), None)
    return np.array([k.pt for k in kps], np.float64).reshape(-1, 2)


def redetected(kp_a: np.ndarray, kp_b: np.ndarray, tol: float = TOLERANCE_PX) -> np.ndarray:
    """Per keypoint of ``kp_a``: is there a keypoint of ``kp_b`` within ``tol`` pixels?

    Args:
      kp_a, kp_b: (N, 2) and (M, 2) positions in the same (static) camera.
      tol: pixel distance.

    Returns:
      bool (N,).
    """
    if len(kp_a) == 0 or len(kp_b) == 0:
        return np.zeros(len(kp_a), bool)
    from scipy.spatial import cKDTree

    d, _ = cKDTree(kp_b).query(kp_a, k=1)
    return d <= tol


def redetection_rate(
    kp_a: np.ndarray, kp_b: np.ndarray, select: np.ndarray | None = None, tol: float = TOLERANCE_PX
) -> float:
    """Fraction of (selected) keypoints of ``kp_a`` re-detected in ``kp_b``; NaN if none
    selected."""
    hit = redetected(kp_a, kp_b, tol)
    if select is not None:
        hit = hit[select]
    return float(hit.mean()) if len(hit) else float("nan")


def category_of(kp: np.ndarray, category: np.ndarray) -> np.ndarray:
    """Category id (``rp_jax.categories``) at each keypoint's nearest pixel."""
    if len(kp) == 0:
        return np.zeros(0, np.int64)
    h, w = category.shape
    x = np.clip(np.round(kp[:, 0]).astype(int), 0, w - 1)
    y = np.clip(np.round(kp[:, 1]).astype(int), 0, h - 1)
    return category[y, x].astype(np.int64)


def _luminance(rgb: np.ndarray) -> np.ndarray:
    """Linear luminance of an 8-bit sRGB image, lightly blurred (texture noise)."""
    g = (cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY).astype(np.float32) / 255.0) ** 2.2
    return cv2.GaussianBlur(g, (0, 0), 1.5)


def movers_mask(category: np.ndarray, movers_px: int) -> np.ndarray:
    """Pixels within ``movers_px`` of a car or person (category VEHICLE or OTHER).

    Parked cars come and go with their dwell times (``scene.parked_car``) and people walk
    by, so what they cover or shade differs between two captures for reasons that are not
    light; the light effects below are measured away from them.
    """
    movers = np.isin(category, (categories.VEHICLE, categories.OTHER)).astype(np.uint8)
    if movers_px <= 0:
        return movers > 0
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * movers_px + 1, 2 * movers_px + 1))
    return cv2.dilate(movers, k) > 0


def away_from_movers(kp: np.ndarray, *categories_maps: np.ndarray, movers_px: int) -> np.ndarray:
    """Keypoints of ``kp`` (N, 2) that no car or person covers or borders in any of the maps."""
    if len(kp) == 0:
        return np.zeros(0, bool)
    h, w = categories_maps[0].shape
    xi = np.clip(np.round(kp).astype(int), 0, [w - 1, h - 1])
    ok = np.ones(len(kp), bool)
    for cat in categories_maps:
        ok &= ~movers_mask(cat, movers_px)[xi[:, 1], xi[:, 0]]
    return ok


def shadow_boundary(
    rgb: np.ndarray,
    day_frames: list[np.ndarray],
    category: np.ndarray,
    *,
    ratio: float = 0.6,
    band_px: int = 3,
    movers_px: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """Cast shadows on the ground of one frame and their boundary, found from pixels only.

    A ground pixel is in shadow when it is much darker than its brightest state over the
    day's frames (each frame normalised by its lit ground, the 90th percentile of ground
    luminance, so that auto-exposure cancels).

    Args:
      rgb: the frame (uint8 RGB).
      day_frames: frames of the same camera at other hours of the same clear day.
      category: the frame's category map.
      ratio: darker than this fraction of the brightest state = shadow.
      band_px: half width of the boundary band.
      movers_px: ground within this many pixels of a car or person (category VEHICLE or
        OTHER) is left out: their shadows belong to objects that are not static.

    Returns:
      (shadow, boundary): bool (H, W) maps, both restricted to GROUND pixels.
    """
    ground = category == categories.GROUND
    if movers_px > 0:  # parked cars and people change between captures, and so do their shadows
        ground &= ~movers_mask(category, movers_px)
    if not ground.any():
        z = np.zeros(category.shape, bool)
        return z, z

    def norm(img):
        lum = _luminance(img)
        return lum / max(float(np.percentile(lum[ground], 90)), 1e-6)

    lum = norm(rgb)
    brightest = np.maximum.reduce([norm(f) for f in day_frames] + [lum])
    shadow = (lum < ratio * brightest) & ground
    k = np.ones((2 * band_px + 1, 2 * band_px + 1), np.uint8)
    s8 = shadow.astype(np.uint8)
    boundary = (cv2.dilate(s8, k) > 0) & ~(cv2.erode(s8, k) > 0) & ground
    return shadow, boundary


@dataclasses.dataclass(frozen=True)
class EmergenceSetup:
    """What is rendered: one static camera on one street, on three dates.

    Attributes:
      scene: the street.
      view: the static camera of the daily curve and of the category effects (it looks
        at the sunlit, south-facing facades of the north side).
      street_view: a second static camera, on the north side looking south over the street,
        where the south side's buildings cast their moving shadows (the shadow effect).
      day_a, day_b: two clear summer dates (reference and "another day").
      winter_day: a January date.
      hours: local hours of ``day_a`` (the daily curve); must include 10, 12, 15.
      hours_b: local hours of ``day_b``; must include 10 and 12 and the dusk hour.
    """

    scene: Scene
    view: View
    street_view: View
    day_a: dt.date
    day_b: dt.date
    winter_day: dt.date
    hours: tuple[float, ...]
    hours_b: tuple[float, ...]


def _clear_days(scene: Scene, year: int, month: int, n: int) -> list[dt.date]:
    days = []
    for d in range(1, 29):
        date = dt.date(year, month, d)
        if weather_of_day(scene.seed, date, scene.latitude)[0] == "clear":
            days.append(date)
            if len(days) == n:
                return days
    raise ValueError(
        f"scene seed {scene.seed}: fewer than {n} clear days in {year}-{month:02d}; "
        f"expected at least {n} (pick another seed)"
    )


def default_setup(
    width: int = 640, height: int = 480, seed: int = 11, *, full_day: bool = True
) -> EmergenceSetup:
    """A webcam over a tree-lined street, high on the south side, looking at the north facades.

    Args:
      width, height: image size.
      seed: scene seed.
      full_day: hourly frames 5:00-23:00 (the figure) or a few hours (the tests).

    Returns:
      ``EmergenceSetup``.
    """
    scene = build_scene(seed, length_m=60.0, vegetation=0.5)
    view = look_at(
        (28.0, scene.sidewalk_y[0], 6.0),
        (36.0, scene.facade_y[1], 3.0),
        width=width,
        height=height,
        fov_deg=75.0,
    )
    # Above the north front yard (an upper-floor window), so that the curb lane below is in
    # the frame: a car parked out of the frame would shade the ground in view, and parked
    # cars stay for hours (scene.parked_car), which is not the sun moving.
    street_view = look_at(
        (28.0, scene.sidewalk_y[1] + 4.0, 8.0),
        (36.0, scene.facade_y[0], 2.0),
        width=width,
        height=height,
        fov_deg=75.0,
    )
    day_a, day_b = _clear_days(scene, 2024, 7, 2)
    winter = dt.date(2024, 1, 17)
    if full_day:
        hours = tuple(float(h) for h in range(5, 24))
        hours_b = (8.0, 10.0, 12.0, 14.0, 16.0, DUSK_HOUR, 22.0)
    else:
        hours = (6.0, 10.0, 12.0, 15.0, 23.0)
        hours_b = (10.0, 12.0, DUSK_HOUR)
    return EmergenceSetup(scene, view, street_view, day_a, day_b, winter, hours, hours_b)


def _movers_px(width: int) -> int:
    """Margin around cars and people: about their shadow's length at 10:00 (1.5 m at 15 m)."""
    return max(2, round(0.06 * width))


def _at(date: dt.date, hour: float) -> dt.datetime:
    return dt.datetime(date.year, date.month, date.day, tzinfo=TZ) + dt.timedelta(hours=hour)


@dataclasses.dataclass
class EmergentEffects:
    """The measured effects (rates are fractions of the reference keypoints re-detected)."""

    hours: list  # day A hours
    counts: list  # keypoints per day A frame
    spread: list  # (x range, y range) of keypoints / image size, per day A frame
    dt_hours: list  # |time difference| (h) of the same-day pairs
    dt_rates: list  # re-detection rate of the same-day pairs
    other_day_rates: dict  # hour -> rate of day A at that hour in day B at that hour
    facade: dict  # midday_other_day, dusk_other_day, n
    shadow_edge: dict  # at_15h_same_day, at_10h_other_day, n, (interior: same for non-edge ground)
    vegetation: dict  # july_other_day, january, n
    vehicle: dict  # other_day (vehicles), building_other_day (for comparison), n
    meta: dict  # dates, image size, tolerance

    def to_json(self) -> dict:
        """JSON-friendly dict (NaN -> None)."""

        def clean(x):
            if isinstance(x, float) and not np.isfinite(x):
                return None
            if isinstance(x, dict):
                return {str(k): clean(v) for k, v in x.items()}
            if isinstance(x, (list, tuple)):
                return [clean(v) for v in x]
            if isinstance(x, np.generic):
                return clean(x.item())
            return x

        return clean(dataclasses.asdict(self))


def _daylight(hours) -> list[float]:
    """The hours whose frames show where the sun reaches (shadow detection): 9:00-16:00."""
    return [h for h in hours if 9 <= h <= 16]


def _render_all(setup: EmergenceSetup, progress: bool) -> dict:
    jobs = [("a", h, _at(setup.day_a, h)) for h in setup.hours]
    jobs += [("b", h, _at(setup.day_b, h)) for h in setup.hours_b]
    jobs += [("w", 12.0, _at(setup.winter_day, 12.0))]
    jobs += [("sa", h, _at(setup.day_a, h)) for h in _daylight(setup.hours)]
    jobs += [("sb", h, _at(setup.day_b, h)) for h in _daylight(setup.hours)]
    frames = {}
    for n, (tag, h, when) in enumerate(
        tqdm(jobs, desc="emergence: render + SIFT", disable=not progress)
    ):
        f = render(
            setup.scene, setup.street_view if tag.startswith("s") else setup.view, when, seed=n
        )
        frames[(tag, h)] = (f, detect(f.rgb))
    return frames


def measure(setup: EmergenceSetup, *, progress: bool = True) -> tuple[EmergentEffects, dict]:
    """Renders the setup's frames, detects SIFT keypoints and measures the effects.

    Args:
      setup: from ``default_setup``.
      progress: show a progress bar.

    Returns:
      (effects, frames) where frames maps (tag, hour) to (Frame, keypoints); tags: ``"a"``,
      ``"b"`` (the two summer days), ``"w"`` (winter), ``"sa"``, ``"sb"`` (street view).
    """
    for h in (10.0, 12.0, 15.0):
        if h not in setup.hours:
            raise ValueError(f"EmergenceSetup.hours must include {h}, got {setup.hours}")
    for h in (10.0, 12.0, DUSK_HOUR):
        if h not in setup.hours_b:
            raise ValueError(f"EmergenceSetup.hours_b must include {h}, got {setup.hours_b}")
    fr = _render_all(setup, progress)
    a = {h: fr[("a", h)] for h in setup.hours}
    b = {h: fr[("b", h)] for h in setup.hours_b}
    W, H = setup.view.width, setup.view.height
    counts = [len(a[h][1]) for h in setup.hours]
    spread = [
        [float(np.ptp(a[h][1][:, 0]) / W), float(np.ptp(a[h][1][:, 1]) / H)]
        if len(a[h][1]) > 1
        else [0.0, 0.0]
        for h in setup.hours
    ]
    mp = _movers_px(W)

    def light_rate(ref, target, select=None):
        # Keypoints away from cars and people in both frames: the effects of light alone.
        (f_ref, k_ref), (f_tgt, k_tgt) = ref, target
        keep = away_from_movers(k_ref, f_ref.category, f_tgt.category, movers_px=mp)
        return redetection_rate(k_ref, k_tgt, keep if select is None else keep & select)

    # Same day, hours apart (references: the daylight hours 9-15 of day A).
    dts, rates = [], []
    for h0 in [h for h in setup.hours if 9 <= h <= 15]:
        for h1 in setup.hours:
            if h1 != h0 and 5 <= h1 <= 21:
                dts.append(abs(h1 - h0))
                rates.append(light_rate(a[h0], a[h1]))
    other = {h: light_rate(a[h], b[h]) for h in setup.hours if h in b}
    # Facades: midday keypoints, re-detected at midday and at dusk of another day.
    f12, k12 = a[12.0]
    cat12 = category_of(k12, f12.category)
    bld = cat12 == categories.BUILDING
    facade = {
        "midday_other_day": light_rate(a[12.0], b[12.0], bld),
        "dusk_other_day": light_rate(a[12.0], b[DUSK_HOUR], bld),
        "n": int(bld.sum()),
    }
    # Shadow boundaries on the ground at 10:00 (street view), found from each day's daylight
    # frames; pooled over both days as reference (day A vs B and day B vs A), since a view
    # holds only a handful of keypoints on a shadow edge.
    tally = {k: [0, 0] for k in ("edge_same", "edge_other", "int_same", "int_other")}

    def add(key, ref, target, select):
        keep = away_from_movers(ref[1], ref[0].category, target[0].category, movers_px=mp)
        hit = redetected(ref[1], target[1])[keep & select]
        tally[key][0] += int(hit.sum())
        tally[key][1] += int(hit.size)

    for day, other_day in (("sa", "sb"), ("sb", "sa")):
        f10, k10 = fr[(day, 10.0)]
        daylight = [fr[(day, h)][0].rgb for h in _daylight(setup.hours) if h != 10.0]
        _, boundary = shadow_boundary(f10.rgb, daylight, f10.category, movers_px=mp)
        xi = np.clip(np.round(k10).astype(int), 0, [W - 1, H - 1]).reshape(-1, 2)
        on_edge = boundary[xi[:, 1], xi[:, 0]]
        interior = (category_of(k10, f10.category) == categories.GROUND) & ~on_edge
        for key, select in (("edge", on_edge), ("int", interior)):
            add(f"{key}_same", fr[(day, 10.0)], fr[(day, 15.0)], select)
            add(f"{key}_other", fr[(day, 10.0)], fr[(other_day, 10.0)], select)

    def rate(key):
        hits, n = tally[key]
        return hits / n if n else float("nan")

    shadow_edge = {
        "at_15h_same_day": rate("edge_same"),
        "at_10h_other_day": rate("edge_other"),
        "n": tally["edge_same"][1],
        "interior_at_15h_same_day": rate("int_same"),
        "interior_at_10h_other_day": rate("int_other"),
    }
    # Trees: July keypoints on VEGETATION, in July (another day) and in January.
    veg = cat12 == categories.VEGETATION
    vegetation = {
        "july_other_day": light_rate(a[12.0], b[12.0], veg),
        "january": light_rate(a[12.0], fr[("w", 12.0)], veg),
        "n": int(veg.sum()),
    }
    veh = cat12 == categories.VEHICLE
    vehicle = {
        "other_day": redetection_rate(k12, b[12.0][1], veh),
        "building_other_day": facade["midday_other_day"],
        "n": int(veh.sum()),
    }
    meta = {
        "day_a": str(setup.day_a),
        "day_b": str(setup.day_b),
        "winter_day": str(setup.winter_day),
        "width": W,
        "height": H,
        "tolerance_px": TOLERANCE_PX,
        "scene_seed": setup.scene.seed,
        "winter_snow_level": int(fr[("w", 12.0)][0].meta["snow"]),
        "winter_foliage": float(fr[("w", 12.0)][0].meta["foliage"]),
    }
    effects = EmergentEffects(
        list(setup.hours),
        counts,
        spread,
        dts,
        rates,
        other,
        facade,
        shadow_edge,
        vegetation,
        vehicle,
        meta,
    )
    return effects, fr


# ---------------------------------------------------------------- the figure


def _draw_points(rgb: np.ndarray, pts: np.ndarray, colours: list, radius: int = 3) -> np.ndarray:
    img = rgb.copy()
    for (x, y), c in zip(pts, colours):
        cv2.circle(img, (round(x), round(y)), radius, c, 1, cv2.LINE_AA)
    return img


def plot(effects: EmergentEffects, frames: dict, path: Path) -> Path:
    """Writes the multi-panel figure of the emergent effects (PNG, atomically).

    Args:
      effects: from ``measure``.
      frames: the frames returned by ``measure``.
      path: output PNG.

    Returns:
      ``path``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    e = effects
    fig, ax = plt.subplots(2, 3, figsize=(17, 10))
    # (a) noon frame with keypoints by category.
    f12, k12 = frames[("a", 12.0)]
    palette = {
        categories.BUILDING: (255, 60, 60),
        categories.VEGETATION: (40, 220, 40),
        categories.VEHICLE: (60, 120, 255),
        categories.GROUND: (255, 220, 0),
    }
    cat = category_of(k12, f12.category)
    ax[0, 0].imshow(_draw_points(f12.rgb, k12, [palette.get(int(c), (255, 255, 255)) for c in cat]))
    ax[0, 0].set_title(
        f"(a) {e.meta['day_a']} 12:00: {len(k12)} SIFT keypoints\n"
        "red building, green tree, blue car, yellow ground"
    )
    ax[0, 0].axis("off")
    # (b) keypoints per frame through the day.
    ax[0, 1].bar(e.hours, e.counts, width=0.8, color="tab:blue")
    ax[0, 1].set_xlabel("local hour (clear day)")
    ax[0, 1].set_ylabel("SIFT keypoints")
    ax[0, 1].set_title("(b) day frames have hundreds of keypoints, night frames few")
    # (c) re-detection vs time difference.
    dts, rates = np.array(e.dt_hours), np.array(e.dt_rates)
    ax[0, 2].scatter(dts, rates, s=12, alpha=0.5, color="tab:gray", label="same day, hours apart")
    for d in np.unique(dts):
        ax[0, 2].plot([d - 0.3, d + 0.3], [np.nanmean(rates[dts == d])] * 2, color="k", lw=2)
    od = np.array([v for v in e.other_day_rates.values()], float)
    ax[0, 2].scatter(
        np.zeros(len(od)), od, s=40, color="tab:red", marker="D", label="same hour, other day"
    )
    for h, r in e.other_day_rates.items():
        if np.isfinite(r):
            ax[0, 2].annotate(
                f"{float(h):g}h", (0.0, r), xytext=(6, -3), textcoords="offset points", fontsize=7
            )
    ax[0, 2].set_xlabel("time difference (hours); 0 = same hour on another day")
    ax[0, 2].set_ylabel(f"re-detected within {TOLERANCE_PX} px")
    ax[0, 2].set_ylim(0, 1)
    ax[0, 2].legend(loc="upper right")
    ax[0, 2].set_title("(c) re-detection falls with time of day, not with days")
    # (d) per-category effects.
    groups = [
        (
            "facade:\nmidday | dusk",
            e.facade["midday_other_day"],
            e.facade["dusk_other_day"],
            e.facade["n"],
        ),
        (
            "shadow edge:\n10h other day | 15h",
            e.shadow_edge["at_10h_other_day"],
            e.shadow_edge["at_15h_same_day"],
            e.shadow_edge["n"],
        ),
        (
            "tree:\nJuly | January",
            e.vegetation["july_other_day"],
            e.vegetation["january"],
            e.vegetation["n"],
        ),
        (
            "other day:\nbuilding | car",
            e.vehicle["building_other_day"],
            e.vehicle["other_day"],
            e.vehicle["n"],
        ),
    ]
    x = np.arange(len(groups))
    good = [np.nan_to_num(g[1]) for g in groups]
    bad = [np.nan_to_num(g[2]) for g in groups]
    ax[1, 0].bar(x - 0.2, good, 0.4, color="tab:green", label="expected high")
    ax[1, 0].bar(x + 0.2, bad, 0.4, color="tab:red", label="expected low")
    for i, g in enumerate(groups):
        ax[1, 0].text(i, max(good[i], bad[i]) + 0.02, f"n={g[3]}", ha="center")
    ax[1, 0].set_xticks(x, [g[0] for g in groups], fontsize=9)
    ax[1, 0].set_ylim(0, 1.05)
    ax[1, 0].set_ylabel("re-detection rate")
    ax[1, 0].legend(loc="upper right")
    ax[1, 0].set_title("(d) categories: high vs low condition")
    # (e) shadow-edge keypoints at 10:00, coloured by re-detection at 15:00.
    f10, k10 = frames[("sa", 10.0)]
    daylight = [frames[("sa", h)][0].rgb for h in _daylight(e.hours) if h != 10.0]
    _, boundary = shadow_boundary(
        f10.rgb, daylight, f10.category, movers_px=_movers_px(f10.rgb.shape[1])
    )
    if len(k10):
        xi = np.clip(np.round(k10).astype(int), 0, [f10.rgb.shape[1] - 1, f10.rgb.shape[0] - 1])
        edge = boundary[xi[:, 1], xi[:, 0]]
        hit15 = redetected(k10[edge], frames[("sa", 15.0)][1])
        img = f10.rgb.copy()
        img[boundary] = (0.5 * img[boundary] + [0, 0, 127]).astype(np.uint8)
        img = _draw_points(
            img, k10[edge], [(0, 255, 0) if h else (255, 0, 0) for h in hit15], radius=4
        )
    else:
        img = f10.rgb
    ax[1, 1].imshow(img)
    ax[1, 1].axis("off")
    ax[1, 1].set_title(
        "(e) 10:00: static shadow boundaries on the ground (blue, from pixels);\n"
        "their keypoints re-detected at 15:00: green yes, red no"
    )
    # (f) January frame and July frame side by side (trees bare, cars changed).
    fw, kw = frames[("w", 12.0)]
    fb, kb = frames[("b", 12.0)]
    ax[1, 2].imshow(np.vstack([fb.rgb, fw.rgb]))
    ax[1, 2].axis("off")
    ax[1, 2].set_title(
        f"(f) top {e.meta['day_b']} 12:00 ({len(kb)} kp), bottom {e.meta['winter_day']} 12:00\n"
        f"({len(kw)} kp, snow level {e.meta['winter_snow_level']}): bare trees, other cars"
    )
    fig.suptitle(
        f"Emergent repeatability effects of the synthetic world (SIFT, static camera, "
        f"{e.meta['width']}x{e.meta['height']}, re-detection within {TOLERANCE_PX} px)",
        fontsize=14,
    )
    fig.tight_layout()
    path = Path(path)
    try:
        with files.replacing(path) as tmp:
            fig.savefig(tmp, format="png", dpi=80)
    finally:
        plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> int:
    """``python -m rp_jax.sources.synthetic.emergence OUT_DIR [--width W --height H --seed S]``."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out_dir", type=Path)
    p.add_argument("--width", type=int, default=640)
    p.add_argument("--height", type=int, default=480)
    p.add_argument("--seed", type=int, default=11)
    args = p.parse_args(argv)
    cv2.setNumThreads(1)
    setup = default_setup(args.width, args.height, args.seed)
    effects, frames = measure(setup)
    args.out_dir.mkdir(parents=True, exist_ok=True)
    png = plot(effects, frames, args.out_dir / "emergent_effects.png")
    files.write_json(args.out_dir / "emergent_effects.json", effects.to_json())
    print(
        json.dumps(
            {k: v for k, v in effects.to_json().items() if k not in ("dt_hours", "dt_rates")},
            indent=1,
        )
    )
    print(f"wrote {png}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
