"""The vectorised matcher equals cv2.BFMatcher.knnMatch(k=2) + ratio test (Sec. III-D)."""

import numpy as np
import pytest

from rp_jax.groundtruth.features import detect_and_describe
from rp_jax.groundtruth.matching import match_all_pairs, match_pair_reference, prepare_descriptors
from tests.groundtruth._scenes import shifted, textured_image


def _assert_equal_to_reference(raw, norm, ratio=0.8, block_bytes=64 << 20):
    descs = [prepare_descriptors(d, norm) for d in raw]
    m = match_all_pairs(descs, ratio=ratio, norm=norm, block_bytes=block_bytes)
    compared = 0
    for a in range(len(raw)):
        for b in range(len(raw)):
            if a == b:
                assert (m.nn[a][:, b] == -1).all() and not m.ratio_ok[a][:, b].any()
                continue
            nn, d1, ok = match_pair_reference(raw[a], raw[b], ratio=ratio, norm=norm)
            np.testing.assert_array_equal(m.ratio_ok[a][:, b], ok, err_msg=f"pair {a}->{b}")
            if len(raw[b]) >= 2:
                np.testing.assert_array_equal(m.nn[a][:, b], nn, err_msg=f"pair {a}->{b}")
                np.testing.assert_allclose(m.d1[a][:, b], d1, rtol=1e-5, atol=1e-3)
            compared += len(raw[a])
    assert compared > 0


def test_random_float_descriptors():
    rng = np.random.default_rng(0)
    raw = [rng.random((n, 128), dtype=np.float32) for n in (40, 55, 33, 1, 0, 47)]
    _assert_equal_to_reference(raw, "l2")


def test_integer_descriptors_with_many_ties():
    # Few distinct values in few dimensions: exact ties everywhere; lowest index must win.
    rng = np.random.default_rng(1)
    raw = [rng.integers(0, 3, (n, 4)).astype(np.float32) for n in (60, 45, 70)]
    _assert_equal_to_reference(raw, "l2", block_bytes=1)  # one target image per block


def test_real_sift_descriptors_of_an_image_pair():
    img = textured_image(3)
    other = shifted(img, 3.3, -2.1, gain=0.8, noise=4.0, seed=1)
    raw = [
        detect_and_describe(im, detector="sift", max_keypoints=300).descriptor
        for im in (img, other, shifted(img, -5, 4, gain=1.2))
    ]
    assert all(len(r) > 50 for r in raw)
    _assert_equal_to_reference(raw, "l2")
    # Sanity: the shifted copy really matches (so the equality above is not vacuous).
    m = match_all_pairs([prepare_descriptors(r, "l2") for r in raw])
    assert m.ratio_ok[0][:, 1].mean() > 0.3


def test_orb_hamming_descriptors():
    img = textured_image(4)
    raw = [
        detect_and_describe(im, detector="orb", max_keypoints=200).descriptor
        for im in (img, shifted(img, 2, 1, gain=0.9))
    ]
    assert raw[0].dtype == np.uint8 and len(raw[0]) > 20
    _assert_equal_to_reference(raw, "hamming")


def test_ratio_test_rejects_ambiguous_neighbours():
    q = np.array([[0.0, 0.0]], np.float32)
    # Two equally near targets: d1 == d2, ratio test must fail; a clear one must pass.
    ambiguous = np.array([[1.0, 0.0], [0.0, 1.0], [5.0, 5.0]], np.float32)
    clear = np.array([[0.1, 0.0], [3.0, 3.0]], np.float32)
    m = match_all_pairs([q, ambiguous, clear])
    assert not m.ratio_ok[0][0, 1] and m.nn[0][0, 1] == 0
    assert m.ratio_ok[0][0, 2] and m.nn[0][0, 2] == 0
    assert m.d1[0][0, 2] == pytest.approx(0.1, abs=1e-6)


def test_cv2_reference_helper_matches_bruteforce_numpy():
    rng = np.random.default_rng(5)
    a, b = rng.random((20, 8), dtype=np.float32), rng.random((30, 8), dtype=np.float32)
    nn, d1, ok = match_pair_reference(a, b, ratio=0.8)
    d = np.sqrt(((a[:, None] - b[None]) ** 2).sum(-1))
    np.testing.assert_array_equal(nn, d.argmin(1))
    nearest, second = np.sort(d, axis=1)[:, :2].T
    np.testing.assert_allclose(d1, nearest, rtol=1e-5)  # the Euclidean distance, not its square
    np.testing.assert_array_equal(ok, nearest < 0.8 * second)
    assert 0 < ok.sum() < len(ok)  # the ratio test passes some points and rejects others
