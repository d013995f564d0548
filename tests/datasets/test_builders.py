"""The TFDS builders of rp_jax.datasets on tiny synthetic worlds (Sec. III-D, IV-A-1, IV-B-1).

An equivalent of ``tfds.testing.DatasetBuilderTestCase`` (that class needs TensorFlow and
dill, neither installed): each builder is built at ``synthetic_tiny`` from a world the
test renders, then its splits, features, labels and resume behaviour are checked.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
import tensorflow_datasets as tfds

from rp_jax.datasets import builder as builder_lib
from rp_jax.datasets import features as features_lib
from rp_jax.datasets import input_pipeline, loading, registry
from rp_jax.schedule import load_spec, preset
from rp_jax.sources.layout import LayoutError
from tests.datasets._tiny import (
    TINY,
    all_records,
    build_tiny,
    check_records,
    shared_data_dir,
)


@pytest.fixture(scope="module")
def webcam(tmp_path_factory):
    return build_tiny("webcam_clipart", shared_data_dir(tmp_path_factory))


def test_webcam_splits_follow_the_data_spec(webcam):
    splits = webcam.info.splits
    assert set(splits) == {"train", "test"}
    # Counted, not derivable: every interest point that verification kept in 10 images per
    # split (tiny world: 2 days x slots 0, 5, 10, 15, 20 of the 21, one training and the
    # test scene; synthetic_tiny keeps all rows, at most 150 detections per image). The
    # rendering, SIFT or the labelling changing moves them: bump the builder's VERSION.
    # The exact counts depend on the CPU's floating-point paths (rendering and SIFT run
    # other SIMD kernels per CPU): measured {train 797, test 832} on an Intel Xeon
    # (AVX-512) and {795, 833} on an AMD EPYC (AVX2), with or without OPENBLAS_CORETYPE.
    # So each count is pinned to within 1 % of the Xeon's (8 records), four times the
    # spread measured between the two CPUs; a larger change fails here.
    counts = {k: v.num_examples for k, v in splits.items()}
    for split, measured in {"train": 797, "test": 832}.items():
        assert abs(counts[split] - measured) <= 0.01 * measured, (split, counts)
    # At most 150 detections in each of the 10 images of a split.
    assert all(0 < n <= 10 * 150 for n in counts.values())
    spec = load_spec("webcam_clipart")["splits"]["synthetic"]
    train_vps = {r["viewpoint"].decode() for r in all_records(webcam, "train")}
    test_vps = {r["viewpoint"].decode() for r in all_records(webcam, "test")}
    assert train_vps and train_vps <= set(spec["train"])
    assert test_vps == set(spec["test"])
    for split in ("train", "test"):
        assert len({r["image_id"] for r in all_records(webcam, split)}) == 10


def test_webcam_features_and_labels(webcam):
    schedule = preset("webcam_clipart")
    assert webcam.info.features["label"].shape == (schedule.num_timestamps,)
    records = all_records(webcam, "test")
    check_records(records, schedule.num_timestamps, schedule)
    labels = np.stack([r["label"] for r in records])
    masks = np.stack([r["label_mask"] for r in records])
    # Several timestamps observed, and some interest points repeat across them.
    assert masks.any(axis=0).sum() >= 2
    slots = np.array([r["slot"] for r in records])
    other = masks.copy()
    other[np.arange(len(slots)), slots] = False
    assert labels[other].max() > 0
    # Categories come from the synthetic segmentation maps.
    assert any(r["category"] >= 0 for r in records)


def _dataset_files(b) -> dict[str, float]:
    root = Path(b.data_dir)
    return {p.name: p.stat().st_mtime_ns for p in root.iterdir()}


def test_second_build_is_a_no_op(webcam, tmp_path_factory):
    before = _dataset_files(webcam)
    again = build_tiny("webcam_clipart", shared_data_dir(tmp_path_factory))
    assert again.is_prepared()
    assert _dataset_files(again) == before


def _records_by_key(b, split: str) -> dict:
    return {
        (r["viewpoint"], r["image_id"], r["keypoint_id"]): (r["label"], r["label_mask"])
        for r in all_records(b, split)
    }


def test_rebuild_reuses_the_ground_truth_cache(webcam, tmp_path, monkeypatch):
    src_downloads = Path(webcam._data_dir_root) / "downloads"
    data_dir = tmp_path / "tfds"
    shutil.copytree(src_downloads, data_dir / "downloads")
    cache = data_dir / "downloads" / "groundtruth" / "webcam_clipart" / TINY
    # An "interrupted" build: the test viewpoint's labels were never written, its
    # per-image features were.
    removed = list(cache.glob("labels/*/scene_07.*"))
    assert removed, f"no per-viewpoint label cache under {cache}"
    for p in removed:
        p.unlink()

    def no_detection(*args, **kwargs):
        raise AssertionError("interest points were detected again instead of read from cache")

    monkeypatch.setattr("rp_jax.groundtruth.features.detect_and_describe", no_detection)
    rebuilt = build_tiny(
        "webcam_clipart",
        data_dir,
        synthetic_root=Path(webcam._data_dir_root).parent / "synthetic" / "webcam_clipart_tiny",
    )
    assert {p.name for p in removed} <= {p.name for p in cache.glob("labels/*/*")}
    for split in ("train", "test"):
        old, new = _records_by_key(webcam, split), _records_by_key(rebuilt, split)
        assert old.keys() == new.keys()
        for key, (label, mask) in old.items():
            np.testing.assert_array_equal(new[key][0], label)
            np.testing.assert_array_equal(new[key][1], mask)


def test_load_gives_an_array_source_for_the_model(webcam):
    data_dir = Path(webcam._data_dir_root)
    source = loading.load("webcam_clipart", "train", config=TINY, data_dir=data_dir)
    assert len(source) == webcam.info.splits["train"].num_examples
    batch = next(input_pipeline.eval_batches(source, 16))
    assert set(input_pipeline.MODEL_KEYS) <= set(batch)
    assert batch["patch"].shape == (16, 64, 64, 3)
    assert batch["label"].shape == (16, 21) and batch["label_mask"].dtype == bool


def test_load_before_build_names_the_command(tmp_path):
    with pytest.raises(loading.NotBuiltError, match="python -m rp_jax.datasets build"):
        loading.load("robotcar", "train", config=TINY, data_dir=tmp_path)


def test_robotcar_tiny(tmp_path_factory):
    b = build_tiny("robotcar", shared_data_dir(tmp_path_factory))
    assert set(b.info.splits) == {"train"} and b.info.splits["train"].num_examples > 0
    records = all_records(b, "train")
    check_records(records, 9, preset("robotcar"))


def test_robotcar_day_tiny_labels_the_hours_its_traversals_were_driven(tmp_path_factory):
    b = build_tiny("robotcar_day", shared_data_dir(tmp_path_factory))
    schedule = preset("robotcar_day")
    assert schedule.num_timestamps == 24 and b.info.metadata["num_timestamps"] == 24
    viewpoints = {}
    for split in ("train", "test"):
        records = all_records(b, split)
        check_records(records, 24, schedule)
        # The tiny world drives at 1:00 and 13:00 local time: those slots, and only those,
        # are labelled (the other 22 hours are unobserved, not zero).
        assert {int(r["slot"]) for r in records} == {1, 13}
        observed = np.array([r["label_mask"] for r in records]).any(0)
        assert np.flatnonzero(observed).tolist() == [1, 13]
        viewpoints[split] = {r["viewpoint"].decode() if isinstance(r["viewpoint"], bytes)
                             else r["viewpoint"] for r in records}
    assert viewpoints == {"train": {"vp00"}, "test": {"vp01"}}


def test_real_config_reads_a_manual_dir(webcam, tmp_path):
    # A real-layout folder (the synthetic world writes exactly that layout).
    manual = tmp_path / "manual"
    src = Path(webcam._data_dir_root).parent / "synthetic" / "webcam_clipart_tiny"
    shutil.copytree(src, manual, ignore=shutil.ignore_patterns("_synthetic"))
    b = loading.get_builder("webcam_clipart", config="real", data_dir=tmp_path / "tfds", workers=1)
    b.download_and_prepare(download_config=tfds.download.DownloadConfig(manual_dir=manual))
    # No scene lists for real data in the spec: the last scene is held out.
    assert {r["viewpoint"] for r in all_records(b, "test")} == {b"scene_07"}


@pytest.mark.parametrize(
    "name, expected", [("cmu_seasons", "intrinsics.txt"), ("robotcar", "stereo.timestamps")]
)
def test_real_config_lists_the_expected_files(name, expected, tmp_path):
    manual = tmp_path / "manual"
    (manual / "unrelated").mkdir(parents=True)
    (manual / "unrelated" / "file.txt").write_text("x")
    b = loading.get_builder(name, config="real", data_dir=tmp_path / "tfds")
    with pytest.raises(LayoutError, match=expected) as err:
        b.download_and_prepare(download_config=tfds.download.DownloadConfig(manual_dir=manual))
    assert "manual_dir" in str(err.value)  # the download instructions follow


def test_synthetic_root_of_another_size_is_refused(tmp_path):
    root = tmp_path / "world"
    (root / "_synthetic").mkdir(parents=True)
    (root / "_synthetic" / "generation.json").write_text(
        json.dumps({"preset": "robotcar", "size": "small", "seed": 0})
    )
    with pytest.raises(ValueError, match="small"):
        builder_lib.ensure_synthetic("robotcar", root, size="tiny", seed=0, workers=1)


def test_synthetic_root_of_an_older_world_version_is_rendered_again(tmp_path, monkeypatch):
    from rp_jax.sources import synthetic
    from rp_jax.sources.synthetic import presets

    root = tmp_path / "world"
    (root / "_synthetic").mkdir(parents=True)
    (root / "stale.jpg").write_bytes(b"old pixels")
    marker = {"preset": "robotcar", "size": "tiny", "seed": 0}  # no "world": version 1
    (root / "_synthetic" / "generation.json").write_text(json.dumps(marker))
    calls = []

    def fake_generate(name, out, **kwargs):
        calls.append((name, out, (out / "stale.jpg").exists()))
        return out

    monkeypatch.setattr(synthetic, "generate", fake_generate)
    builder_lib.ensure_synthetic("robotcar", root, size="tiny", seed=0, workers=1)
    assert calls == [("robotcar", root, False)]  # the old frames are gone before rendering
    # The current version is kept as it is.
    root.mkdir(exist_ok=True)
    (root / "_synthetic").mkdir(exist_ok=True)
    (root / "_synthetic" / "generation.json").write_text(
        json.dumps({**marker, "world": presets.world_version("robotcar")}))
    builder_lib.ensure_synthetic("robotcar", root, size="tiny", seed=0, workers=1)
    assert len(calls) == 1


def test_synthetic_root_default_location(tmp_path):
    root = builder_lib.synthetic_root(tmp_path / "tfds", "cmu_seasons", "small")
    assert root == (tmp_path / "synthetic" / "cmu_seasons_small").resolve()
    assert builder_lib.synthetic_root(tmp_path / "tfds", "robotcar", "full", seed=3).name == (
        "robotcar_seed3"
    )


def test_splits_of_each_dataset():
    cmu = registry.get("cmu_seasons").splits(
        "synthetic", ["slice6/vp0000", "slice8/vp0001", "slice9/vp0000"]
    )
    assert cmu == {"train": ["slice6/vp0000", "slice9/vp0000"], "test": ["slice8/vp0001"]}
    assert registry.get("robotcar").splits("real", ["b", "a"]) == {"train": ["a", "b"]}
    day = registry.get("robotcar_day").splits("synthetic", [f"vp{i:02d}" for i in range(8, -1, -1)])
    assert day == {"train": ["vp00", "vp02", "vp03", "vp04", "vp06", "vp07", "vp08"],
                   "test": ["vp01", "vp05"]}
    with pytest.raises(ValueError, match="scene_99"):
        registry.get("webcam_clipart").splits("synthetic", ["scene_00", "scene_99"])
    real = registry.get("webcam_clipart").splits("real", ["c", "a", "b"])
    assert real == {"train": ["a", "b"], "test": ["c"]}


def test_a_split_that_loses_its_viewpoints_is_an_error(tmp_path):
    # Issue 14, item 7: the would-be test scene (sorted last, no list in data_specs) whose
    # files are not named by time was left out unseen, and another scene held out instead.
    import cv2

    for scene, names in (("a", ["20100601_080000"]), ("b", ["20100601_080000"]),
                         ("c", ["IMG_0001", "IMG_0002"])):
        for n in names:
            (tmp_path / scene).mkdir(exist_ok=True)
            cv2.imwrite(str(tmp_path / scene / f"{n}.jpg"), np.full((8, 8, 3), 99, np.uint8))
    found = registry.get("webcam_clipart").layout_viewpoints(tmp_path)
    assert found == ["a", "b", "c"]
    with pytest.raises(LayoutError, match=r"split 'test' \(c\) lost all its viewpoints"):
        registry.get("webcam_clipart").splits("real", ["a", "b"], found=found)
    # A training scene lost (counted and named by the reader) leaves a working split.
    assert registry.get("webcam_clipart").splits("real", ["a", "c"],
                                                 found=found) == {"train": ["a"], "test": ["c"]}
    cmu_found = ["slice6/", "slice8/"]
    with pytest.raises(LayoutError, match=r"split 'test' \(slice8/\) lost"):
        registry.get("cmu_seasons").splits("real", ["slice6/vp0000"], found=cmu_found)


def test_records_to_examples_refuses_other_descriptors():
    n = 2
    records = {
        "patch": np.zeros((n, 64, 64, 3), np.uint8),
        "xy": np.zeros((n, 2), np.float32),
        "xy_normalized": np.zeros((n, 2), np.float32),
        "image_size": np.ones((n, 2), np.int32),
        "label": np.zeros((n, 3), np.float32),
        "label_mask": np.ones((n, 3), bool),
        "category": np.full(n, -1),
        "descriptor": np.zeros((n, 32), np.float32),
        "time": np.zeros((n, 6), np.int32),
        "cycle": np.zeros(n),
        "slot": np.zeros(n),
        "viewpoint": np.array(["v", "v"]),
        "image_id": np.array(["a", "a"]),
        "keypoint_id": np.arange(n),
    }
    with pytest.raises(ValueError, match="128"):
        list(features_lib.records_to_examples(records))
    records["descriptor"] = np.zeros((n, 128), np.float32)
    out = list(features_lib.records_to_examples(records))
    assert [k for k, _ in out] == ["v|a|0", "v|a|1"]


def test_package_import_is_light():
    import subprocess
    import sys

    code = "import sys, rp_jax.datasets; print('tensorflow_datasets' in sys.modules)"
    out = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        cwd=Path(__file__).resolve().parents[2],
        env=os.environ,
        check=True,
    )
    assert out.stdout.strip() == "False"


def test_real_config_without_manual_dir_gives_the_instructions(tmp_path):
    b = loading.get_builder("robotcar", config="real", data_dir=tmp_path / "tfds")
    with pytest.raises(LayoutError, match="does not exist") as err:
        b.download_and_prepare()
    assert "stereo.timestamps" in str(err.value)


def test_one_viewpoint_job_is_picklable_and_gives_the_built_records(webcam):
    import pickle

    root = Path(webcam._data_dir_root)
    dataset = registry.get("webcam_clipart")
    captures = dataset.read(root.parent / "synthetic" / "webcam_clipart_tiny")
    config = dataset.ground_truth(webcam.builder_config.max_keypoints)
    cache = root / "downloads" / "groundtruth" / "webcam_clipart" / TINY
    (job,) = builder_lib.viewpoint_jobs(
        "webcam_clipart", captures, ["scene_07"], config=config, cache_dir=cache
    )
    job = pickle.loads(pickle.dumps(job))  # what Beam or a process pool does
    examples = builder_lib.label_viewpoint_examples(job)
    built = _records_by_key(webcam, "test")
    assert {tuple(k.split("|")) for k, _ in examples} == {
        (v.decode(), i.decode(), str(k)) for v, i, k in built
    }


def test_splits_larger_than_the_memory_buffer_are_written_without_tensorflow(
    webcam, tmp_path, monkeypatch
):
    # TFDS spills a split past MAX_MEM_BUFFER_SIZE to bucket files through tf.io.gfile;
    # make that happen at tiny size and check the build still gives the same records.
    from tensorflow_datasets.core import shuffle

    monkeypatch.setattr(shuffle, "MAX_MEM_BUFFER_SIZE", 64 << 10)
    data_dir = tmp_path / "tfds"
    shutil.copytree(Path(webcam._data_dir_root) / "downloads", data_dir / "downloads")
    rebuilt = build_tiny(
        "webcam_clipart",
        data_dir,
        synthetic_root=Path(webcam._data_dir_root).parent / "synthetic" / "webcam_clipart_tiny",
    )
    for split in ("train", "test"):
        assert _records_by_key(rebuilt, split).keys() == _records_by_key(webcam, split).keys()
    assert shuffle.tf is not builder_lib._PYTHON_FILE_IO  # restored after the build
    assert not list((data_dir / "webcam_clipart").rglob("*.tmp*")), "bucket files left"


def test_load_columns_reads_what_the_tfds_decoder_reads(webcam):
    # loading.load_columns parses the serialized records itself (fast path); it must agree
    # with TFDS's own decoder on every feature, values and declared dtypes.
    data_dir = Path(webcam._data_dir_root)
    cols = loading.load_columns(
        "webcam_clipart", "test", keys=features_lib.FEATURE_KEYS, config=TINY, data_dir=data_dir
    )
    infos = webcam.info.features.get_tensor_info()
    records = all_records(webcam, "test")
    for k in features_lib.FEATURE_KEYS:
        ref = np.stack(
            [r[k].decode() if isinstance(r[k], bytes) else np.asarray(r[k]) for r in records]
        )
        assert cols[k].shape == ref.shape, k
        np.testing.assert_array_equal(cols[k], ref, err_msg=k)
        if k not in features_lib.TEXT_KEYS:
            assert cols[k].dtype == np.dtype(infos[k].np_dtype), k
    with pytest.raises(KeyError, match="no_such_feature"):
        loading.load_columns(
            "webcam_clipart", "test", keys=["no_such_feature"], config=TINY, data_dir=data_dir
        )


def test_select_records_keeps_a_seeded_subset_per_image():
    from rp_jax.datasets.builder import select_records

    records = {"image_id": np.array(["a"] * 10 + ["b"] * 3), "viewpoint": np.array(["v"] * 13),
               "x": np.arange(13)}
    picked = select_records(records, 4, seed=0)
    assert list(picked["x"][picked["image_id"] == "b"]) == [10, 11, 12]  # fewer than 4: all
    assert (picked["image_id"] == "a").sum() == 4
    assert list(select_records(records, 4, seed=0)["x"]) == list(picked["x"])  # deterministic
    assert list(select_records(records, 4, seed=1)["x"]) != list(picked["x"])
    assert len(select_records(records, 0)["x"]) == 13


def test_every_dataset_has_one_object_and_unknown_names_are_named():
    from rp_jax.datasets import DATASET_NAMES

    assert tuple(registry.DATASETS) == DATASET_NAMES
    assert registry.get("webcam_clipart").ground_truth(7).verification == "static"
    assert registry.get("webcam_clipart").ground_truth(7).static_pixel_threshold == 5.0
    assert registry.get("cmu_seasons").ground_truth(7).verification == "pose"
    assert registry.get("robotcar").ground_truth(7).max_keypoints == 7
    with pytest.raises(ValueError, match="unknown dataset 'kitti'; known: webcam_clipart"):
        registry.get("kitti")
