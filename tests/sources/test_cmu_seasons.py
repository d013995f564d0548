"""Tests of the Extended CMU Seasons reader on a tiny layout written here."""

import datetime as dt
import logging
import zoneinfo

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rp_jax.sources import cmu_seasons, images
from rp_jax.sources.layout import LayoutError

NY = zoneinfo.ZoneInfo("America/New_York")
# Looks along world +x, image y down = world -z.
R_EAST = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
INTRINSICS = (
    "c0 OPENCV 64 48 50.0 51.0 31.5 23.5 -0.3 0.1 0.0002 0.0005\n"
    "c1 OPENCV 64 48 52.0 52.0 32.0 24.0 -0.2 0.05 0.0 0.0\n"
)


def _us(*args):
    return round(dt.datetime(*args, tzinfo=NY).timestamp() * 1e6)


def _name(i, cam, us):
    return f"img_{i:05d}_{cam}_{us}us.jpg"


def _gt_line(name, R, C):
    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return f"{name} {w} {x} {y} {z} {C[0]} {C[1]} {C[2]}\n"


def _write_image(path):
    path.parent.mkdir(parents=True, exist_ok=True)
    img = np.random.default_rng(abs(hash(path.name)) % 2**32).integers(
        0, 255, (48, 64, 3), np.uint8
    )
    assert cv2.imwrite(str(path), img)


def _layout(root):
    """slice7: place A (x~0) and B (x~100) seen on Jul 28 2010 and Mar 04 2011, an outlier."""
    (root / "intrinsics.txt").write_text("# id model w h params\n" + INTRINSICS)
    s = root / "slice7"
    entries = []  # (name, C)
    i = 0
    for when in [(2010, 7, 28, 14, 0), (2011, 3, 4, 12, 0)]:
        for place in (0.0, 100.0):
            for k in range(2):
                i += 1
                entries.append(
                    (_name(i, "c0" if k == 0 else "c1", _us(*when) + i), (place + k, 1.0 * k, 0.0))
                )
    entries.append((_name(99, "c0", _us(2010, 7, 28, 15, 0)), (50.0, 50.0, 0.0)))  # outlier
    for name, _ in entries:
        _write_image(s / "database" / name)
    _write_image(s / "database" / _name(98, "c0", _us(2010, 7, 28, 15, 5)))  # no pose
    (s / "ground-truth-database-images-slice7.txt").write_text(
        "".join(_gt_line(n, R_EAST, C) for n, C in entries)
    )
    q_posed = _name(200, "c0", _us(2010, 11, 3, 10, 0))
    q_unposed = _name(201, "c1", _us(2010, 11, 3, 10, 1))
    _write_image(s / "query" / q_posed)
    _write_image(s / "query" / q_unposed)
    (root / "_evaluation").mkdir()
    (root / "_evaluation" / "ground-truth-query-images-slice7.txt").write_text(
        _gt_line(q_posed, R_EAST, (0.5, 0.5, 0.0))
    )
    return entries, q_posed, q_unposed


