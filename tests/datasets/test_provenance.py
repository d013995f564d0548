"""A built real dataset knows what it was built from (issue 14, item 1)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from rp_jax.datasets import __main__ as cli
from rp_jax.datasets import provenance

STAMPS = ("20100601_080000", "20100601_083000", "20100602_080000")


def _download(root, seed):
    """A real Webcam Clip Art layout: two static scenes of textured frames."""
    rng = np.random.default_rng(seed)
    for scene in ("houseA", "houseB"):
        base = cv2.GaussianBlur(rng.integers(0, 255, (72, 96, 3), np.uint8), (0, 0), 1.5)
        for k, stamp in enumerate(STAMPS):
            (root / scene).mkdir(parents=True, exist_ok=True)
            frame = np.clip(base.astype(int) + 4 * k, 0, 255).astype(np.uint8)
            assert cv2.imwrite(str(root / scene / f"{stamp}.png"), frame)
    return root


def _build(manual, tfds_dir):
    return cli.main(["build", "webcam_clipart", "--manual-dir", str(manual),
                     "--data-dir", str(tfds_dir), "--workers", "1"])


def test_a_second_download_is_refused_not_read_as_the_first(tmp_path, capsys):
    a, b = _download(tmp_path / "A", 0), _download(tmp_path / "B", 1)
    tfds_dir = tmp_path / "tfds"
    assert _build(a, tfds_dir) == 0
    built = next(tfds_dir.glob("webcam_clipart/real/*/" + provenance.BUILT_FROM_JSON))
    record = json.loads(built.read_text())
    assert record["layout"]["root"] == str(a) and record["layout"]["files"] == 6
    capsys.readouterr()

    assert _build(a, tfds_dir) == 0  # the same download: already built
    assert "already built" in capsys.readouterr().out

    assert _build(b, tfds_dir) == 2  # another download: refused, not A's counts
    err = capsys.readouterr().err
    assert f"built from {a}" in err and f"not from {b}" in err and "--data-dir" in err

    frame = a / "houseA" / f"{STAMPS[0]}.png"  # the same folder, a file rewritten
    st = frame.stat()
    os.utime(frame, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    assert _build(a, tfds_dir) == 2
    assert "its files changed since" in capsys.readouterr().err


def test_labelling_settings_are_part_of_the_fingerprint(tmp_path, monkeypatch):
    from rp_jax.datasets import loading

    a = _download(tmp_path / "A", 0)
    builder = loading.get_builder("webcam_clipart", config="real", data_dir=tmp_path / "t",
                                  workers=1)
    assert provenance.prepare(builder, a) is True
    assert provenance.prepare(builder, a) is False
    fp = provenance.labelling_fingerprint(builder)
    monkeypatch.setattr(provenance, "labelling_fingerprint",
                        lambda b: {**fp, "digest": "other", "version": "0.0.1"})
    with pytest.raises(provenance.BuiltFromAnotherLayoutError, match="version differ"):
        provenance.prepare(builder, a)


def test_the_camera_place_in_the_data_spec_is_not_part_of_the_labelling(tmp_path, monkeypatch):
    # data_specs' location feeds only the conditional predictor's sun: adding it to a spec
    # must not refuse every dataset built before; a field the labelling reads must.
    from rp_jax import schedule
    from rp_jax.datasets import loading

    builder = loading.get_builder("cmu_seasons", config="synthetic_tiny",
                                  data_dir=tmp_path / "t", workers=1)
    spec = schedule.load_spec("cmu_seasons")
    assert "location" in spec
    before = provenance.labelling_fingerprint(builder)["digest"]
    without = {k: v for k, v in spec.items() if k not in ("location", "location_note")}
    monkeypatch.setattr(schedule, "load_spec", lambda name: without)
    assert provenance.labelling_fingerprint(builder)["digest"] == before
    monkeypatch.setattr(schedule, "load_spec", lambda name: {**spec, "timezone": "UTC"})
    assert provenance.labelling_fingerprint(builder)["digest"] != before


def test_a_synthetic_build_of_another_world_version_is_built_again(
        tmp_path, tmp_path_factory, monkeypatch, caplog):
    from rp_jax.datasets import loading
    from rp_jax.sources.synthetic import output_folder, presets
    from tests.datasets._tiny import tiny_data_copy

    data_dir = tiny_data_copy(tmp_path_factory, ["robotcar"], tmp_path / "d")

    def builder():
        return loading.get_builder("robotcar", config="synthetic_tiny", data_dir=data_dir,
                                   workers=1)

    b = builder()
    now = presets.world_version("robotcar")
    record = json.loads((Path(b.data_dir) / provenance.BUILT_FROM_JSON).read_text())
    assert record["synthetic"]["preset"] == "robotcar" and record["synthetic"]["world"] == now
    assert record["synthetic"]["size"] == "tiny"
    assert provenance.synthetic_staleness(b) is None
    assert provenance.prepare(b) is False  # this world, these settings: kept as built
    train_before = b.info.splits["train"].num_examples

    # The code moves the world on: the build and its layout are made again, saying why.
    monkeypatch.setitem(presets._PRESET_WORLD_VERSIONS, "robotcar", now + 1)
    assert f"version {now} of the synthetic robotcar world" in provenance.synthetic_staleness(b)
    with caplog.at_level("WARNING"):
        loading.load_columns("robotcar", "train", keys=("label",), config="synthetic_tiny",
                             data_dir=data_dir)
    assert "builds it again" in caplog.text and f"renders version {now + 1}" in caplog.text
    from rp_jax.datasets import outcomes

    # The per-pair outcomes written beside the old records.
    sidecar = outcomes.sidecar_dir(data_dir, "robotcar", "synthetic_tiny", b.version)
    (sidecar / "train").mkdir(parents=True)
    (sidecar / "train" / "vp.npz").write_bytes(b"old rows")
    assert provenance.prepare(b) is True
    assert not sidecar.exists()
    assert provenance.synthetic_staleness(b) is None
    layout = output_folder.folder_parameters(b.synthetic_layout_root())
    assert layout["world"] == now + 1
    assert b.info.splits["train"].num_examples == builder().info.splits["train"].num_examples
    assert train_before > 0


def test_a_synthetic_build_without_its_world_or_with_other_labelling_is_stale(
        tmp_path, tmp_path_factory, monkeypatch):
    from rp_jax.datasets import loading
    from tests.datasets._tiny import tiny_data_copy

    data_dir = tiny_data_copy(tmp_path_factory, ["robotcar"], tmp_path / "d")
    b = loading.get_builder("robotcar", config="synthetic_tiny", data_dir=data_dir, workers=1)
    assert provenance.synthetic_staleness(b) is None
    fp = provenance.labelling_fingerprint(b)
    monkeypatch.setattr(provenance, "labelling_fingerprint",
                        lambda b: {**fp, "digest": "other", "version": "0.0.1"})
    assert "other settings (version differ)" in provenance.synthetic_staleness(b)
    monkeypatch.undo()
    (Path(b.data_dir) / provenance.BUILT_FROM_JSON).unlink()  # a build older than the record
    assert "before builds recorded" in provenance.synthetic_staleness(b)
