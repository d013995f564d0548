"""End-to-end ground truth of tiny viewpoints: records, labels, caching, resume, parallel."""

import json

import numpy as np
import pytest

from rp_jax.groundtruth import (
    RECORD_KEYS,
    GroundTruthConfig,
    attach_patches,
    label_viewpoint,
    label_viewpoints,
)
from rp_jax.groundtruth.viewpoint import TIME_FIELDS
from tests.groundtruth import _scenes
from tests.groundtruth._scenes import make_capture, shifted, textured_image

T = 4  # slot 3 never has an image
STATIC = GroundTruthConfig(detector="sift", max_keypoints=150, verification="static")


def _static_viewpoint(viewpoint="vp0", seed=0):
    """2 cycles x 3 slots of a static webcam, one unreadable image, slot 3 empty."""
    base = textured_image(seed)
    spec = [  # (image id, cycle, slot, image or None)
        ("c0s0", 0, 0, base),
        ("c0s1", 0, 1, shifted(base, 0.4, -0.3, gain=0.9, seed=1)),
        ("c0s2", 0, 2, shifted(base, 0.2, 0.1, gain=0.35, noise=18.0, seed=2)),  # dusk
        ("c1s0", 1, 0, shifted(base, -0.3, 0.2, gain=1.1, seed=3)),
        ("c1s1", 1, 1, shifted(base, 0.1, 0.4, gain=0.95, seed=4)),
        ("c1s1b", 1, 1, None),  # unreadable: must not count in m_{1,1}
        ("c1s2", 1, 2, shifted(base, 12.0, 0.0)),  # camera knocked 12 px: no static inliers
    ]
    captures = []
    for image_id, cycle, slot, img in spec:
        captures.append(make_capture(image_id, cycle, slot, viewpoint=viewpoint))
        _scenes.IMAGES[f"{viewpoint}/{image_id}"] = img
    return captures


def _assert_records_equal(r1, r2):
    assert set(r1) == set(r2)
    assert set(r1) in (set(RECORD_KEYS), set(RECORD_KEYS) - {"patch"})
    for k in r1:
        np.testing.assert_array_equal(r1[k], r2[k], err_msg=k)


def test_static_viewpoint_records_and_labels():
    caps = _static_viewpoint()
    rec = label_viewpoint(
        caps, load_image=_scenes.load_from_registry, num_timestamps=T, config=STATIC
    )
    n = rec["xy"].shape[0]
    assert set(rec) == set(RECORD_KEYS) and n > 300
    shapes = {
        "patch": (n, 64, 64, 3),
        "xy": (n, 2),
        "xy_normalized": (n, 2),
        "image_size": (n, 2),
        "label": (n, T),
        "label_mask": (n, T),
        "category": (n,),
        "descriptor": (n, 128),
        "time": (n, len(TIME_FIELDS)),
        "cycle": (n,),
        "slot": (n,),
        "viewpoint": (n,),
        "image_id": (n,),
        "keypoint_id": (n,),
    }
    for k, s in shapes.items():
        assert rec[k].shape == s, k
    assert rec["patch"].dtype == np.uint8 and rec["label"].dtype == np.float32
    assert rec["label_mask"].dtype == bool and rec["category"].dtype == np.int32
    assert set(rec["image_id"]) == {"c0s0", "c0s1", "c0s2", "c1s0", "c1s1", "c1s2"}
    assert (rec["category"] == -1).all()
    np.testing.assert_array_equal(rec["image_size"][0], [_scenes.WIDTH, _scenes.HEIGHT])
    np.testing.assert_allclose(rec["xy_normalized"] * rec["image_size"], rec["xy"], atol=1e-3)
    assert rec["time"][0].tolist()[3:] == [8, 30, -300]  # 08:30 at UTC-5, cycle 0 slot 0

    # Masks: slot 3 has no image at all.
    np.testing.assert_array_equal(rec["label_mask"], np.tile([True, True, True, False], (n, 1)))
    assert (rec["label"][:, 3] == 0).all()
    lab = rec["label"]
    assert lab.min() >= 0 and lab.max() <= 1
    # m_j = (2, 2, 2): the unreadable image is not counted, so slot 1 reaches 1.0.
    np.testing.assert_allclose(lab[:, :3] * 2, np.round(lab[:, :3] * 2), atol=1e-6)
    own = rec["slot"]
    # The own image counts as an inlier: at least 1/2 in the own slot.
    assert (lab[np.arange(n), own] >= 0.5).all()
    # The 12-px-shifted image never holds a static inlier, so slot 2 stays <= 1/2 for
    # points of other images.
    not_shifted = rec["image_id"] != "c1s2"
    assert (lab[not_shifted, 2] <= 0.5 + 1e-6).all()
    shifted_pts = rec["image_id"] == "c1s2"
    # ... and its own points have only themselves, except matches to nothing else.
    np.testing.assert_allclose(lab[shifted_pts], np.tile([0, 0, 0.5, 0], (shifted_pts.sum(), 1)))
    # Day images repeat each other well; the dusk image repeats them less.
    day = (rec["image_id"] == "c0s0") | (rec["image_id"] == "c1s0")
    assert lab[day, 1].mean() > 0.6
    assert lab[day, 1].mean() > lab[day, 2].mean() + 0.2
    assert (lab[day, 1] == 1.0).any()


