"""Shared helpers of the dataset tests: tiny synthetic builds and record checks.

``shared_data_dir`` is one TFDS data dir for the whole test session, seen by every xdist
worker: each tiny world is rendered and each tiny dataset built there once, by the first
test that asks (``build_tiny`` holds a lock per dataset while it builds, so a second worker
waits and then finds the build done). Tests read it and copy what they change (a copy of
a build that changed after it was built fails, naming the files):
``tiny_data_copy`` gives a test a data dir of its own holding copies of the session's tiny
builds (and their worlds), so the end-to-end runs of the experiments and notebooks read
built datasets instead of each rendering and labelling the same tiny world again.
``tiny_world`` and ``tiny_world_copy`` do the same for a tiny world alone (a layout the
map-summarization commands or the readers' tests read): rendered once, where the session's
build of that preset would render it.
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rp_jax.datasets import features as features_lib
from rp_jax.datasets import loading
from tests import _session_cache

TINY = "synthetic_tiny"


def shared_data_dir(tmp_path_factory) -> Path:
    # The synthetic worlds land in <base>/synthetic/ beside it (test_datasets_cli.py,
    # test_outcomes.py and test_builders.py use the same place).
    return _session_cache.shared_base(tmp_path_factory) / "datasets_shared" / "tfds"


def build_tiny(name: str, data_dir: Path, **kwargs):
    """The ``synthetic_tiny`` build of ``name`` in ``data_dir`` (built unless it is there)."""
    data_dir = Path(data_dir)
    # Two workers building one dataset in one data dir at once would write the same files.
    with _build_lock(data_dir, name):
        b = loading.get_builder(name, config=TINY, data_dir=data_dir, workers=1, **kwargs)
        built_before = b.is_prepared()
        b.download_and_prepare()  # a no-op where built (tests/datasets/test_builders.py)
        if not built_before:
            _built_record(data_dir, name).write_text(json.dumps(_files_of(data_dir, name)))
    return b


def _build_lock(data_dir: Path, name: str):
    """The lock of ``name``'s build and world in ``data_dir`` (held while either is made)."""
    return _session_cache.locked(data_dir.parent / f".build-{name}.lock")


def _built_record(data_dir: Path, name: str) -> Path:
    return data_dir.parent / f".built-{name}.json"


def _files_of(data_dir: Path, name: str) -> dict[str, list[int]]:
    """{file: [size, mtime_ns]} of what ``tiny_data_copy`` copies of ``name``'s build."""
    roots = (data_dir / name, data_dir / "downloads" / "groundtruth" / name / TINY,
             data_dir.parent / "synthetic" / f"{name}_tiny")
    files = (p for root in roots for p in sorted(root.rglob("*"))
             if p.is_file() and not p.name.endswith(".lock"))
    return {str(p.relative_to(data_dir.parent)): [(st := p.stat()).st_size, st.st_mtime_ns]
            for p in files}


def _unchanged_since_built(data_dir: Path, name: str) -> None:
    """Fail, naming the files, if ``name``'s build in ``data_dir`` changed after it was built.

    The session's builds are shared: a test that writes into one (say, computes outcomes,
    which writes the label cache again) changes what every later test copies, and races a
    copy in another worker. It must work on ``tiny_data_copy``'s copy instead.
    """
    record = _built_record(data_dir, name)
    if not record.exists():  # not built by build_tiny: nothing to compare with
        return
    before, now = json.loads(record.read_text()), _files_of(data_dir, name)
    changed = sorted(k for k in before.keys() | now.keys() if before.get(k) != now.get(k))
    assert not changed, (f"the session's tiny {name} build in {data_dir} changed after it was "
                         f"built ({len(changed)} files: {', '.join(changed[:4])}): a test wrote "
                         "into it instead of into a copy (tiny_data_copy)")


