"""Tests of rp_jax.page, rp_jax.mapsum.summary_page and the commands' ``--html`` pages.

Three kinds:

* structure, without a browser: the page is one self-contained file (no URL outside it, the
  image a ``data:`` URI, the arrays inline JSON equal to the input), names cannot break out
  of the script, a user's file is never replaced;
* the commands: ``python -m rp_jax.keypoints --html`` and ``python -m rp_jax.mapsum
  summarize --html`` write pages whose data are the run's own (the keypoints' ``.npz``, the
  summaries the command writes for each timestamp);
* as a person sees it, in headless Chromium (skipped where none is installed; Debian's
  ``chromium`` package, docs/page.md): a screenshot per state the URL sets (``?t=...``
  moves the slider, ``&click=x,y`` clicks), compared pixel by pixel: the keypoints change
  colour between two times and nothing else of the image does, the curve panel holds no
  curve before a click and one after; the page's own reading of a curve (its state JSON,
  from ``--dump-dom``) equals ``rp_jax.predict.at_time``.
"""

import base64
import datetime as dt
import html.parser
import json
import os
import re
import shutil
import subprocess

import cv2
import numpy as np
import pytest

from rp_jax import page
from rp_jax import schedule as schedule_lib
from tests._own_data import render, texture

WEBCAM = schedule_lib.preset("webcam_clipart")  # 21 timestamps 08:00-18:00: no wrap
CMU = schedule_lib.preset("cmu_seasons")  # 12 dates over the year: wraps
CURVE_RGB = (0xD6, 0x27, 0x28)  # the page's curve colour (CURVE_COLOUR in its script)


@pytest.fixture(scope="module")
def image():
    return render(texture(3), np.eye(3), np.zeros(3))  # 320x240 RGB


def _points(n=40, seed=0, w=320, h=240):
    """n keypoints at least 24 pixels apart (none hides another on screen)."""
    rng = np.random.default_rng(seed)
    xy = []
    while len(xy) < n:
        p = rng.uniform([12, 12], [w - 12, h - 12])
        if all(np.hypot(*(p - q)) >= 24 for q in xy):
            xy.append(p)
    return np.array(xy)


def _opposite_curves(n, T, lo=0.1, hi=0.9):
    """Half the keypoints rise over the cycle, half fall: every colour changes with time."""
    ramp = np.linspace(lo, hi, T)
    return np.where(np.arange(n)[:, None] % 2 == 0, ramp, ramp[::-1])


class _Parts(html.parser.HTMLParser):
    """Tags with their attributes, and the text of each <script>."""

    def __init__(self):
        super().__init__()
        self.tags, self.scripts, self._in = [], [], None

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))
        if tag == "script":
            self._in = dict(attrs)
            self.scripts.append([dict(attrs), ""])

    def handle_endtag(self, tag):
        if tag == "script":
            self._in = None

    def handle_data(self, data):
        if self._in is not None:
            self.scripts[-1][1] += data


def _parse(text):
    p = _Parts()
    p.feed(text)
    return p


def _data(text):
    scripts = [s for a, s in _parse(text).scripts if a.get("id") == "rp-data"]
    assert len(scripts) == 1
    return json.loads(scripts[0])


def _assert_self_contained(text):
    parts = _parse(text)
    assert not re.search(r"(https?:)?//[a-z0-9.-]+\.[a-z]{2,}/", text, re.I), "a URL"
    assert not re.search(r"\b(fetch|XMLHttpRequest|import\s*\(|@import)\b", text)
    for tag, attrs in parts.tags:
        assert tag not in ("link", "iframe", "object", "embed"), tag
        for key in ("src", "href"):
            if key in attrs:
                assert attrs[key].startswith("data:"), (tag, key, attrs[key][:40])
    assert all("src" not in a for a, _ in parts.scripts)


# ---- structure, no browser ----


def test_slider_covers_the_schedules_span_or_its_whole_cycle():
    day = page.slider_cycle(WEBCAM)
    assert (day.cycle, day.wraps, day.start, day.stop, day.step) == (
        "day", False, 8 * 3600, 18 * 3600, 60)
    year = page.slider_cycle(CMU)
    assert (year.cycle, year.wraps, year.start, year.stop, year.step) == (
        "year", True, 0, 364 * 86400, 86400)
    assert year.labels == tuple(CMU.labels) and year.offsets == tuple(CMU.offsets)
    night = page.slider_cycle(WEBCAM, wrap=True)  # --wrap: across the night as well
    assert (night.wraps, night.start, night.stop) == (True, 0, 86400 - 60)