def test_unassigned_capture_and_mixed_viewpoints_are_refused():
    caps = _static_viewpoint()
    bad = [caps[0], make_capture("x", 0, 0, viewpoint="other")]
    with pytest.raises(ValueError, match="share a viewpoint"):
        label_viewpoint(bad, load_image=_scenes.load_from_registry, num_timestamps=T)
    with pytest.raises(ValueError, match=r"slot 5 outside"):
        label_viewpoint(
            [make_capture("y", 0, 5)], load_image=_scenes.load_from_registry, num_timestamps=T
        )


class _Loader:
    """Counts calls; raises after ``fail_after`` calls (an interrupted build)."""

    def __init__(self, fail_after=None):
        self.calls, self.fail_after = [], fail_after

    def __call__(self, capture):
        if self.fail_after is not None and len(self.calls) >= self.fail_after:
            raise RuntimeError("interrupted")
        self.calls.append(capture.image_id)
        return _scenes.load_from_registry(capture)


def _without_patches(records):
    return {k: v for k, v in records.items() if k != "patch"}


def test_resume_redoes_only_missing_work(tmp_path):
    caps = _static_viewpoint()
    reference = label_viewpoint(
        caps, load_image=_scenes.load_from_registry, num_timestamps=T, config=STATIC
    )
    cache = tmp_path / "cache"
    # Without patches, an image is loaded only to detect its interest points.
    kw = {"num_timestamps": T, "config": STATIC, "cache_dir": cache, "with_patches": False}

    first = _Loader(fail_after=3)
    with pytest.raises(RuntimeError, match="interrupted"):
        label_viewpoint(caps, load_image=first, **kw)
    # Images are detected on threads, so which three were loaded before the interruption
    # depends on the scheduling (under load it is not always the first three).
    assert len(first.calls) >= 3
    assert len(list(cache.glob("features/*/*/*.npz"))) == len(set(first.calls) - {"c1s1b"})
    assert not list(cache.glob("labels/*/*.npz"))

    resumed = _Loader()
    records = label_viewpoint(caps, load_image=resumed, **kw)
    assert "patch" not in records
    _assert_records_equal(records, _without_patches(reference))
    # Only the images not cached were loaded again (the unreadable one always is).
    cached = set(first.calls) - {"c1s1b"}
    assert sorted(resumed.calls) == sorted({c.image_id for c in caps} - cached)

    again = _Loader()
    _assert_records_equal(label_viewpoint(caps, load_image=again, **kw),
                          _without_patches(reference))
    assert again.calls == []  # finished viewpoint: read back

    # Patches are cut from the images on return (the caches hold none), identical to the
    # uncached run; the 6 readable images are read once each.
    with_patches = _Loader()
    kw_patches = {**kw, "with_patches": True}
    _assert_records_equal(label_viewpoint(caps, load_image=with_patches, **kw_patches), reference)
    assert sorted(with_patches.calls) == sorted(c.image_id for c in caps if c.image_id != "c1s1b")
    cached_bytes = sum(f.stat().st_size for f in cache.rglob("*.npz"))
    assert cached_bytes < reference["patch"].nbytes / 4

    for f in cache.glob("labels/*/*.npz"):
        f.unlink()  # lose the viewpoint file: labels are redone from cached features
    redo = _Loader()
    _assert_records_equal(label_viewpoint(caps, load_image=redo, **kw), _without_patches(reference))
    assert redo.calls == ["c1s1b"]  # only the unreadable image is retried

    # Changing the captures (a different slot assignment) invalidates the viewpoint file.
    moved = [c.with_slot(c.cycle, 0) if c.image_id == "c0s2" else c for c in caps]
    relabelled = label_viewpoint(moved, load_image=_Loader(), **kw)
    assert not np.array_equal(relabelled["slot"], reference["slot"])


