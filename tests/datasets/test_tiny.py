"""The shared tiny builds' guard (tests/datasets/_tiny.py): a test that writes into the
session's build, instead of into its copy, fails the next copy, naming the files."""

import json

import pytest

from tests.datasets import _tiny


def _fake_build(data_dir, name):
    for rel in (name + "/1.0.0/records.array_record",
                f"downloads/groundtruth/{name}/{_tiny.TINY}/labels/x/scene_00.npz"):
        (data_dir / rel).parent.mkdir(parents=True, exist_ok=True)
        (data_dir / rel).write_bytes(b"built")
    world = data_dir.parent / "synthetic" / f"{name}_tiny" / "frame.jpg"
    world.parent.mkdir(parents=True)
    world.write_bytes(b"frame")
    _tiny._built_record(data_dir, name).write_text(json.dumps(_tiny._files_of(data_dir, name)))


def test_a_build_changed_after_it_was_built_is_named(tmp_path):
    data_dir = tmp_path / "tfds"
    _fake_build(data_dir, "webcam_clipart")
    _tiny._unchanged_since_built(data_dir, "webcam_clipart")  # as built: nothing to say
    labels = data_dir / f"downloads/groundtruth/webcam_clipart/{_tiny.TINY}/labels/x"
    (labels / "scene_00.npz").write_bytes(b"labelled again")
    (labels / "scene_00.outcomes.npz").write_bytes(b"new")
    (labels.parent.parent / ".build.lock").write_bytes(b"")  # locks are not the build's
    with pytest.raises(AssertionError, match=r"2 files: .*scene_00\.npz, .*scene_00\.outcomes"):
        _tiny._unchanged_since_built(data_dir, "webcam_clipart")


def test_a_build_without_a_record_is_not_judged(tmp_path):
    data_dir = tmp_path / "tfds"
    _fake_build(data_dir, "robotcar")
    _tiny._built_record(data_dir, "robotcar").unlink()
    (data_dir / "robotcar" / "1.0.0" / "records.array_record").write_bytes(b"changed")
    _tiny._unchanged_since_built(data_dir, "robotcar")
