"""The vectorised matcher equals cv2.BFMatcher.knnMatch(k=2) + ratio test (Sec. III-D)."""

import numpy as np
import pytest

from rp_jax.groundtruth import blas_threads, exact_pairs
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


# --- The bfloat16 candidate path (module docstring): identical to the float32 path. ---------


def _assert_identical(m, ref):
    for field in ("nn", "d1", "d2", "ratio_ok"):
        for i, (x, y) in enumerate(zip(getattr(m, field), getattr(ref, field))):
            np.testing.assert_array_equal(x, y, err_msg=f"{field} of image {i}")


@pytest.fixture(scope="module")
def sift_viewpoint():
    """Real SIFT descriptors (integer-valued float32) of a small synthetic viewpoint."""
    img = textured_image(7)
    ims = [img, shifted(img, 3.3, -2.1, gain=0.8, noise=4.0, seed=1), shifted(img, -5, 4, 1.2)]
    ims.append(shifted(img, 1.5, 6.0, gain=0.9, noise=6.0, seed=2))
    raw = [detect_and_describe(im, detector="sift", max_keypoints=400).descriptor for im in ims]
    assert all(len(r) > 100 for r in raw)
    return [prepare_descriptors(r, "l2") for r in raw]


@pytest.mark.parametrize("reduce", ["host", "device"])
def test_bf16_path_identical_on_real_sift(sift_viewpoint, reduce):
    ref = match_all_pairs(sift_viewpoint, method="float32")
    m = match_all_pairs(sift_viewpoint, method="bf16", reduce=reduce, block_bytes=1 << 20)
    _assert_identical(m, ref)
    assert sum(int(r.sum()) for r in m.ratio_ok) > 100  # not vacuous: many matches pass


def _near_tie_descriptors(seed: int) -> list[np.ndarray]:
    """Queries whose 2nd and 3rd (and 1st and 2nd) neighbours tie exactly or differ by 1-2
    in squared distance, with values up to 255 and norms (~1,300) above SIFT's 512, so that
    the certificate's bound E (~ 30) exceeds those gaps."""
    rng = np.random.default_rng(seed)
    dim = 128
    base = rng.integers(1, 140, (12, dim)).astype(np.float32)
    base[:, :8] = 254
    targets = []
    for q in base:
        for s in (4, 5, 5, 6, 6, 6, 7, 9):  # squared offsets: ties and near-ties
            t = q.copy()
            idx = rng.choice(dim, s, replace=False)
            t[idx] += rng.choice([-1.0, 1.0], s)
            targets.append(t)
    targets = np.asarray(targets)
    rng.shuffle(targets)
    return [base, targets, targets[::-1].copy(), np.concatenate([base, base])]


@pytest.mark.parametrize("seed", [0, 1])
def test_bf16_path_identical_on_adversarial_near_ties(seed):
    from rp_jax.groundtruth import matching

    descs = _near_tie_descriptors(seed)
    ref = match_all_pairs(descs, method="float32")
    for reduce in ("host", "device"):
        m = match_all_pairs(descs, method="bf16", reduce=reduce, threads=1)
        _assert_identical(m, ref)
        assert matching.last_recomputed_rows > 0  # the exact fallback was exercised
    # And against OpenCV itself, pair by pair.
    for a, b in ((0, 1), (1, 0), (0, 3), (3, 2)):
        nn, d1, ok = match_pair_reference(descs[a], descs[b])
        np.testing.assert_array_equal(m.nn[a][:, b], nn)
        np.testing.assert_array_equal(m.ratio_ok[a][:, b], ok)


