"""Tests of the renderer: exact geometry, lighting and what SIFT sees (Sec. III-C, IV-A)."""

import datetime as dt

import cv2
import numpy as np
import pytest

from rp_jax import categories
from rp_jax.sources.synthetic import textures as tx
from rp_jax.sources.synthetic.contact_sheet import contact_sheet
from rp_jax.sources.synthetic.quads import Material, QuadSet
from rp_jax.sources.synthetic.render import look_at, project, render
from rp_jax.sources.synthetic.scene import build_scene

TZ = dt.timezone(dt.timedelta(hours=-5))
NOON = dt.datetime(2024, 7, 9, 12, 30, tzinfo=TZ)


@pytest.fixture(scope="module")
def scene():
    return build_scene(11, length_m=60.0, vegetation=0.4)


def _webcam(scene, w=320, h=240, distortion=None):
    return look_at(
        (30.0, scene.sidewalk_y[0], 4.0),
        (36.0, scene.facade_y[1], 6.0),
        width=w,
        height=h,
        fov_deg=70.0,
        distortion=distortion,
    )


def _clear_day(scene, hour=12, minute=30, month=7, start=1):
    """First date (from ``start``) whose weather is clear, to make lighting tests sharp."""
    from rp_jax.sources.synthetic.conditions import weather_of_day

    for d in range(start, 29):
        if weather_of_day(scene.seed, dt.date(2024, month, d), scene.latitude)[0] == "clear":
            return dt.datetime(2024, month, d, hour, minute, tzinfo=TZ)
    raise AssertionError("no clear day")


def test_frame_shapes_and_categories(scene):
    view = look_at(
        (20.0, scene.lanes_y["eastbound"], 1.6),
        (60.0, scene.lanes_y["eastbound"], 1.6),
        width=160,
        height=120,
    )
    f = render(scene, view, NOON)
    assert f.rgb.shape == (120, 160, 3) and f.rgb.dtype == np.uint8
    assert f.depth.shape == (120, 160) and f.depth.dtype == np.float32
    assert f.category.shape == (120, 160)
    assert np.all(f.category[-3:] == categories.GROUND)
    top = f.category[:5, 60:100]
    assert np.mean(top == categories.SKY) > 0.5
    assert np.all(np.isinf(f.depth[f.category == categories.SKY]))
    assert np.all(np.isfinite(f.depth[f.category != categories.SKY]))
    for key in ("sun_elevation_deg", "sun_azimuth_deg", "weather", "gain", "snow", "foliage"):
        assert key in f.meta


def test_depth_is_consistent_between_views(scene):
    when = _clear_day(scene)
    va = _webcam(scene)
    vb = look_at(
        (26.0, scene.sidewalk_y[0] + 1.0, 2.5),
        (38.0, scene.facade_y[1], 5.0),
        width=320,
        height=240,
        fov_deg=65.0,
    )
    fa, fb = render(scene, va, when), render(scene, vb, when)
    v, u = np.mgrid[0:240:7, 0:320:7]
    z = fa.depth[v, u]
    ok = np.isfinite(z)
    u, v, z = u[ok], v[ok], z[ok]
    Xc = np.stack([(u - va.K[0, 2]) / va.K[0, 0] * z, (v - va.K[1, 2]) / va.K[1, 1] * z, z], -1)
    X = (Xc - va.t) @ va.R
    pb = project(vb, X)
    zb = (X @ vb.R.T + vb.t)[:, 2]
    ib = np.round(pb).astype(int)
    inside = (ib[:, 0] >= 0) & (ib[:, 0] < 320) & (ib[:, 1] >= 0) & (ib[:, 1] < 240) & (zb > 0)
    rendered = fb.depth[ib[inside, 1], ib[inside, 0]]
    rel = np.abs(rendered - zb[inside]) / zb[inside]
    # Occluded points differ; visible ones agree. Most sampled points are visible in both,
    # counting those on static structure in both views: parked cars stand where their
    # stays put them and hide different things from the two viewpoints.
    movers = (categories.VEHICLE, categories.OTHER)
    static = ~np.isin(fa.category[v, u][inside], movers) & ~np.isin(
        fb.category[ib[inside, 1], ib[inside, 0]], movers
    )
    assert static.sum() > 300
    assert np.mean(rel[static] < 0.02) > 0.8


