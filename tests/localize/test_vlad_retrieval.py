"""Tests of rp_jax.localize.vlad and retrieval: VLAD over RootSIFT finds the right image."""

import numpy as np
import pytest

from rp_jax.localize import (
    GlobalIndex,
    build_vlad_index,
    learn_vocabulary,
    load_global_descriptors,
    rootsift,
    save_global_descriptors,
    vlad,
)


def test_rootsift_properties():
    rng = np.random.default_rng(0)
    d = rng.integers(0, 256, (10, 128)).astype(np.uint8)
    r = rootsift(d)
    np.testing.assert_allclose(np.linalg.norm(r, axis=1), 1.0, rtol=1e-5)
    # Hellinger kernel: <rootsift(a), rootsift(b)> = sum sqrt(a_l1 * b_l1).
    a, b = d[0] / d[0].sum(), d[1] / d[1].sum()
    assert np.isclose(r[0] @ r[1], np.sqrt(a * b).sum(), rtol=1e-5)


def test_vlad_normalisation():
    rng = np.random.default_rng(1)
    words = learn_vocabulary(rng.random((500, 8)), num_words=4, seed=0)
    v = vlad(rng.random((50, 8)), words)
    assert v.shape == (32,) and np.isclose(np.linalg.norm(v), 1.0, rtol=1e-5)
    assert not np.any(vlad(np.zeros((0, 8)), words))


def test_vocabulary_is_scipys_kmeans_plus_plus():
    """The incremental k-means++ seeding draws the centres SciPy's ``minit="++"`` draws, so
    the vocabulary (and every map and run built on it) is SciPy's."""
    from scipy.cluster.vq import kmeans2

    rng = np.random.default_rng(3)
    d = rootsift(rng.integers(0, 60, (3000, 128)))
    for k, seed in ((1, 0), (16, 0), (64, 5)):
        # learn_vocabulary's own path: its generator seeds the sample draw (none here) and
        # then the initialisation.
        expected, _ = kmeans2(d.astype(np.float64), k, minit="++",
                              seed=np.random.default_rng(seed))
        np.testing.assert_array_equal(learn_vocabulary(d, num_words=k, seed=seed),
                                      expected.astype(np.float32))


def _scene_images(rng, n_images=6, n_kp=150):
    """Images of disjoint 'places': each place has its own set of SIFT-like descriptors."""
    places = [rng.gamma(0.5, 20, (n_kp, 128)) for _ in range(n_images)]
    return {f"db_{i}.jpg": p + rng.gamma(0.5, 2, p.shape) for i, p in enumerate(places)}, places


def test_vlad_retrieval_finds_the_right_image():
    rng = np.random.default_rng(2)
    db, places = _scene_images(rng)
    index, words = build_vlad_index(db, num_words=16, seed=0)
    for i, place in enumerate(places):
        # The query sees 60 % of the place's keypoints, with noise, plus clutter.
        sel = rng.choice(len(place), int(0.6 * len(place)), replace=False)
        query = np.concatenate(
            [place[sel] + rng.gamma(0.5, 2, (len(sel), 128)), rng.gamma(0.5, 20, (40, 128))]
        )
        names, dist = index.query(vlad(rootsift(query), words), k=3)
        assert names[0] == f"db_{i}.jpg"
        assert np.all(np.diff(dist) >= 0)


def test_global_descriptor_file_round_trip(tmp_path):
    rng = np.random.default_rng(3)
    desc = {f"img{i}.png": rng.normal(size=64).astype(np.float32) for i in range(5)}
    path = save_global_descriptors(tmp_path / "netvlad.npz", desc)
    loaded = load_global_descriptors(path)
    assert set(loaded) == set(desc)
    index = GlobalIndex.from_mapping(loaded)
    names, _ = index.query(desc["img3.png"] * 2.0, k=2)  # scale-invariant (unit vectors)
    assert names[0] == "img3.png"
    with pytest.raises(ValueError, match="one \\[G\\] descriptor per name"):
        GlobalIndex(["a", "b"], np.zeros((3, 4)))