def test_times_poses_viewpoints_and_slots(tmp_path, caplog):
    entries, q_posed, _ = _layout(tmp_path)
    with caplog.at_level(logging.INFO):
        caps = cmu_seasons.read(tmp_path, slices=[7])
    by_name = {c.image_path.name: c for c in caps}
    # 8 database images in 2 places + 1 posed query; the outlier and unposed images dropped.
    assert len(caps) == 9 and entries[-1][0] not in by_name
    assert (
        "2 no pose" in caplog.text
    )  # a database image and a query and "1 no viewpoint" in caplog.text
    first = by_name[entries[0][0]]
    assert first.time == dt.datetime(2010, 7, 28, 14, 0, 0, 1, tzinfo=NY)
    assert first.time.utcoffset() == dt.timedelta(hours=-4)
    assert first.meta["camera_id"] == "c0" and first.camera.model == "OPENCV"
    # t = -R C, and a point 5 m ahead (and 1 m to the right) projects where expected.
    C = np.array(entries[0][1])
    np.testing.assert_allclose(first.R, R_EAST, atol=1e-12)
    np.testing.assert_allclose(first.t, -R_EAST @ C, atol=1e-12)
    np.testing.assert_allclose(first.center, C, atol=1e-12)
    pin = cmu_seasons.undistorted_camera(first)
    assert pin.model == "PINHOLE" and pin is not None
    for X, uv in [
        (C + [5, 0, 0], (31.5, 23.5)),
        (C + [5, -1, 0], (31.5 + 50 / 5, 23.5)),
        (C + [5, 0, 1], (31.5, 23.5 - 51 / 5)),
    ]:
        x = pin.K @ (first.R @ X + first.t)
        np.testing.assert_allclose(x[:2] / x[2], uv, atol=1e-9)
    # viewpoints: the two places, each seen on both dates, the query joins place A.
    vps = {c.viewpoint for c in caps}
    assert len(vps) == 2
    assert (
        by_name[q_posed].viewpoint == first.viewpoint and by_name[q_posed].meta["kind"] == "query"
    )
    # slots: Jul 28 -> 2, Mar 04 -> 0, Nov 03 -> 8; one traversal per date -> cycle 0 (M = 1)
    slots = {(c.time.month, c.slot) for c in caps}
    assert slots == {(7, 2), (3, 0), (11, 8)}
    assert {c.cycle for c in caps} == {0}
    calendar = cmu_seasons.read(tmp_path, cycle_rule="calendar")
    assert {c.cycle for c in calendar if c.time.year == 2011} == {1}


def test_query_options(tmp_path):
    _, q_posed, q_unposed = _layout(tmp_path)
    no_query = cmu_seasons.read(tmp_path, include_query=False)
    assert all(c.meta["kind"] == "database" for c in no_query) and len(no_query) == 8
    queries = cmu_seasons.read_queries(tmp_path)
    assert [c.image_path.name for c in queries] == [q_posed, q_unposed]
    assert queries[0].has_pose and not queries[1].has_pose
    assert queries[1].camera.K[0, 0] == 52.0


def test_load_image_undistorts(tmp_path):
    entries, _, _ = _layout(tmp_path)
    cap = next(c for c in cmu_seasons.read(tmp_path) if c.image_path.name == entries[0][0])
    out = cmu_seasons.load_image(cap)
    raw = images.read_rgb(cap.image_path)
    assert out.shape == (48, 64, 3) and out.dtype == np.uint8
    np.testing.assert_array_equal(out, images.undistort_image(raw, cap.camera))
    assert np.abs(out.astype(int) - raw).mean() > 1  # it did change the pixels
    assert cap.meta["undistorted_camera"].model == "PINHOLE"