def test_colour_range_holds_every_value_of_every_curve():
    curves = np.array([[0.031, 0.2], [0.39, 0.05]])
    assert page.colour_range(curves) == (0.03, 0.39)
    lo, hi = page.colour_range(np.full((3, 4), 0.5))
    assert lo < 0.5 < hi and hi - lo == pytest.approx(0.01)
    assert page.colour_range(np.array([[0.0, 1.0]])) == (0.0, 1.0)


def test_keypoints_page_is_one_self_contained_file_holding_its_data(image):
    xy = _points()
    curves = _opposite_curves(len(xy), WEBCAM.num_timestamps)
    text = page.keypoints_page(image, xy, curves, WEBCAM, captured=dt.datetime(2024, 6, 1, 9, 30),
                               at=dt.datetime(2024, 6, 1, 16, 2), title="photo.jpg", model="m")
    _assert_self_contained(text)
    d = _data(text)
    np.testing.assert_allclose(d["xy"], xy, atol=0.005)
    np.testing.assert_allclose(page.decode_curves(d["curves"], *curves.shape), curves, atol=1e-5)
    assert d["range"] == [0.1, 0.9] and len(d["colours"]) == 256
    assert d["start"] == 16 * 3600 + 120 and d["captured_offset"] == 9 * 3600 + 1800
    uri = [a["src"] for t, a in _parse(text).tags if t == "img"][0]
    shown = cv2.imdecode(np.frombuffer(base64.b64decode(uri.split(",", 1)[1]), np.uint8), 1)
    assert shown.shape == (240, 320, 3)
    # The JPEG is the image (not another one): close to it, pixel by pixel.
    assert np.abs(shown[:, :, ::-1].astype(int) - image).mean() < 8


def test_a_large_image_is_shrunk_and_its_keypoints_keep_their_pixels():
    big = np.zeros((100, 2000, 3), np.uint8)
    text = page.keypoints_page(big, [[1999.0, 99.0]], [[0.5] * 21], WEBCAM, max_image_side=400)
    d = _data(text)
    assert d["image"] == {"width": 2000, "height": 100, "shown_width": 400, "shown_height": 20}
    assert d["xy"] == [[1999.0, 99.0]]


def test_names_cannot_close_the_script_or_inject_markup(image):
    evil = 'a</script><script>alert(1)</script><b onload="x">'
    text = page.keypoints_page(image, _points(3), np.full((3, 21), 0.5), WEBCAM, title=evil,
                               model=evil)
    assert text.count("</script>") == 2  # the data's and the code's, nothing more
    assert "<b onload" not in text
    d = _data(text)
    assert d["title"] == evil and d["model"] == evil


def test_map_page_keeps_one_mask_per_timestamp_bit_for_bit():
    rng = np.random.default_rng(1)
    P, T = 37, CMU.num_timestamps
    kept = rng.random((T, P)) < 0.4
    text = page.map_page(rng.normal(size=(P, 2)), rng.random((P, T)), kept, CMU,
                         cameras_xy=np.zeros((2, 2)), at=dt.datetime(2024, 12, 20))
    _assert_self_contained(text)
    d = _data(text)
    back = np.stack([np.unpackbits(np.frombuffer(base64.b64decode(b), np.uint8))[:P]
                     for b in d["kept"]]).astype(bool)
    np.testing.assert_array_equal(back, kept)
    assert d["kept_counts"] == kept.sum(1).tolist()
    assert d["start"] == CMU.offset_of(dt.datetime(2024, 12, 20))


def test_arrays_of_the_wrong_shape_are_refused(image):
    with pytest.raises(ValueError, match=r"curves must be \[2, 21\]"):
        page.keypoints_page(image, _points(2), np.zeros((2, 12)), WEBCAM)
    with pytest.raises(ValueError, match=r"kept must be \[12, 3\]"):
        page.map_page(np.zeros((3, 2)), np.zeros((3, 12)), np.zeros((3, 12), bool), CMU)
    with pytest.raises(ValueError, match="uint8"):
        page.keypoints_page(image.astype(float), _points(2), np.zeros((2, 21)), WEBCAM)


