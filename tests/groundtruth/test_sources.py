"""Source images, streamed labels and blocks (Sec. III-D, Fig. 4): the records of a viewpoint
labelled from some of its images, against all of them, equal the all-pairs labels."""

import numpy as np
import pytest

from rp_jax.groundtruth import (
    GroundTruthConfig,
    label_viewpoint,
    label_viewpoint_block,
    label_viewpoints,
    viewpoint_block_count,
)
from rp_jax.groundtruth import blocks as blocks_lib
from rp_jax.groundtruth import features as features_lib
from rp_jax.groundtruth.image_features import image_features
from rp_jax.groundtruth.labels import repeatability_labels
from rp_jax.groundtruth.matching import match_all_pairs, prepare_descriptors
from rp_jax.groundtruth.sources import choose_sources, source_blocks
from rp_jax.groundtruth.verify_matches import intrinsics_of, resolve_mode, verify_matches
from tests.groundtruth import _scenes
from tests.groundtruth.test_viewpoint import STATIC, T, _static_viewpoint
from tests.groundtruth.test_viewpoint_pose import _posed_viewpoint

LOAD = _scenes.load_from_registry


def _all_pairs_labels(caps, config, num_timestamps):
    """The all-pairs labelling, from its parts: every image matched against every other
    (``match_all_pairs``), verified (``verify_matches``), averaged per timestamp."""
    found = [(c, image_features(c, load_image=LOAD, config=config)) for c in caps]
    readable = [c for c, f in found if f is not None]
    feats = [f for _, f in found if f is not None]
    norm = features_lib.descriptor_norm(config.detector)
    matches = match_all_pairs([prepare_descriptors(f["descriptor"], norm) for f in feats],
                              ratio=config.ratio, norm=norm)
    mode = resolve_mode(config, readable)
    intrinsics = ([intrinsics_of(c, None, f["image_size"]) for c, f in zip(readable, feats)]
                  if mode == "pose" else None)
    inliers = verify_matches(readable, [f["xy"] for f in feats], matches, mode=mode,
                             config=config, intrinsics=intrinsics)
    slots = np.array([c.slot for c in readable])
    out = {}
    for i, c in enumerate(readable):
        out[c.image_id] = repeatability_labels(inliers[i], slots, i, num_timestamps)
    return out


def _rows_of(records, image_id):
    return np.flatnonzero(np.asarray(records["image_id"]).astype(str) == image_id)


def test_choose_sources_spreads_over_timestamps_and_cycles():
    cycles, slots = np.meshgrid(np.arange(10), np.arange(5), indexing="ij")  # 10 days x 5
    cycles, slots = cycles.ravel(), slots.ravel()
    chosen = choose_sources(cycles, slots, 15)
    assert len(chosen) == 15 and np.all(np.diff(chosen) > 0)
    assert np.bincount(slots[chosen], minlength=5).tolist() == [3] * 5
    assert len(set(cycles[chosen].tolist())) >= 9  # timestamps do not all pick the same days
    for j in range(5):  # within a timestamp: evenly spread over the 10 days
        days = np.sort(cycles[chosen][slots[chosen] == j])
        assert days.min() <= 3 and days.max() >= 6 and np.all(np.diff(days) >= 2)
    np.testing.assert_array_equal(choose_sources(cycles, slots, 15), chosen)  # deterministic
    # A remainder goes to evenly spaced timestamps; a timestamp with few images gives the
    # rest to the others.
    assert sorted(np.bincount(slots[choose_sources(cycles, slots, 7)], minlength=5)) == [
        1, 1, 1, 2, 2]
    sparse = slots.copy()
    sparse[sparse == 4] = 3
    sparse[[0]] = 4  # timestamp 4 has a single image
    counts = np.bincount(sparse[choose_sources(cycles, sparse, 13)], minlength=5)
    assert counts[4] == 1 and counts.sum() == 13 and counts[:4].max() - counts[:4].min() <= 1
    np.testing.assert_array_equal(choose_sources(cycles, slots, 0), np.arange(50))
    np.testing.assert_array_equal(choose_sources(cycles, slots, 80), np.arange(50))
    with pytest.raises(ValueError, match="max_sources"):
        choose_sources(cycles, slots, -1)
    assert [list(b) for b in source_blocks(5, 2)] == [[0, 1], [2, 3], [4]]