def test_category_map_is_undistorted_like_the_image(tmp_path):
    """The category of a keypoint is read at the pixel it was detected on, in the undistorted
    image: the map must move with the pixels (nearest neighbour, unlabelled outside)."""
    import dataclasses

    entries, _, _ = _layout(tmp_path)
    cap = next(c for c in cmu_seasons.read(tmp_path) if c.image_path.name == entries[0][0])
    blocks = (np.arange(48)[:, None] // 8 * 8 + np.arange(64)[None, :] // 8).astype(np.uint8)
    cv2.imwrite(str(cap.image_path.with_suffix(".png")), np.repeat(blocks[..., None], 3, -1))
    cv2.imwrite(str(tmp_path / "seg.png"), blocks)
    cap = dataclasses.replace(cap, image_path=cap.image_path.with_suffix(".png"),
                              meta={**cap.meta, "segmentation_path": tmp_path / "seg.png"})
    image = cmu_seasons.load_image(cap)[..., 0]
    cmap = cmu_seasons.load_category(cap)
    assert cmap.shape == (48, 64) and cmap.dtype == np.uint8
    labelled = cmap != 255
    assert (cmap[labelled] == image[labelled]).mean() > 0.9  # same pixels, bar block edges
    assert (cmap != blocks).mean() > 0.05  # it did move with the distortion
    np.testing.assert_array_equal(cmu_seasons.camera_matrix(cap), cap.camera.K)


def test_corrupt_image_is_skipped_and_counted(tmp_path, caplog):
    entries, _, _ = _layout(tmp_path)
    (tmp_path / "slice7" / "database" / entries[0][0]).write_bytes(b"")
    with caplog.at_level(logging.INFO):
        caps = cmu_seasons.read(tmp_path)
    assert entries[0][0] not in {c.image_path.name for c in caps}
    assert "1 unreadable" in caplog.text


def test_bad_layouts(tmp_path):
    with pytest.raises(LayoutError) as err:
        cmu_seasons.read(tmp_path)
    msg = str(err.value)
    assert "no intrinsics.txt" in msg and "slice{N}/database/img_*_c0_*us.jpg" in msg
    _layout(tmp_path)
    with pytest.raises(LayoutError, match=r"slices \[6\]"):
        cmu_seasons.read(tmp_path, slices=[6, 7])
    (tmp_path / "slice7" / "ground-truth-database-images-slice7.txt").unlink()
    with pytest.raises(LayoutError, match="ground-truth-database-images-slice7.txt"):
        cmu_seasons.read(tmp_path)


def test_parse_image_name():
    assert cmu_seasons.parse_image_name("img_00122_c1_1303398475046031us.jpg") == (
        122,
        "c1",
        1303398475046031,
    )
    assert cmu_seasons.parse_image_name("img_1_c2_5us.jpg") is None


# --------------------------------------------------------------------------- the real release
# Fixtures below are written as the dataset's README and the public tools that read it
# describe the files (kapture's ``kapture_import_Extended_CMU_Seasons.py``, pixloc's
# ``preprocess_cmu.py``), not by the project's synthetic writer.


def _real_slice(root):
    """slice7 as released: the reference traversal (Apr 4 2011) in ``database/`` with its
    ground truth; queries of Sep 1 and Dec 21 2010 in ``query/``, listed in
    ``test-images-slice7.txt``; the poses of half of them in ``camera-poses/*.txt`` (same
    line format as the database file, spread over several files, one of them empty)."""
    (root / "intrinsics.txt").write_text(INTRINSICS)
    s = root / "slice7"
    database, queries = [], []
    i = 0
    for when, out in [
        ((2011, 4, 4, 11, 0), database),
        ((2010, 9, 1, 13, 0), queries),
        ((2010, 12, 21, 12, 0), queries),
    ]:
        for place in (0.0, 100.0):
            for cam in ("c0", "c1"):
                i += 1
                C = (place + (cam == "c1"), 0.5 * (cam == "c1"), 0.0)
                out.append((_name(i, cam, _us(*when) + i), C))
    for name, _ in database:
        _write_image(s / "database" / name)
    for name, _ in queries:
        _write_image(s / "query" / name)
    (s / "ground-truth-database-images-slice7.txt").write_text(
        "".join(_gt_line(n, R_EAST, C) for n, C in database)
    )
    (s / "test-images-slice7.txt").write_text("".join(f"{n}\n" for n, _ in queries))
    posed = queries[::2]  # about half of the queries have a reference pose
    (s / "camera-poses").mkdir()
    (s / "camera-poses" / "poses_a.txt").write_text(_gt_line(*posed[0][:1], R_EAST, posed[0][1]))
    (s / "camera-poses" / "poses_b.txt").write_text(
        "".join(_gt_line(n, R_EAST, C) for n, C in posed[1:])
    )
    (s / "camera-poses" / "poses_c.txt").write_text("")  # some files are empty
    return database, queries, posed


def test_query_ground_truth_from_camera_poses(tmp_path, caplog):
    database, queries, posed = _real_slice(tmp_path)
    assert not (tmp_path / "_evaluation").exists()
    with caplog.at_level(logging.INFO):
        caps = cmu_seasons.read(tmp_path)
    by_name = {c.image_path.name: c for c in caps}
    # Every database image and every posed query; the unposed queries are counted.
    assert set(by_name) == {n for n, _ in database} | {n for n, _ in posed}
    assert "4 no pose" in caplog.text
    # Seasonal variation: the reference date (Apr 4 -> the paper's Apr 21, slot 1) and the
    # two query dates (Sep 01 -> 3, Dec 21 -> 11), where the reader alone gave one date.
    assert {(c.time.month, c.slot) for c in caps} == {(4, 1), (9, 3), (12, 11)}
    q = by_name[posed[1][0]]
    np.testing.assert_allclose(q.center, posed[1][1], atol=1e-9)
    assert q.meta["kind"] == "query"
    # Queries join the viewpoints of the database images at the same place.
    assert q.viewpoint == by_name[database[2][0]].viewpoint
    # read_queries returns every query, posed or not (R None for the others).
    out = cmu_seasons.read_queries(tmp_path)
    assert sorted(c.image_path.name for c in out) == sorted(n for n, _ in queries)
    have = {c.image_path.name for c in out if c.has_pose}
    assert have == {n for n, _ in posed}
    assert all(c.R is None and c.t is None for c in out if c.image_path.name not in have)


def test_query_ground_truth_files_are_merged(tmp_path):
    """``camera-poses/*.txt`` and the two older places are all read (layouts rendered before
    the synthetic world wrote ``camera-poses/`` keep their query poses)."""
    _, queries, posed = _real_slice(tmp_path)
    extra = queries[1]
    (tmp_path / "_evaluation").mkdir()
    (tmp_path / "_evaluation" / "ground-truth-query-images-slice7.txt").write_text(
        _gt_line(extra[0], R_EAST, extra[1])
    )
    poses = cmu_seasons.read_query_ground_truth(tmp_path, 7)
    assert set(poses) == {n for n, _ in posed} | {extra[0]}
    np.testing.assert_allclose(poses[extra[0]][1], -R_EAST @ np.array(extra[1]), atol=1e-12)


def test_original_cmu_seasons_rect_names(tmp_path, caplog):
    """The original CMU Seasons names its images ``img_<i>_<c0|c1>_<us>us_rect.jpg``: they
    are already undistorted (its README: PINHOLE with the same fx fy cx cy), so they are
    read with a PINHOLE camera and not undistorted again. A .jpg with another name is
    counted, not silently skipped."""
    (tmp_path / "intrinsics.txt").write_text(INTRINSICS)
    s = tmp_path / "slice7"
    names = [f"img_{i:05d}_c0_{_us(2011, 4, 4, 11, 0) + i}us_rect.jpg" for i in range(1, 4)]
    for name in names:
        _write_image(s / "database" / name)
    _write_image(s / "database" / "thumbnail.jpg")
    (s / "ground-truth-database-images-slice7.txt").write_text(
        "".join(_gt_line(n, R_EAST, (0.5 * k, 0.0, 0.0)) for k, n in enumerate(names))
    )
    with caplog.at_level(logging.INFO):
        caps = cmu_seasons.read(tmp_path)
    assert sorted(c.image_path.name for c in caps) == names
    assert "4 read" in caplog.text and "1 no time" in caplog.text
    cap = caps[0]
    assert cmu_seasons.parse_image_name(names[0])[1:] == ("c0", _us(2011, 4, 4, 11, 0) + 1)
    assert cap.camera.model == "PINHOLE" and not np.any(cap.camera.distortion)
    np.testing.assert_allclose(cap.camera.K[0], [50.0, 0.0, 31.5])
    np.testing.assert_array_equal(cmu_seasons.load_image(cap), images.read_rgb(cap.image_path))


# Issue 14, item 7: a bad pose line is named by file and line, never dropped in silence.

@pytest.mark.parametrize("values,what", [
    ("1 0 0 0 nan 1 0", "NaN or infinite"),
    ("nan 0 0 0 0 1 0", "NaN or infinite"),
    ("1 0 0 0 inf 1 0", "NaN or infinite"),
    ("0 0 0 0 0 1 0", "norm 0"),
])
def test_bad_pose_line_names_file_and_line(tmp_path, values, what):
    entries, _, _ = _layout(tmp_path)
    gt = tmp_path / "slice7" / "ground-truth-database-images-slice7.txt"
    lines = gt.read_text().splitlines()
    lines[2] = f"{entries[2][0]} {values}"
    gt.write_text("\n".join(lines) + "\n")
    with pytest.raises(LayoutError) as err:
        cmu_seasons.read(tmp_path)
    msg = str(err.value)
    assert f"{gt}:3:" in msg and entries[2][0] in msg and what in msg