@pytest.mark.parametrize("which", ["near_ties", "sift"])
def test_bf16_certificate_survives_a_worse_backend(monkeypatch, sift_viewpoint, which):
    """Approximate distances perturbed by up to the certified error bound E (as a backend
    with a different float32 summation order could): the result must not change."""
    import jax
    import jax.numpy as jnp

    from rp_jax.groundtruth import matching

    descs = _near_tie_descriptors(2) if which == "near_ties" else sift_viewpoint
    norms = np.concatenate([np.linalg.norm(d, axis=1) for d in descs])
    amp = 0.99 * (128 + 10) * 2.0**-24 * (2 * norms.min()) ** 2  # <= every row's bound
    assert amp > 1  # large enough to reorder integer distances that differ by 1
    real = matching._bf16_block_kernel.__wrapped__

    def noisy(block, on_device):
        inner = real(block, on_device=False)

        def kernel(lhs, rhs, a, b0):
            fwd, bwd = inner(lhs, rhs, a, b0)
            key = jax.random.fold_in(jax.random.key(0), a * 100_003 + b0)
            k1, k2 = jax.random.split(key)
            fwd = fwd + amp * jax.random.uniform(k1, fwd.shape, jnp.float32, -1.0, 1.0)
            bwd = bwd + amp * jax.random.uniform(k2, bwd.shape, jnp.float32, -1.0, 1.0)
            return fwd, bwd

        return kernel

    monkeypatch.setattr(matching, "_bf16_block_kernel", noisy)
    ref = match_all_pairs(descs, method="float32")
    _assert_identical(match_all_pairs(descs, method="bf16", reduce="host"), ref)


def test_bf16_path_refuses_descriptors_bfloat16_cannot_hold():
    rng = np.random.default_rng(0)
    floats = [rng.random((10, 8), dtype=np.float32) for _ in range(2)]
    with pytest.raises(ValueError, match="bfloat16"):
        match_all_pairs(floats, method="bf16")
    big = [rng.integers(0, 1000, (10, 8)).astype(np.float32) + 257 for _ in range(2)]
    with pytest.raises(ValueError, match="bfloat16"):
        match_all_pairs(big, method="bf16")
    # "auto" takes the float32 path for them, and it still matches OpenCV.
    _assert_equal_to_reference(floats, "l2")


def test_auto_takes_bf16_on_an_accelerator_only(monkeypatch, sift_viewpoint):
    from rp_jax.groundtruth import matching

    def bf16_path(*args, **kwargs):
        raise RuntimeError("bf16 path taken")

    monkeypatch.setattr(matching, "_match_bf16", bf16_path)
    monkeypatch.setattr(matching, "_on_accelerator", lambda: False)
    match_all_pairs(sift_viewpoint[:2])  # CPU: the float32 path (faster here, see docstring)
    monkeypatch.setattr(matching, "_on_accelerator", lambda: True)
    with pytest.raises(RuntimeError, match="bf16 path taken"):
        match_all_pairs(sift_viewpoint[:2])
    floats = [np.random.default_rng(0).random((9, 8), dtype=np.float32) for _ in range(2)]
    match_all_pairs(floats)  # not exact in bf16: float32 even on an accelerator


# --- The per-pair path of exact descriptors (exact_pairs) and OpenBLAS's threads. ------------


def test_integer_descriptors_with_empty_and_single_point_images():
    # Integer-valued (the per-pair path) with images of 0 and 1 points: no ratio test there.
    rng = np.random.default_rng(2)
    raw = [rng.integers(0, 6, (n, 8)).astype(np.float32) for n in (30, 1, 0, 41, 2)]
    _assert_equal_to_reference(raw, "l2")


def test_column_top2_equals_row_top2_of_the_transpose_with_ties():
    rng = np.random.default_rng(3)
    d = rng.integers(0, 4, (37, 3 * exact_pairs.STRIP_COLUMNS + 5)).astype(np.float32)
    want = exact_pairs.top2_rows(np.ascontiguousarray(d.T))
    got = exact_pairs.top2_columns(d.copy())
    for w, g in zip(want, got):
        np.testing.assert_array_equal(g, w)
    assert (want[1] == want[2]).any()  # ties present: the lowest index must have won


def test_blas_thread_limit_is_restored():
    before = blas_threads.threads()
    if before is None:
        pytest.skip("NumPy here does not use OpenBLAS")
    with blas_threads.limit(1):
        assert blas_threads.threads() == 1
        with blas_threads.limit(1):
            pass
        assert blas_threads.threads() == 1  # an inner block does not restore early
    assert blas_threads.threads() == before
