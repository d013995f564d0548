"""Tests of the RobotCar Seasons reader and writer on tiny layouts written here, and on lines
in the exact shape of the public files and tools (each test says where the shape comes from)."""

import datetime as dt
import logging

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rp_jax import sun
from rp_jax.localize.submission import read_submission, write_submission
from rp_jax.sources import robotcar_seasons as rs
from rp_jax.sources.capture import Camera
from rp_jax.sources.layout import LayoutError

# The rear camera's intrinsics as the public code that reads the release quotes them (S2DHM's
# and descriptor-disambiguation's RobotCar loaders): f = 400, (cx, cy) = (508.222931, 498.187378).
REAR_INTRINSICS = "fx 400.000000\nfy 400.000000\ncx 508.222931\ncy 498.187378\n"
SIZE = (40, 32)  # tiny images; the release's are 1024 x 1024


def _pose(seed):
    R = Rotation.from_rotvec(np.random.default_rng(seed).normal(size=3)).as_matrix()
    return R, np.array([seed, 2.0 * seed, -1.0])


def _camera(f, cx, cy):
    return Camera("PINHOLE", *SIZE, np.array([[f, 0, cx], [0, f, cy], [0, 0, 1.0]]))


def _write_image(path):
    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), np.full((SIZE[1], SIZE[0], 3), 128, np.uint8))


def _layout(root):
    """overcast-reference (posed by the NVM) and night, two timestamps, three cameras."""
    cams = {"left": _camera(20.0, 19.5, 15.5), "rear": _camera(21.0, 20.0, 16.0),
            "right": _camera(22.0, 18.5, 14.5)}
    for name, cam in cams.items():
        rs.write_intrinsics(root, name, cam)
    times = {"overcast-reference": [1417176458999821, 1417176459999821],
             "night": [1418235223450115, 1418235224450115]}
    poses = {}
    for condition, stamps in times.items():
        for k, us in enumerate(stamps):
            for j, camera in enumerate(rs.CAMERAS):
                name = rs.image_name(condition, camera, us)
                _write_image(root / "images" / name)
                poses[name] = _pose(10 * k + j + (100 if condition == "night" else 1))
    ref = {n: p for n, p in poses.items() if n.startswith(rs.REFERENCE_CONDITION)}
    rs.write_nvm(root / rs.NVM_PATH, [rs.NvmImage.from_pose(n, *p, focal=21.0)
                                      for n, p in ref.items()])
    rs.write_query_lists(root, size=SIZE)
    night = {n: p for n, p in poses.items() if n.startswith("night/")}
    rs.write_v2_poses(root / rs.V2_TRAIN, night)
    return cams, ref, night


def test_write_then_read_round_trips(tmp_path):
    cams, ref, night = _layout(tmp_path)
    assert rs.find_conditions(tmp_path) == ["overcast-reference", "night"]
    assert rs.find_cameras(tmp_path) == {"overcast-reference": list(rs.CAMERAS),
                                         "night": list(rs.CAMERAS)}
    caps = rs.read_captures(tmp_path)
    assert len(caps) == 12 and [c.time for c in caps] == sorted(c.time for c in caps)
    for cap in caps:
        cond, camera, us = rs.parse_image_name(cap.image_id)
        assert cap.viewpoint == cond == cap.meta["condition"] and cap.meta["camera"] == camera
        np.testing.assert_allclose(cap.camera.K, cams[camera].K)
        assert cap.camera.size == SIZE and cap.time == rs.capture_time(us)
        if cond == rs.REFERENCE_CONDITION:
            np.testing.assert_allclose(cap.R, ref[cap.image_id][0], atol=1e-12)
            np.testing.assert_allclose(cap.t, ref[cap.image_id][1], atol=1e-9)
        else:
            assert cap.R is None and cap.t is None
    assert sorted(c.image_id for c in rs.read_captures(tmp_path, ["night"])) == sorted(night)
    for name, (R, t) in rs.reference_poses(tmp_path).items():
        np.testing.assert_allclose(R, ref[name][0], atol=1e-12)
        np.testing.assert_allclose(t, ref[name][1], atol=1e-9)
    queries = rs.read_query_list(tmp_path / "queries/night_queries_with_intrinsics.txt")
    assert sorted(queries) == sorted(night)
    for name, cam in queries.items():
        assert cam.model == "PINHOLE" and cam.size == SIZE
        np.testing.assert_allclose(cam.K, cams[rs.parse_image_name(name)[1]].K)
    assert not (tmp_path / "queries/overcast-reference_queries_with_intrinsics.txt").exists()
    for name, (R, t) in rs.read_v2_poses(tmp_path / rs.V2_TRAIN).items():
        np.testing.assert_allclose(R, night[name][0], atol=1e-12)
        np.testing.assert_allclose(t, night[name][1], atol=1e-9)