def test_attach_patches_names_an_image_that_became_unreadable(tmp_path):
    caps = _static_viewpoint()
    kw = {"num_timestamps": T, "config": STATIC, "cache_dir": tmp_path, "with_patches": False}
    records = label_viewpoint(caps, load_image=_scenes.load_from_registry, **kw)
    gone = caps[0].image_id

    def loader(capture):
        return None if capture.image_id == gone else _scenes.load_from_registry(capture)

    with pytest.raises(ValueError, match="unreadable now"):
        attach_patches(records, caps, loader)
    # A subset of rows (as after select_records) gets exactly the full run's patches.
    full = attach_patches(records, caps, _scenes.load_from_registry)
    rows = np.arange(0, len(records["xy"]), 7)
    subset = attach_patches({k: v[rows] for k, v in records.items()}, caps,
                            _scenes.load_from_registry)
    np.testing.assert_array_equal(subset["patch"], full["patch"][rows])


def test_parallel_viewpoints_equal_serial(tmp_path):
    vps = {"vpA": _static_viewpoint("vpA", seed=5), "vpB": _static_viewpoint("vpB", seed=6)}
    kw = {"load_image": _scenes.load_from_registry, "num_timestamps": T, "config": STATIC}
    serial = dict(label_viewpoints(vps, workers=1, **kw))
    # Worker processes are spawned: they read the same images from lossless PNGs.
    on_disk = {vp: _scenes.to_disk(caps, tmp_path / "images") for vp, caps in vps.items()}
    kw["load_image"] = _scenes.load_from_disk
    parallel = dict(label_viewpoints(on_disk, workers=2, cache_dir=tmp_path / "cache", **kw))
    assert set(serial) == set(parallel) == {"vpA", "vpB"}
    for vp in vps:
        _assert_records_equal(serial[vp], parallel[vp])
        assert (serial[vp]["viewpoint"] == vp).all()


def test_records_do_not_depend_on_the_thread_count():
    # Detection (images in parallel) and matching (image pairs in parallel) on 1 or 3 threads.
    caps = _static_viewpoint("vpT", seed=8)
    kw = {"load_image": _scenes.load_from_registry, "num_timestamps": T, "config": STATIC}
    one = label_viewpoint(caps, matching_threads=1, **kw)
    three = label_viewpoint(caps, matching_threads=3, **kw)
    _assert_records_equal(one, three)
    assert one["label"].max() > 0  # some points repeat: the comparison is not of empty labels