@pytest.mark.parametrize("which", ["static", "pose", "orb"])
def test_every_image_a_source_gives_the_all_pairs_labels(which):
    if which == "pose":
        caps = _posed_viewpoint("src_pose")
        config, num_timestamps = GroundTruthConfig(max_keypoints=200), 3
    else:
        caps = _static_viewpoint(f"src_{which}", seed=3)
        config, num_timestamps = STATIC, T
        if which == "orb":  # binary descriptors: Hamming distances
            config = GroundTruthConfig(detector="orb", max_keypoints=150, verification="static")
    records = label_viewpoint(caps, load_image=LOAD, num_timestamps=num_timestamps,
                              config=config, with_patches=False, sources_per_block=2)
    reference = _all_pairs_labels(caps, config, num_timestamps)
    assert list(dict.fromkeys(np.asarray(records["image_id"]).astype(str))) == list(reference)
    for image_id, (label, mask) in reference.items():
        rows = _rows_of(records, image_id)
        np.testing.assert_array_equal(records["label"][rows], label, err_msg=image_id)
        np.testing.assert_array_equal(records["label_mask"][rows], mask, err_msg=image_id)
    assert 0 < records["label"].mean() < 1  # points repeat, and not everywhere


def test_a_source_has_the_same_labels_whichever_images_are_sources():
    caps = _static_viewpoint("src_few", seed=4)
    kw = {"load_image": LOAD, "num_timestamps": T, "with_patches": False}
    every = label_viewpoint(caps, config=STATIC, **kw)
    three = GroundTruthConfig(detector="sift", max_keypoints=150, verification="static",
                              max_sources=3)
    few = label_viewpoint(caps, config=three, **kw)
    kept = list(dict.fromkeys(np.asarray(few["image_id"]).astype(str)))
    assert len(kept) == 3
    assert len({c.slot for c in caps if c.image_id in kept}) == 3  # one per timestamp
    rows = np.concatenate([_rows_of(every, i) for i in kept])
    for k in few:
        np.testing.assert_array_equal(few[k], every[k][rows], err_msg=k)


def test_blocks_concatenated_are_the_viewpoint_and_a_killed_run_resumes(tmp_path,
                                                                        monkeypatch):
    caps = _static_viewpoint("src_blocks", seed=6)
    kw = {"load_image": LOAD, "num_timestamps": T, "config": STATIC}
    whole = label_viewpoint(caps, **kw, with_patches=False)
    count = viewpoint_block_count(len(caps), STATIC, sources_per_block=2)
    assert count == 4  # 7 captures; one is unreadable, so the last block is empty
    parts = [label_viewpoint_block(caps, k, **kw, sources_per_block=2) for k in range(count)]
    assert len(parts[-1]["xy"]) == 0
    for k in whole:
        np.testing.assert_array_equal(np.concatenate([p[k] for p in parts]), whole[k],
                                      err_msg=k)

    # Killed in its second block: the first block's labels are on disk, and the resumed
    # run labels only the two blocks left.
    calls = []
    real = blocks_lib.block_counts

    def dying(*args, **kwargs):
        calls.append(args[0])
        if len(calls) == 2:
            raise RuntimeError("killed")
        return real(*args, **kwargs)

    monkeypatch.setattr(blocks_lib, "block_counts", dying)
    cache = tmp_path / "cache"
    with pytest.raises(RuntimeError, match="killed"):
        label_viewpoint(caps, **kw, cache_dir=cache, with_patches=False, sources_per_block=2)
    assert len(list(cache.glob("labels/*/*.blocks/*.npz"))) == 1
    calls.clear()
    monkeypatch.setattr(blocks_lib, "block_counts", lambda *a, **k: calls.append(a[0]) or
                        real(*a, **k))
    resumed = label_viewpoint(caps, **kw, cache_dir=cache, with_patches=False,
                              sources_per_block=2)
    assert len(calls) == 2
    for k in whole:
        np.testing.assert_array_equal(resumed[k], whole[k], err_msg=k)
    # Finished: the viewpoint's file replaces its blocks; a block is then read from it.
    assert not list(cache.glob("labels/*/*.blocks/*.npz"))
    calls.clear()
    again = label_viewpoint_block(caps, 1, **kw, cache_dir=cache, sources_per_block=2)
    assert calls == []
    for k in again:
        np.testing.assert_array_equal(again[k], parts[1][k], err_msg=k)


def test_worker_processes_share_one_viewpoint_by_blocks(tmp_path):
    caps = _static_viewpoint("src_pool", seed=7)
    kw = {"num_timestamps": T, "config": STATIC}
    serial = label_viewpoint(caps, load_image=LOAD, **kw)
    # Spawned workers read the same images from lossless PNGs.
    on_disk = _scenes.to_disk(caps, tmp_path / "images")
    got = dict(label_viewpoints({"src_pool": on_disk}, load_image=_scenes.load_from_disk,
                                workers=2, cache_dir=tmp_path / "cache",
                                sources_per_block=2, **kw))
    assert len(list((tmp_path / "cache").glob("labels/*/*.blocks/*.npz"))) == 3
    for k in serial:
        np.testing.assert_array_equal(got["src_pool"][k], serial[k], err_msg=k)