def test_a_users_file_is_never_replaced_and_our_own_page_is(tmp_path, image):
    text = page.keypoints_page(image, _points(2), np.full((2, 21), 0.5), WEBCAM)
    mine = tmp_path / "notes.html"
    mine.write_text("<html>my notes</html>")
    with pytest.raises(page.PageExistsError, match="notes.html: exists and is not a page"):
        page.write_page(mine, text)
    assert mine.read_text() == "<html>my notes</html>"
    with pytest.raises(page.PageExistsError, match="is a folder"):
        page.write_page(tmp_path, text)
    ours = page.write_page(tmp_path / "sub" / "page.html", text)
    page.write_page(ours, text.replace("</body>", "<!-- again --></body>"))
    assert "again" in ours.read_text()
    assert sorted(p.name for p in (tmp_path / "sub").iterdir()) == ["page.html"]  # no temporary


# ---- the commands ----


def test_keypoints_command_writes_the_page_of_its_own_results(image, tmp_path, capsys):
    from rp_jax.keypoints import __main__ as command

    photo = tmp_path / "photo.png"
    cv2.imwrite(str(photo), image[:, :, ::-1])
    target = tmp_path / "pages" / "photo.html"
    rc = command.main([str(photo), "--predictor", "webcam_clipart-synthetic", "--captured",
                       "2024-06-01 09:30", "--at", "2024-06-01 22:00", "--wrap", "--out",
                       str(tmp_path / "out"), "--html", str(target), "--max-keypoints", "50"])
    assert rc == 0, capsys.readouterr().err
    assert f"and the page {target}" in capsys.readouterr().out
    text = target.read_text()
    _assert_self_contained(text)
    d = _data(text)
    with np.load(tmp_path / "out" / "photo.npz") as z:
        np.testing.assert_allclose(d["xy"], z["xy"], atol=0.005)
        np.testing.assert_allclose(page.decode_curves(d["curves"], *z["curves"].shape),
                                   z["curves"], atol=1e-5)
    # --wrap: the slider covers the night too, and starts at --at.
    assert d["cycle"]["wraps"] and d["start"] == 22 * 3600
    assert d["model"] == "webcam_clipart-synthetic"
    assert d["title"] == f"photo.png: {len(d['xy'])} keypoints"


