"""Per-image-pair outcomes beside the labels: what y^j averages, cached, records unchanged."""

import shutil

import numpy as np

from rp_jax.groundtruth import OUTCOME_KEYS, label_viewpoint, label_viewpoint_outcomes
from rp_jax.groundtruth import labels as labels_lib
from tests.groundtruth import _scenes
from tests.groundtruth.test_viewpoint import STATIC, T, _static_viewpoint


class _CountingLoader:
    def __init__(self):
        self.calls = 0

    def __call__(self, capture):
        self.calls += 1
        return _scenes.load_from_registry(capture)


def _slot_average(outcome, row_image, slots, readable):
    """y^j by hand: inliers among the slot's readable images, the own image counted."""
    label = np.zeros((len(outcome), T))
    for r in range(len(outcome)):
        for j in range(T):
            images = np.flatnonzero((slots == j) & readable)
            if len(images):
                hits = [(k == row_image[r]) or outcome[r, k] == 1 for k in images]
                label[r, j] = np.mean(hits)
    return label


def test_outcomes_average_into_the_labels_and_records_are_unchanged(tmp_path):
    caps = _static_viewpoint()
    kwargs = dict(load_image=_scenes.load_from_registry, num_timestamps=T, config=STATIC)
    plain = label_viewpoint(caps, **kwargs, with_patches=False)
    records, out = label_viewpoint_outcomes(caps, **kwargs, cache_dir=tmp_path)
    for k in plain:  # the existing records, bit for bit
        np.testing.assert_array_equal(records[k], plain[k], err_msg=k)
    assert set(out) == set(OUTCOME_KEYS)

    n, n_images = len(records["xy"]), len(caps)
    assert out["outcome"].shape == (n, n_images) and out["outcome"].dtype == np.int8
    np.testing.assert_array_equal(out["image_id"], [c.image_id for c in caps])
    np.testing.assert_array_equal(out["image_slot"], [c.slot for c in caps])
    np.testing.assert_array_equal(out["image_id"][out["row_image"]], records["image_id"])
    np.testing.assert_array_equal(out["keypoint_id"], records["keypoint_id"])
    np.testing.assert_array_equal(out["image_time"][out["row_image"]], records["time"])
    assert out["image_unix_time"][0] == caps[0].time.timestamp()
    unreadable = list(out["image_id"]).index("c1s1b")
    assert not out["image_readable"][unreadable] and out["image_readable"].sum() == 6
    # Unknown exactly in the own image and the unreadable one.
    unknown = out["outcome"] == labels_lib.OUTCOME_UNKNOWN
    expected = np.zeros_like(unknown)
    expected[np.arange(n), out["row_image"]] = True
    expected[:, unreadable] = True
    np.testing.assert_array_equal(unknown, expected)
    # The camera knocked 12 px holds no static inlier of another image's points.
    shifted = list(out["image_id"]).index("c1s2")
    assert (out["outcome"][out["row_image"] != shifted, shifted] == 0).all()
    assert (out["outcome"] == 1).sum() > n  # day images re-detect each other's points

    # Averaged over each slot's images, the outcomes are the labels.
    label, mask = labels_lib.repeatability_from_outcomes(
        out["outcome"], out["image_slot"], out["image_readable"], out["row_image"], T)
    np.testing.assert_array_equal(label, records["label"])
    np.testing.assert_array_equal(mask, records["label_mask"])
    by_hand = _slot_average(out["outcome"], out["row_image"], out["image_slot"],
                            out["image_readable"])
    np.testing.assert_allclose(by_hand, records["label"], atol=1e-6)

    # Cached: a second call reads no image; without the outcome cache (a viewpoint labelled
    # before outcomes were kept) it matches again and gives the same.
    loader = _CountingLoader()
    again_records, again = label_viewpoint_outcomes(caps, **{**kwargs, "load_image": loader},
                                                    cache_dir=tmp_path)
    assert loader.calls == 0
    for k in out:
        np.testing.assert_array_equal(again[k], out[k], err_msg=k)
    shutil.rmtree(tmp_path / "outcomes")
    _, redone = label_viewpoint_outcomes(caps, **kwargs, cache_dir=tmp_path)
    for k in out:
        np.testing.assert_array_equal(redone[k], out[k], err_msg=k)


def test_pair_outcomes_marks_own_and_unreadable_images():
    inliers = np.array([[True, False, True], [False, False, True]])
    got = labels_lib.pair_outcomes(inliers, own_image=1, columns=np.array([0, 2, 3]),
                                   num_images=4)
    np.testing.assert_array_equal(got, [[1, -1, -1, 1], [0, -1, -1, 1]])