def test_categories_are_read_at_keypoints(tmp_path):
    caps = _static_viewpoint("vpcat", seed=7)[:2]
    cat_map = np.full((_scenes.HEIGHT, _scenes.WIDTH), 255, np.uint8)
    cat_map[:, : _scenes.WIDTH // 2] = 1  # left half vegetation, right half unlabelled
    kw = {"load_image": _scenes.load_from_registry, "num_timestamps": T, "config": STATIC}
    # First without categories (cached features have none), then with: read, not stale.
    plain = label_viewpoint(caps, cache_dir=tmp_path / "a", **kw)
    assert (plain["category"] == -1).all()
    rec = label_viewpoint(caps, cache_dir=tmp_path / "a", load_category=lambda c: cat_map, **kw)
    left = np.floor(rec["xy"][:, 0] + 0.5) < _scenes.WIDTH // 2
    assert left.any() and (~left).any()
    np.testing.assert_array_equal(rec["category"], np.where(left, 1, -1))


def test_orb_viewpoint_and_meta_counts(tmp_path):
    caps = _static_viewpoint("vporb", seed=8)
    config = GroundTruthConfig(detector="orb", max_keypoints=150, verification="static")
    rec = label_viewpoint(
        caps,
        load_image=_scenes.load_from_registry,
        num_timestamps=T,
        config=config,
        cache_dir=tmp_path,
    )
    assert rec["descriptor"].shape[1] == 32 and rec["descriptor"].dtype == np.float32
    assert np.array_equal(rec["descriptor"], np.round(rec["descriptor"]))  # raw bytes
    day = rec["image_id"] == "c0s0"
    assert rec["label"][day, 1].mean() > 0.5
    meta = json.loads(next(tmp_path.glob("labels/*/*.json")).read_text())
    assert meta["num_images"] == 7 and meta["num_unreadable"] == 1
    assert meta["unreadable"] == ["c1s1b"]
    assert meta["num_interest_points"] == len(rec["xy"])


def test_caches_are_redone_when_an_image_file_changes(tmp_path):
    caps = _static_viewpoint("vpfile", seed=9)[:3]
    on_disk = _scenes.to_disk(caps, tmp_path / "images")
    kw = {
        "load_image": _scenes.load_from_disk,
        "num_timestamps": T,
        "config": STATIC,
        "cache_dir": tmp_path / "cache",
        "with_patches": False,
    }
    first = label_viewpoint(on_disk, **kw)
    # Replace one image by another (same name): its features and the viewpoint's labels
    # must not be served from the cache.
    changed = on_disk[0].image_path
    other = _scenes.load_from_disk(on_disk[1])[::-1].copy()
    import cv2

    cv2.imwrite(str(changed), cv2.cvtColor(other, cv2.COLOR_RGB2BGR))
    second = label_viewpoint(on_disk, **kw)
    rows = second["image_id"] == on_disk[0].image_id
    first_rows = first["image_id"] == on_disk[0].image_id
    assert not np.array_equal(second["xy"][rows], first["xy"][first_rows])


# Issue 14, item 4: caches keyed by what they depend on.

def _bmp_viewpoint(tmp_path, viewpoint, seed):
    """Captures on disk as BMP: a file of the same image size has the same byte size."""
    import dataclasses

    import cv2

    caps = _static_viewpoint(viewpoint, seed=seed)[:3]
    out = []
    for c in caps:
        path = tmp_path / "images" / viewpoint / f"{c.image_id}.bmp"
        path.parent.mkdir(parents=True, exist_ok=True)
        img = _scenes.IMAGES[f"{viewpoint}/{c.image_id}"]
        assert cv2.imwrite(str(path), cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
        out.append(dataclasses.replace(c, image_path=path))
    return out


def test_caches_see_new_content_behind_the_same_size_and_mtime(tmp_path):
    import os

    import cv2

    caps = _bmp_viewpoint(tmp_path, "vpsame", seed=10)
    kw = {"load_image": _scenes.load_from_disk, "num_timestamps": T, "config": STATIC,
          "with_patches": False}
    first = label_viewpoint(caps, cache_dir=tmp_path / "cache", **kw)
    path = caps[0].image_path
    st = path.stat()
    other = textured_image(99)  # another scene, written over it: same size, same mtime
    assert cv2.imwrite(str(path), cv2.cvtColor(other, cv2.COLOR_RGB2BGR))
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))
    assert (path.stat().st_size, path.stat().st_mtime_ns) == (st.st_size, st.st_mtime_ns)
    second = label_viewpoint(caps, cache_dir=tmp_path / "cache", **kw)
    fresh = label_viewpoint(caps, cache_dir=tmp_path / "fresh", **kw)
    _assert_records_equal(second, fresh)
    rows = first["image_id"] == caps[0].image_id
    assert not np.array_equal(first["xy"][rows], second["xy"][second["image_id"] ==
                                                              caps[0].image_id])