def _marker_scene(scene, centre):
    """The scene plus a vertical 0.6 m marker quad facing -y with a dark dot at its centre."""
    key = "marker"

    def tex():
        img = np.full((64, 64, 3), 0.9, np.float32)
        yy, xx = np.mgrid[0:64, 0:64]
        img *= 1 - 0.85 * np.exp(-((xx - 31.5) ** 2 + (yy - 31.5) ** 2) / (2 * 4.0**2))[..., None]
        return tx.finish(img, np.zeros((64, 64), np.uint8), blur=0)

    scene.textures.register(key, tex, {})
    o = np.asarray(centre) + np.array([-0.3, 0.0, 0.3])
    marker = QuadSet(
        o[None],
        np.array([[0.6, 0, 0]]),
        np.array([[0, 0, -0.6]]),
        [key],
        np.array([categories.OTHER], np.uint8),
        np.array([Material.WALL], np.int8),
        np.array([-1], np.int32),
        np.asarray(centre)[None] - [0, 0.05, 0],
        np.array([-1], np.int32),
        np.zeros(1, np.float32),
    )
    import dataclasses

    return dataclasses.replace(scene, static=QuadSet.concat([scene.static, marker]))


@pytest.mark.parametrize("distortion", [None, (-0.12, 0.02, 0.001, -0.0005)])
def test_marker_drawn_where_projected(scene, distortion):
    centre = np.array([35.0, scene.sidewalk_y[0] + 3.5, 2.0])
    s = _marker_scene(scene, centre)
    for eye in [(33.0, scene.sidewalk_y[0], 1.7), (36.4, scene.sidewalk_y[0] - 0.5, 2.3)]:
        view = look_at(
            eye,
            centre + [0.37, 0.0, 0.21],
            width=320,
            height=240,
            fov_deg=60.0,
            distortion=distortion,
        )
        f = render(s, view, _clear_day(scene), seed=0)
        p = project(view, centre[None])[0]
        x0, y0 = int(p[0]) - 10, int(p[1]) - 10
        patch = f.rgb[y0 : y0 + 21, x0 : x0 + 21].astype(np.float64).mean(-1)
        dark = np.clip(np.percentile(patch, 90) - patch, 0, None)
        dark[dark < 0.3 * dark.max()] = 0
        yy, xx = np.mgrid[0:21, 0:21]
        cx, cy = (dark * xx).sum() / dark.sum() + x0, (dark * yy).sum() / dark.sum() + y0
        assert np.hypot(cx - p[0], cy - p[1]) < 0.5, (cx, cy, p)


def test_day_night_and_weather_lighting(scene):
    view = _webcam(scene, 160, 120)
    day = _clear_day(scene)
    noon = render(scene, view, day)
    night = render(scene, view, day.replace(hour=23, minute=30))
    assert noon.meta["sun_elevation_deg"] > 60 and night.meta["sun_elevation_deg"] < -15
    assert night.meta["gain"] > 5 * noon.meta["gain"]
    assert night.rgb.mean() < 0.6 * noon.rgb.mean()
    winter_dusk = render(scene, view, dt.datetime(2024, 12, 15, 17, 30, tzinfo=TZ))
    summer_dusk = render(scene, view, dt.datetime(2024, 7, 15, 17, 30, tzinfo=TZ))
    assert winter_dusk.meta["sun_elevation_deg"] < 0 < summer_dusk.meta["sun_elevation_deg"]
    assert winter_dusk.rgb.mean() < summer_dusk.rgb.mean()


def test_shadows_move_with_the_sun(scene):
    view = look_at((30.0, scene.lanes_y["westbound"], 8.0), (34.0, 0.0, 0.0), width=160, height=120)
    day = _clear_day(scene)
    a = render(scene, view, day.replace(hour=9, minute=0)).rgb.astype(float)
    b = render(scene, view, day.replace(hour=16, minute=0)).rgb.astype(float)
    assert np.mean(np.abs(a - b)) > 8.0


def _sift(img):
    sift = cv2.SIFT_create()
    return sift.detect(cv2.cvtColor(img, cv2.COLOR_RGB2GRAY), None)


def _redetected(kp_a, kp_b, tol=2.5):
    if not kp_a or not kp_b:
        return 0.0
    a = np.array([k.pt for k in kp_a])
    b = np.array([k.pt for k in kp_b])
    d = np.sqrt(((a[:, None] - b[None]) ** 2).sum(-1)).min(1)
    return float(np.mean(d < tol))