def test_nvm_names_are_written_as_the_release_writes_them(tmp_path):
    # The release's all.nvm names its images ./<condition>/<camera>/<ts>.png although the
    # files are .jpg (the benchmark's issue threads; hloc's colmap_from_nvm strips './' and maps
    # png to jpg, S2DHM's from_nvm keeps split('/')[1:4]).
    R, t = _pose(3)
    path = rs.write_nvm(tmp_path / "m.nvm", [rs.NvmImage.from_pose(
        "overcast-reference/rear/1417176458999821.jpg", R, t, focal=400.0)])
    lines = path.read_text().splitlines()
    assert lines[:3] == ["NVM_V3", "", "1"]
    assert lines[3].startswith("./overcast-reference/rear/1417176458999821.png 400.0 ")
    assert lines[3].endswith(" 0.0 0") and len(lines[3].split()) == 11


def test_reads_an_nvm_camera_line_as_hloc_does(tmp_path):
    # NVM_V3 (VisualSFM): '<name> <f> <qw qx qy qz> <camera centre> <radial> 0'; the README:
    # the quaternion is world-to-camera and t = -(R * c); hloc: camera_center_to_translation.
    R, t = _pose(7)
    C = -R.T @ t
    q = Rotation.from_matrix(R).as_quat()  # x y z w
    line = (f"./night-rain/rear/1418840689734892.png 400 {q[3]} {q[0]} {q[1]} {q[2]} "
            f"{C[0]} {C[1]} {C[2]} 0 0")
    (tmp_path / "all.nvm").write_text(f"NVM_V3 \n\n1\n{line}\n\n2\n1 2 3 4 5 6 0\n")
    [image] = rs.read_nvm(tmp_path / "all.nvm")
    assert image.name == "night-rain/rear/1418840689734892.jpg" and image.focal == 400.0
    np.testing.assert_allclose(image.pose[0], R, atol=1e-12)
    np.testing.assert_allclose(image.pose[1], t, atol=1e-9)


def test_reads_an_hloc_query_list_line(tmp_path):
    # hloc's pipelines/RobotCar/pipeline.py generate_query_list (and hfnet's
    # generate_robotcar_query_list.py) write 'name SIMPLE_RADIAL 1024 1024 fx cx cy 0.0'.
    path = tmp_path / "night_queries_with_intrinsics.txt"
    path.write_text("night/rear/1418235223450115.jpg SIMPLE_RADIAL 1024 1024 400.000000 "
                    "508.222931 498.187378 0.0")
    [(name, cam)] = rs.read_query_list(path).items()
    assert name == "night/rear/1418235223450115.jpg"
    assert cam.model == "PINHOLE" and cam.size == (1024, 1024)
    # COLMAP's (0, 0) is the top-left corner, OpenCV's the top-left pixel's centre.
    np.testing.assert_allclose(cam.K, [[400, 0, 507.722931], [0, 400, 497.687378], [0, 0, 1]])


def test_query_lines_match_hloc_from_the_intrinsics_files(tmp_path):
    # hloc reads the second token of the first four lines as fx, fy, cx, cy.
    (tmp_path / "intrinsics").mkdir()
    (tmp_path / "intrinsics/rear_intrinsics.txt").write_text(REAR_INTRINSICS)
    _write_image(tmp_path / "images/dusk/rear/1424450252186877.jpg")
    assert rs.read_intrinsics(tmp_path / "intrinsics/rear_intrinsics.txt") == (
        400.0, 400.0, 508.222931, 498.187378)
    assert rs.query_list_lines(tmp_path, "dusk") == [
        "dusk/rear/1424450252186877.jpg SIMPLE_RADIAL 1024 1024 400.0 508.222931 498.187378 0.0"]
    swapped = "cy 498.187378\ncx 508.222931\nfy 400.000000\nfx 400.000000\n"
    (tmp_path / "intrinsics/rear_intrinsics.txt").write_text(swapped)
    assert rs.read_intrinsics(tmp_path / "intrinsics/rear_intrinsics.txt") == (
        400.0, 400.0, 508.222931, 498.187378)


