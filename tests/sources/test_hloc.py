"""Tests of rp_jax.sources.hloc on files written in hloc's layout with h5py directly."""

import h5py
import numpy as np
import pytest

from rp_jax.sources import hloc
from rp_jax.sources.layout import LayoutError


@pytest.fixture
def features(tmp_path):
    """As hloc's extract_features.py writes with --as_half: nested names, float16, [D, N]."""
    rng = np.random.default_rng(0)
    path = tmp_path / "feats-superpoint-n4096-r1024.h5"
    kp = {"db/a.jpg": rng.uniform(0, 300, (5, 2)), "query/day/b.jpg": rng.uniform(0, 300, (3, 2))}
    desc = {n: rng.normal(size=(256, len(v))) for n, v in kp.items()}
    with h5py.File(path, "w", libver="latest") as f:
        for name in kp:
            g = f.create_group(name)
            g.create_dataset("keypoints", data=kp[name].astype(np.float16))
            g.create_dataset("descriptors", data=desc[name].astype(np.float16))
            g.create_dataset("scores", data=np.linspace(1, 0, len(kp[name]), dtype=np.float16))
            g.create_dataset("image_size", data=np.array([320, 240]))
            g["keypoints"].attrs["uncertainty"] = 2.0
    return path, kp, desc


def test_read_local_features_transposes_descriptors(features):
    path, kp, desc = features
    assert hloc.list_names(path) == ["db/a.jpg", "query/day/b.jpg"]
    f = hloc.read_local_features(path, "db/a.jpg")
    assert len(f) == 5 and f.image_size == (320, 240) and f.scales is None
    np.testing.assert_allclose(f.keypoints, kp["db/a.jpg"], atol=0.13)  # float16 at < 512
    assert f.descriptors.shape == (5, 256) and f.descriptors.dtype == np.float32
    np.testing.assert_allclose(f.descriptors, desc["db/a.jpg"].T, atol=2e-3)
    assert f.scores.shape == (5,)


def test_find_name_by_trailing_path_components():
    names = ["db/a.jpg", "query/day/b.jpg", "x/c.jpg", "y/c.jpg"]
    assert hloc.find_name(names, "db/a.jpg") == "db/a.jpg"
    assert hloc.find_name(names, "a.jpg") == "db/a.jpg"
    assert hloc.find_name(names, "/data/images/query/day/b.jpg") == "query/day/b.jpg"
    assert hloc.find_name(names, "/data/x/c.jpg") == "x/c.jpg"
    assert hloc.find_name(names, "c.jpg") is None  # ambiguous
    assert hloc.find_name(names, "d.jpg") is None


def test_global_descriptors(tmp_path):
    path = tmp_path / "global-feats-netvlad.h5"
    with h5py.File(path, "w") as f:
        for i, name in enumerate(["db/a.jpg", "db/b.jpg"]):
            f.create_group(name).create_dataset("global_descriptor",
                                                data=np.full(4096, i, np.float16))
    out = hloc.read_global_descriptors(path)
    assert sorted(out) == ["db/a.jpg", "db/b.jpg"] and out["db/b.jpg"].shape == (4096,)
    assert hloc.read_global_descriptors(path, ["b.jpg"])["b.jpg"][0] == 1.0
    with pytest.raises(LayoutError, match="no global descriptor for image 'c.jpg'"):
        hloc.read_global_descriptors(path, ["c.jpg"])


def test_errors_name_the_file(features, tmp_path):
    path, _, _ = features
    with pytest.raises(LayoutError, match="no group for image 'nope.jpg'"):
        hloc.read_local_features(path, "nope.jpg")
    bad = tmp_path / "bad.h5"
    with h5py.File(bad, "w") as f:
        g = f.create_group("a.jpg")
        g.create_dataset("keypoints", data=np.zeros((4, 2)))
        g.create_dataset("descriptors", data=np.zeros((4, 128)))  # [N, D]: not hloc's layout
    with pytest.raises(LayoutError, match=r"bad\.h5: image 'a\.jpg' has 4 keypoints"):
        hloc.read_local_features(bad, "a.jpg")
    (tmp_path / "text.h5").write_text("not hdf5")
    with pytest.raises(LayoutError, match=r"text\.h5: not an HDF5 file"):
        hloc.list_names(tmp_path / "text.h5")
    with pytest.raises(FileNotFoundError, match=r"missing\.h5"):
        hloc.list_names(tmp_path / "missing.h5")