def test_keypoints_command_refuses_a_page_it_cannot_write_before_any_work(image, tmp_path,
                                                                          capsys):
    from rp_jax.keypoints import __main__ as command

    photo = tmp_path / "photo.png"
    cv2.imwrite(str(photo), image[:, :, ::-1])
    mine = tmp_path / "mine.html"
    mine.write_text("mine")
    args = ["--predictor", "webcam_clipart-synthetic", "--captured", "2024-06-01 09:30", "--out",
            str(tmp_path / "out")]
    assert command.main([str(photo), *args, "--html", str(mine)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--html" in err and "mine.html: exists" in err
    assert mine.read_text() == "mine" and not (tmp_path / "out").exists()
    other = tmp_path / "other.png"
    shutil.copy(photo, other)
    assert command.main([str(photo), str(other), *args, "--html", str(tmp_path / "p.html")]) == 2
    assert "a page shows one IMAGE, got 2" in capsys.readouterr().err


@pytest.fixture(scope="module")
def summarized(tmp_path_factory):
    """A map summarized at every timestamp (--all-slots) with its page, in one run, by the
    shipped RobotCar-like model (9 hourly timestamps: 9 summaries)."""
    from rp_jax.mapsum import __main__ as command
    from tests._own_data import make_scene

    root = tmp_path_factory.mktemp("map")
    scene = make_scene(root / "scene")
    out, target = root / "summary", root / "map.html"
    rc = command.main(["summarize", "--model", str(scene.model), "--images", str(scene.images),
                       "--predictor", "robotcar-synthetic", "--ratio", "0.7", "--parts", "3",
                       "--all-slots", "--out", str(out), "--html", str(target), "--quiet"])
    assert rc == 0
    return scene, out, target


def test_map_page_shows_the_summaries_the_command_writes(summarized):
    import pycolmap

    from rp_jax.mapsum import map_points_from_reconstruction, read_model
    from rp_jax.mapsum.model_summary import slot_folder

    scene, out, target = summarized
    text = target.read_text()
    _assert_self_contained(text)
    d = _data(text)
    mp = map_points_from_reconstruction(read_model(scene.model))
    assert len(d["xy"]) == mp.num_points and len(d["cameras"]) == len(scene.db_names)
    for j, label in enumerate(schedule_lib.preset("robotcar").labels):
        bits = np.unpackbits(np.frombuffer(base64.b64decode(d["kept"][j]), np.uint8))
        on_page = set(mp.point3D_ids[bits[: mp.num_points].astype(bool)].tolist())
        written = set(pycolmap.Reconstruction(str(out / slot_folder(j, label) / "model"))
                      .point3D_ids())
        assert on_page == written, label
    assert len({tuple(k) for k in d["kept"]}) > 1  # the kept points change with time


def test_map_page_needs_the_repeatability_summary(summarized, tmp_path, capsys):
    from rp_jax.mapsum import __main__ as command

    scene, _, _ = summarized
    rc = command.main(["summarize", "--model", str(scene.model), "--images", str(scene.images),
                       "--method", "kcover", "--ratio", "0.5", "--out", str(tmp_path / "o"),
                       "--html", str(tmp_path / "p.html")])
    assert rc == 2 and "--html shows the summary at each timestamp" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


# ---- in a browser ----


def _chromium():
    for name in (os.environ.get("RP_JAX_CHROMIUM"), "chromium", "chromium-browser",
                 "google-chrome", "google-chrome-stable"):
        if name and shutil.which(name):
            return shutil.which(name)
    return None


CHROMIUM = _chromium()
needs_browser = pytest.mark.skipif(CHROMIUM is None, reason="no Chromium installed "
                                   "(apt-get install chromium; docs/page.md)")
WINDOW = (1200, 850)


def _browser(tmp_path, url, *what):
    # --no-sandbox: CI runs as root, where Chromium's sandbox refuses to start; the page is
    # our own file. --disable-dev-shm-usage: containers' small /dev/shm crashes its renderer.
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
           "--disable-dev-shm-usage",
           "--no-first-run", "--force-device-scale-factor=1", f"--user-data-dir={tmp_path}/prof",
           f"--window-size={WINDOW[0]},{WINDOW[1]}", "--virtual-time-budget=5000", *what, url]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120)


def _state(tmp_path, path, query):
    r = _browser(tmp_path, f"{path.as_uri()}?{query}", "--dump-dom")
    m = re.search(r'<pre id="rp-state"[^>]*>(.*?)</pre>', r.stdout, re.S)
    assert m, r.stderr[-2000:]
    return json.loads(m.group(1).replace("&quot;", '"').replace("&amp;", "&"))


def _screenshot(tmp_path, path, query, name):
    png = tmp_path / f"{name}.png"
    r = _browser(tmp_path, f"{path.as_uri()}?{query}", f"--screenshot={png}")
    assert png.is_file(), r.stderr[-2000:]
    return cv2.imread(str(png))[:, :, ::-1].astype(int)


def _box(shot, rect):
    x, y, w, h = (round(v) for v in rect)
    return shot[y:y + h, x:x + w]


def _curve_pixels(shot, state):
    return int(np.all(np.abs(_box(shot, state["curve"]) - CURVE_RGB) <= 12, axis=-1).sum())