def tiny_data_copy(tmp_path_factory, names: Sequence[str], dest: Path) -> Path:
    """A TFDS data dir in ``dest`` holding a copy of the session's tiny build of each of
    ``names`` (built first where missing), with what the experiments read beside it.

    ``dest/tfds``: each dataset's ``synthetic_tiny`` build and its label cache
    (``downloads/groundtruth``); ``dest/synthetic``: the rendered tiny worlds, where
    ``builder.synthetic_root`` looks for them. A command given ``--data-dir dest/tfds`` finds
    everything built, as on its own second run, and may change its copy freely.

    Returns:
      ``dest/tfds``.
    """
    shared = shared_data_dir(tmp_path_factory)
    data_dir = Path(dest) / "tfds"
    for name in names:
        build_tiny(name, shared)
        with _build_lock(shared, name):
            _unchanged_since_built(shared, name)
            for rel in (Path(name), Path("downloads") / "groundtruth" / name / TINY):
                shutil.copytree(shared / rel, data_dir / rel,
                                ignore=shutil.ignore_patterns("*.lock"))
            world = Path("synthetic") / f"{name}_tiny"
            shutil.copytree(shared.parent / world, Path(dest) / world)
    return data_dir


def tiny_world(tmp_path_factory, name: str, seed: int = 0) -> Path:
    """The session's tiny synthetic world of the preset ``name`` and ``seed``, rendered once
    (in this process, by the first test that asks) where the session's tiny build of
    ``name`` renders and reads it, beside ``shared_data_dir``. Read it; copy what you change
    (``tiny_world_copy``)."""
    from rp_jax.datasets import builder

    shared = shared_data_dir(tmp_path_factory)
    root = builder.synthetic_root(shared, name, "tiny", seed)
    with _build_lock(shared, name):
        builder.ensure_synthetic(name, root, size="tiny", seed=seed, workers=1)
    return root


def tiny_world_copy(tmp_path_factory, name: str, dest: Path, seed: int = 0) -> Path:
    """A copy of ``tiny_world`` in ``dest`` (a folder not there yet), for a test or command
    that may write into it: ``builder.synthetic_root(data_dir, name, "tiny", seed)`` of the
    data dir a command is given, for the command to find it rendered."""
    world = tiny_world(tmp_path_factory, name, seed)
    with _build_lock(shared_data_dir(tmp_path_factory), name):
        shutil.copytree(world, dest, ignore=shutil.ignore_patterns("*.lock"))
    return Path(dest)


def all_records(b, split: str) -> list[dict]:
    source = b.as_data_source(split)
    return source.__getitems__(list(range(len(source))))


def check_records(records: list[dict], T: int, schedule) -> None:
    keys = set()
    for r in records:
        assert set(r) == set(features_lib.FEATURE_KEYS)
        assert r["patch"].shape == (64, 64, 3) and r["patch"].dtype == np.uint8
        assert r["descriptor"].shape == (128,) and r["descriptor"].dtype == np.float32
        assert r["label"].shape == (T,) and r["label"].dtype == np.float32
        assert r["label_mask"].shape == (T,) and r["label_mask"].dtype == bool
        for k in ("xy", "xy_normalized"):
            assert r[k].shape == (2,) and r[k].dtype == np.float32
        assert r["image_size"].dtype == np.int32 and np.all(r["image_size"] > 0)
        np.testing.assert_allclose(
            r["xy_normalized"], np.clip(r["xy"] / r["image_size"], 0, 1), atol=1e-6
        )
        mask, label = r["label_mask"], r["label"]
        assert np.all((label[mask] >= 0) & (label[mask] <= 1))
        assert mask[r["slot"]], "the image's own timestamp must be observed"
        assert 0 <= r["cycle"] and -1 <= r["category"] <= 5
        assert 1 <= r["month"] <= 12 and 1 <= r["day"] <= 31 and 0 <= r["hour"] < 24
        if schedule.cycle == "day":  # the record's wall-clock time lies near its slot
            minutes = r["hour"] * 60 + r["minute"]
            assert abs(minutes * 60 - schedule.offsets[r["slot"]]) <= schedule.tolerance
        keys.add((r["viewpoint"], r["image_id"], r["keypoint_id"]))
    assert len(keys) == len(records)