def test_reads_a_v2_train_line_as_kapture_does(tmp_path):
    # kapture's read_robotcar_v2_train: the name (png -> jpg), then [R|t] from the row-major
    # matrix's first 12 numbers, inverted: the file holds the camera's pose in the world.
    line = "night/rear/1418235223450115.png 0 -1 0 11 1 0 0 -2 0 0 1 3 0 0 0 1"
    (tmp_path / "v2.txt").write_text(line + "\n\n")
    [(name, (R, t))] = rs.read_v2_poses(tmp_path / "v2.txt").items()
    assert name == "night/rear/1418235223450115.jpg"
    np.testing.assert_allclose(-R.T @ t, [11, -2, 3])
    np.testing.assert_allclose(R, [[0, 1, 0], [-1, 0, 0], [0, 0, 1]])


def test_submission_names_drop_the_condition_as_the_evaluation_expects(tmp_path):
    # The README's example line; hloc's localize_sfm(prepend_camera_name=True) and kapture's
    # export_LTVL2020 --prepend_cam write '<camera>/<ts>.jpg', no condition.
    example = ("rear/1417178853389469.jpg 0.655230866337965 -0.536609290501044 "
               "-0.340346549997501 -0.408516459863989 24.094399999999997 24.855200000000004 "
               "-120.244000000000028")
    (tmp_path / "example.txt").write_text(example + "\n")
    [(name, (R, t))] = read_submission(tmp_path / "example.txt").items()
    queries = ["night/rear/1418235223450115.jpg", "dawn/left/1418721355537204.jpg",
               "overcast-winter/right/1447411560581573.jpg"]
    for q in queries:
        assert rs.submission_name(q) == q.split("/")[-2] + "/" + q.split("/")[-1]  # hloc's rule
    out = write_submission(tmp_path / "RobotCar_eval_rp.txt",
                           {rs.submission_name(q): (R, t) for q in queries})
    lines = out.read_text().splitlines()
    assert sorted(line.split()[0] for line in lines) == [
        "left/1418721355537204.jpg", "rear/1418235223450115.jpg",
        "right/1447411560581573.jpg"]
    assert all(len(line.split()) == len(example.split()) == 8 for line in lines)
    back = read_submission(out)["rear/1418235223450115.jpg"]
    np.testing.assert_allclose(back[0], R, atol=1e-12)
    np.testing.assert_allclose(back[1], t)


def test_capture_time_is_london_wall_clock_in_winter_and_summer():
    # The reference traversal: 2014-11-28 12:07:38 UTC, GMT.
    winter = rs.capture_time(1417176458999821)
    assert (winter.hour, winter.minute) == (12, 7) and winter.utcoffset() == dt.timedelta(0)
    assert winter.date() == rs.CAPTURE_DATES["overcast-reference"]
    summer_us = round(dt.datetime(2015, 5, 22, 13, 0, tzinfo=dt.UTC).timestamp() * 1e6)
    summer = rs.capture_time(summer_us)
    assert summer.hour == 14 and summer.utcoffset() == dt.timedelta(hours=1)  # BST
    assert summer.tzname() == "BST" and winter.tzname() == "GMT"


def test_a_malformed_query_list_names_the_file_and_line(tmp_path):
    path = tmp_path / "night_queries_with_intrinsics.txt"
    path.write_text("night/rear/1.jpg SIMPLE_RADIAL 1024 1024 400 508.2 498.1 0.0\n"
                    "night/rear/2.jpg SIMPLE_RADIAL 1024 1024 400 508.2 0.0\n")
    with pytest.raises(LayoutError, match=rf"{path}:2: expected 'name SIMPLE_RADIAL"):
        rs.read_query_list(path)
    path.write_text("night/rear/1.jpg OPENCV 1024 1024 400 400 508 498 0 0 0 0\n")
    with pytest.raises(LayoutError, match=r":1: .*OPENCV with 8 parameters"):
        rs.read_query_list(path)