@needs_browser
def test_in_a_browser_the_slider_recolours_the_keypoints_and_a_click_draws_a_curve(
        tmp_path, image):
    xy = _points()
    curves = _opposite_curves(len(xy), WEBCAM.num_timestamps)
    path = page.write_page(tmp_path / "kp.html", page.keypoints_page(
        image, xy, curves, WEBCAM, captured=dt.datetime(2024, 6, 1, 9, 30)))
    morning = _screenshot(tmp_path, path, "t=08:00", "morning")
    evening = _screenshot(tmp_path, path, "t=18:00", "evening")
    clicked = _screenshot(tmp_path, path, f"t=18:00&click={xy[3, 0]:.2f},{xy[3, 1]:.2f}",
                          "clicked")
    state = _state(tmp_path, path, f"t=18:00&click={xy[3, 0]:.2f},{xy[3, 1]:.2f}")
    assert state["ready"] and state["time"] == "18:00" and state["selected"] == 3
    left, top, w, h = state["view"]
    s = w / image.shape[1]
    on_screen = np.column_stack([left + (xy[:, 0] + 0.5) * s, top + (xy[:, 1] + 0.5) * s])
    # Each keypoint's dot: its colour at 08:00 against 18:00 (viridis 0.1 <-> 0.9).
    changed = [np.abs(morning[round(y) - 1:round(y) + 2, round(x) - 1:round(x) + 2]
                      - evening[round(y) - 1:round(y) + 2, round(x) - 1:round(x) + 2]).max() > 60
               for x, y in on_screen]
    assert np.mean(changed) == 1.0, np.flatnonzero(~np.array(changed))
    # Away from every keypoint the image is the same.
    yy, xx = np.mgrid[round(top):round(top + h), round(left):round(left + w)]
    far = np.min(np.hypot(xx[..., None] - on_screen[:, 0], yy[..., None] - on_screen[:, 1]),
                 axis=-1) > 10 * s
    same = np.all(morning[yy[far], xx[far]] == evening[yy[far], xx[far]], axis=-1)
    assert same.mean() > 0.999
    # The curve panel: no curve before a click, a curve after.
    assert _curve_pixels(evening, state) == 0
    assert _curve_pixels(clicked, state) > 300


@needs_browser
def test_in_a_browser_the_page_reads_the_curves_as_predict_does(tmp_path, image):
    """Linear between timestamps; a year wraps from Dec 21 round to Mar 04, a day only when
    asked (``--wrap``)."""
    from rp_jax import predict

    rng = np.random.default_rng(2)
    for schedule, wrap, times in ((WEBCAM, None, ["09:47", "18:00"]), (WEBCAM, True, ["22:00"]),
                                  (CMU, None, ["01-15", "06-30"])):
        xy = _points(5, seed=3)
        curves = rng.random((5, schedule.num_timestamps))
        path = page.write_page(tmp_path / f"{schedule.name}_{wrap}.html", page.keypoints_page(
            image, xy, curves, schedule, wrap=wrap))
        for t in times:
            state = _state(tmp_path, path, f"t={t}&click={xy[2, 0]:.2f},{xy[2, 1]:.2f}")
            when = (dt.datetime(2024, 6, 1, *map(int, t.split(":"))) if ":" in t
                    else dt.datetime(2023, *map(int, t.split("-"))))
            assert state["selected"] == 2
            expected = float(predict.at_time(curves[2], schedule, when, wrap=wrap))
            assert state["score"] == pytest.approx(expected, abs=6e-5), (schedule.name, t)


@needs_browser
def test_in_a_browser_the_map_keeps_other_points_at_other_times(tmp_path):
    rng = np.random.default_rng(4)
    P, T = 120, WEBCAM.num_timestamps
    top_xy = rng.uniform(0, 50, (P, 2))
    kept = np.zeros((T, P), bool)
    kept[:, : P // 2] = np.arange(T)[:, None] < T // 2  # the first half kept in the morning,
    kept[:, P // 2:] = np.arange(T)[:, None] >= T // 2  # the other in the afternoon
    path = page.write_page(tmp_path / "map.html", page.map_page(
        top_xy, rng.random((P, T)), kept, WEBCAM, cameras_xy=[[25, -5]]))
    morning = _screenshot(tmp_path, path, "t=08:00", "morning")
    afternoon = _screenshot(tmp_path, path, "t=17:00", "afternoon")
    state = _state(tmp_path, path, f"t=17:00&click={top_xy[0, 0]},{top_xy[0, 1]}")
    assert state["timestamp"] == 18 and state["kept"] == P // 2 and state["selected"] == 0
    view = state["view"]
    assert np.abs(_box(morning, view) - _box(afternoon, view)).max(axis=-1).astype(bool).sum() > 500
    clicked = _screenshot(tmp_path, path, f"t=17:00&click={top_xy[0, 0]},{top_xy[0, 1]}", "c")
    assert _curve_pixels(afternoon, state) == 0 and _curve_pixels(clicked, state) > 300