def test_sift_day_night_and_time_of_day_repeatability(scene):
    view = _webcam(scene, 320, 240)
    d1 = _clear_day(scene, 12, 0)
    d2 = _clear_day(scene, 12, 0, start=d1.day + 1)
    f_noon = render(scene, view, d1)
    kp_noon = _sift(f_noon.rgb)
    kp_noon2 = _sift(render(scene, view, d2, seed=1).rgb)
    kp_eve = _sift(render(scene, view, d1.replace(hour=18, minute=30)).rgb)
    kp_night = _sift(render(scene, view, d1.replace(hour=23, minute=30)).rgb)
    assert len(kp_noon) > 200
    assert len(kp_night) < 0.6 * len(kp_noon)
    xy = np.array([k.pt for k in kp_noon]).astype(int)
    assert np.ptp(xy[:, 0]) > 200 and np.ptp(xy[:, 1]) > 120  # spread over the scene
    same_time = _redetected(kp_noon, kp_noon2)
    other_time = _redetected(kp_noon, kp_eve)
    assert same_time > other_time
    assert same_time > 0.3


def test_vegetation_changes_with_season():
    s = build_scene(4, vegetation=0.9)
    view = look_at(
        (20.0, s.sidewalk_y[0], 1.7),
        (24.0, s.sidewalk_y[1], 4.0),
        width=320,
        height=240,
        fov_deg=75.0,
    )
    july = render(s, view, dt.datetime(2024, 7, 20, 12, 0, tzinfo=TZ))
    jan = render(s, view, dt.datetime(2024, 1, 20, 12, 0, tzinfo=TZ))
    assert july.meta["foliage"] == 1.0 and jan.meta["foliage"] == 0.0
    veg_july = np.mean(july.category == categories.VEGETATION)
    veg_jan = np.mean(jan.category == categories.VEGETATION)
    assert veg_jan < 0.5 * veg_july


def test_foliage_moves_between_frames_and_buildings_do_not():
    s = build_scene(4, vegetation=0.9)
    view = look_at(
        (20.0, s.sidewalk_y[0], 1.7),
        (24.0, s.sidewalk_y[1], 4.0),
        width=320,
        height=240,
        fov_deg=75.0,
    )
    when = dt.datetime(2024, 7, 20, 12, 0, tzinfo=TZ)
    a, b = render(s, view, when), render(s, view, when + dt.timedelta(seconds=2))
    again = render(s, view, when)
    np.testing.assert_array_equal(a.rgb, again.rgb)  # deterministic per instant
    diff = np.abs(a.rgb.astype(np.int16) - b.rgb.astype(np.int16)).max(-1)
    veg = (a.category == categories.VEGETATION) & (b.category == categories.VEGETATION)
    bld = (a.category == categories.BUILDING) & (b.category == categories.BUILDING)
    assert veg.sum() > 2000 and bld.sum() > 2000
    assert np.mean(diff[veg] > 30) > 0.05  # leaves moved
    assert np.mean(diff[bld] > 30) < 0.01  # walls only get sensor noise


def test_flutter_is_smooth_seeded_and_off_when_calm():
    from rp_jax.sources.synthetic.render import _flutter

    img = np.zeros((64, 64, 4), np.uint8)
    for c in range(0, 64, 8):
        img[:, c : c + 3] = 255  # vertical stripes, 3 px wide
    rng = lambda: np.random.default_rng(5)  # noqa: E731
    np.testing.assert_array_equal(_flutter(img, 0.1, 8.0, rng()), img)  # below 0.2 px: untouched
    moved = _flutter(img, 2.0, 16.0, rng())
    np.testing.assert_array_equal(moved, _flutter(img, 2.0, 16.0, rng()))
    assert not np.array_equal(moved, img)
    # Smooth: neighbouring rows are displaced alike, so a stripe stays one connected line.
    n, _ = cv2.connectedComponents((moved[8:-8, 8:-8, 0] > 127).astype(np.uint8))
    assert n - 1 <= 8


def test_contact_sheet():
    imgs = [np.full((48, 64, 3), v, np.uint8) for v in (0, 128, 255)]
    sheet = contact_sheet(imgs, ["a", "b", "c"], columns=2, pad=4)
    caption = 14  # max(14, 48 // 10)
    assert sheet.shape == (2 * (48 + caption + 4) + 4, 2 * (64 + 4) + 4, 3)
    np.testing.assert_array_equal(sheet[4:52, 4:68], imgs[0])  # first tile, top left
    np.testing.assert_array_equal(sheet[4:52, 72:136], imgs[1])  # second, same row
    np.testing.assert_array_equal(sheet[70:118, 4:68], imgs[2])  # third, next row
    with pytest.raises(ValueError, match="3 frames but 1 labels"):
        contact_sheet(imgs, ["a"])
    with pytest.raises(ValueError, match="same size"):
        contact_sheet([imgs[0], imgs[0][:10]], ["a", "b"])