@pytest.mark.parametrize("text, line_no, what", [
    ("NVM_V3\n\n2\n./a/rear/1.png 400 1 0 0 0 0 0 0 0 0\n./a/rear/2.png 400 1 0 0 0 0 0 0\n",
     5, "9 fields"),
    ("NVM_V3\n\nmany\n", 3, "number of cameras"),
    ("NVM_V3\n\n1\n./a/rear/1.png 400 0 0 0 0 1 2 3 0 0\n", 4, "norm 0"),
    ("NVM_V3\n\n1\n./a/rear/1.png 400 1 0 0 0 nan 2 3 0 0\n", 4, "NaN"),
    ("NVM_V3\n\n2\n./a/rear/1.png 400 1 0 0 0 0 0 0 0 0\n", 5, "end of file"),
])
def test_a_malformed_nvm_names_the_file_and_line(tmp_path, text, line_no, what):
    path = tmp_path / "all.nvm"
    path.write_text(text)
    with pytest.raises(LayoutError, match=rf"{path}:{line_no}: .*{what}"):
        rs.read_nvm(path)


def test_malformed_intrinsics_and_v2_lines_are_named(tmp_path):
    path = tmp_path / "rear_intrinsics.txt"
    path.write_text("fx 400\nfy 400\ncx 508\n")
    with pytest.raises(LayoutError, match=rf"{path}: 3 lines; expected four"):
        rs.read_intrinsics(path)
    path.write_text("fx 400\nfy\ncx 508\ncy 498\n")
    with pytest.raises(LayoutError, match=rf"{path}:2: expected '<fx|fy|cx|cy> <number>'"):
        rs.read_intrinsics(path)
    path = tmp_path / "robotcar_v2_train.txt"
    path.write_text("night/rear/1.png 1 0 0 0 0 1 0 0 0 0 1\n")
    with pytest.raises(LayoutError, match=rf"{path}:1: .*11 numbers"):
        rs.read_v2_poses(path)


def test_missing_parts_of_the_layout_are_named(tmp_path, caplog):
    with pytest.raises(LayoutError, match=r"missing images/; intrinsics/<camera>_intrinsics"):
        rs.read_captures(tmp_path)
    _layout(tmp_path)
    (tmp_path / "images/fog").mkdir()
    with caplog.at_level(logging.WARNING):
        assert "fog" not in rs.find_conditions(tmp_path)
    assert "fog is not a RobotCar Seasons condition" in caplog.text
    with pytest.raises(LayoutError, match=r"missing images/snow/"):
        rs.read_captures(tmp_path, ["snow"])
    (tmp_path / "intrinsics/right_intrinsics.txt").unlink()
    with pytest.raises(LayoutError, match=r"right/.*no .*right_intrinsics.txt"):
        rs.read_captures(tmp_path)


def test_each_condition_has_its_traversal_on_the_readmes_capture_date():
    """Two independent sources: the README's capture dates and the RobotCar folder names that
    public code maps RobotCar Seasons images to."""
    assert set(rs.TRAVERSALS) == set(rs.CONDITIONS) == set(rs.CAPTURE_DATES)
    for condition in rs.CONDITIONS:
        start = rs.traversal_start(condition)
        assert start.date() == rs.CAPTURE_DATES[condition], condition
        assert start.tzinfo == dt.UTC
    local = {c: rs.capture_time(int(rs.traversal_start(c).timestamp() * 1e6))
             for c in ("night", "night-rain", "dawn", "sun")}
    assert local["night"].hour >= 18 and local["night-rain"].hour >= 18  # GMT in December
    assert local["dawn"].hour == 9 and local["sun"].hour == 14
    oxford = (51.752, -1.2577)
    elevation = {c: float(sun.solar_position(sun.unix_seconds(rs.traversal_start(c)), *oxford)[0])
                 for c in rs.CONDITIONS}
    assert 0 < elevation["dawn"] < 10 and 0 < elevation["dusk"] < 10  # a low sun, not a dark sky
    assert elevation["night"] < -18 and elevation["night-rain"] < -18  # astronomical night
    assert min(v for c, v in elevation.items() if "night" not in c) > 0  # every other by day
    with pytest.raises(ValueError, match="not a RobotCar Seasons condition"):
        rs.traversal_start("fog")