def test_caches_see_a_rewritten_category_map(tmp_path):
    import dataclasses

    import cv2

    caps = _bmp_viewpoint(tmp_path, "vpseg", seed=11)
    seg = []
    for c in caps:
        p = tmp_path / "segmentation" / f"{c.image_id}.png"
        p.parent.mkdir(parents=True, exist_ok=True)
        assert cv2.imwrite(str(p), np.full((_scenes.HEIGHT, _scenes.WIDTH), 1, np.uint8))
        seg.append(dataclasses.replace(c, meta={**c.meta, "segmentation_path": p}))

    def load_category(capture):
        return cv2.imread(str(capture.meta["segmentation_path"]), cv2.IMREAD_UNCHANGED)

    kw = {"load_image": _scenes.load_from_disk, "num_timestamps": T, "config": STATIC,
          "with_patches": False, "load_category": load_category}
    first = label_viewpoint(seg, cache_dir=tmp_path / "cache", **kw)
    assert (first["category"] == 1).all()
    for c in seg:  # the maps rewritten: every pixel is now a building (2)
        cv2.imwrite(str(c.meta["segmentation_path"]),
                    np.full((_scenes.HEIGHT, _scenes.WIDTH), 2, np.uint8))
    second = label_viewpoint(seg, cache_dir=tmp_path / "cache", **kw)
    assert (second["category"] == 2).all()
    np.testing.assert_array_equal(second["xy"], first["xy"])  # detection was not redone
    # Without the labels file the features' cache alone must not bring them back either.
    for f in (tmp_path / "cache").glob("labels/*/*"):
        f.unlink()
    for c in seg:
        cv2.imwrite(str(c.meta["segmentation_path"]),
                    np.full((_scenes.HEIGHT, _scenes.WIDTH), 3, np.uint8))
    third = label_viewpoint(seg, cache_dir=tmp_path / "cache", **kw)
    assert (third["category"] == 3).all()


def test_static_viewpoint_of_mixed_sizes_is_refused_naming_the_files(tmp_path):
    # Issue 14, item 5: the < 5 px check across resolutions; any caller of label_viewpoint.
    import cv2

    caps = _bmp_viewpoint(tmp_path, "vpmixed", seed=12)
    small = cv2.resize(cv2.imread(str(caps[1].image_path)),
                       (_scenes.WIDTH // 2, _scenes.HEIGHT // 2))
    assert cv2.imwrite(str(caps[1].image_path), small)
    with pytest.raises(ValueError, match=r"'vpmixed' has images of 2 sizes: 2 at .*; "
                                         r"1 at \d+x\d+ \(.*c0s1\.bmp\)"):
        label_viewpoint(caps, load_image=_scenes.load_from_disk, num_timestamps=T,
                        config=STATIC, with_patches=False)


def test_a_category_map_of_another_size_names_the_image_and_the_map(tmp_path):
    import dataclasses

    import cv2

    caps = _bmp_viewpoint(tmp_path, "vpsegsize", seed=13)
    p = tmp_path / "seg.png"
    assert cv2.imwrite(str(p), np.zeros((8, 8), np.uint8))
    caps = [dataclasses.replace(c, meta={**c.meta, "segmentation_path": p}) for c in caps]
    with pytest.raises(ValueError, match=r"c0s0\.bmp: category map of shape \(8, 8\).*seg\.png"):
        label_viewpoint(caps, load_image=_scenes.load_from_disk, num_timestamps=T,
                        config=STATIC, with_patches=False,
                        load_category=lambda c: cv2.imread(str(c.meta["segmentation_path"]), 0))