def test_a_long_caption_stays_under_its_own_tile():
    imgs = [np.full((48, 64, 3), 128, np.uint8)] * 2
    sheet = contact_sheet(imgs, ["overcast-reference: left 12:07", ""], columns=2, pad=4)
    strip = sheet[52:66]  # the caption row
    assert (strip[:, 4:68] < 128).any()  # the first caption is drawn
    assert (strip[:, 68:] == 255).all()  # and stops before the second tile's


def test_motion_of_a_sideways_camera_is_f_v_t_over_depth():
    from rp_jax.sources.synthetic.camera_effects import motion_field

    K = np.array([[200.0, 0, 32], [0, 200.0, 24], [0, 0, 1]])
    R = np.eye(3)  # camera axes = world axes: x right, z forward
    depth = np.full((48, 64), 10.0, np.float32)
    depth[:, 40:] = np.inf  # the sky does not move
    m = motion_field(K, R, depth, np.array([5.0, 0.0, 0.0]), 0.09)
    # the camera moves 0.45 m right: the scene 200 * 0.45 / 10 = 9 px left
    np.testing.assert_allclose(m[:, :40, 0], -9.0, atol=1e-3)
    np.testing.assert_allclose(m[:, :40, 1], 0.0, atol=1e-3)
    assert not m[:, 40:].any()


def test_a_moving_camera_s_night_is_blurred_and_a_distorted_one_refused(scene):
    from rp_jax.sources.synthetic import camera_effects, photometry

    view = _webcam(scene, 160, 120)
    night = dt.datetime(2024, 1, 9, 23, 0, tzinfo=TZ)
    kw = dict(seed=3, lighting=photometry.EN_13201, sensor=camera_effects.GRASSHOPPER2_11HZ)
    still = render(scene, view, night, **kw)
    moving = render(scene, view, night, velocity=np.array([12.0, 0.0, 0.0]), **kw)
    longest = camera_effects.GRASSHOPPER2_11HZ.max_exposure_s
    assert still.meta["exposure_s"] == pytest.approx(longest)

    def across_over_along(rgb):  # the street runs along the image's x: blur takes x detail
        g = cv2.GaussianBlur(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY).astype(np.float32), (0, 0), 1)
        return (np.diff(g, axis=1) ** 2).mean() / (np.diff(g, axis=0) ** 2).mean()

    assert across_over_along(moving.rgb) < 0.8 * across_over_along(still.rgb)
    bent = _webcam(scene, 160, 120, distortion=np.array([-0.2, 0.05, 0.0, 0.0]))
    with pytest.raises(NotImplementedError, match="undistorted"):
        render(scene, bent, night, velocity=np.array([1.0, 0.0, 0.0]), **kw)


def test_the_car_s_headlamps_light_the_road_ahead_at_night_where_the_lighting_has_them(scene):
    from rp_jax.sources.synthetic import camera_effects, photometry

    # A camera on the car, looking ahead along the eastbound lane, at night, with the
    # RobotCar camera's long exposure and gain (a webcam at its gain limit sees no road).
    y = scene.lanes_y["eastbound"]
    view = look_at((20.0, y, 1.6), (40.0, y, 0.0), width=96, height=72, fov_deg=60.0)
    night = dt.datetime(2024, 1, 9, 23, 0, tzinfo=TZ)
    car = (18.0, y, 0.0)
    kw = dict(seed=3, sensor=camera_effects.GRASSHOPPER2_11HZ)
    lit = render(scene, view, night, vehicle=car, lighting=photometry.EN_13201, **kw)
    dark = render(scene, view, night, vehicle=None, lighting=photometry.EN_13201, **kw)
    near = lit.category[48:] == categories.GROUND  # the road a few metres ahead
    assert near.mean() > 0.9
    assert lit.rgb[48:][near].mean() > 2.0 * dark.rgb[48:][near].mean()
    legacy = [render(scene, view, night, vehicle=v, **kw) for v in (car, None)]
    np.testing.assert_array_equal(legacy[0].rgb, legacy[1].rgb)  # no headlamps in LEGACY
