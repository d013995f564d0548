"""Atomic writes, readable by others (rp_jax.files)."""

import os
import stat

import numpy as np
import pytest

from rp_jax import files


def _mode(path):
    return stat.S_IMODE(os.stat(path).st_mode)


@pytest.fixture
def umask_022():
    old = os.umask(0o022)
    yield
    os.umask(old)


def test_written_files_are_readable_by_others_and_whole(tmp_path, umask_022):
    p = files.write_json(tmp_path / "sub" / "a.json", {"x": 1})
    assert p.read_text() == '{\n  "x": 1\n}\n'
    assert _mode(p) == 0o644  # tempfile alone would leave 0600
    files.write_text(p, "second")
    assert p.read_text() == "second" and _mode(p) == 0o644
    assert [q.name for q in p.parent.iterdir()] == ["a.json"]  # no temporary left


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path):
    p = files.write_text(tmp_path / "a.txt", "old")
    with pytest.raises(RuntimeError), files.replacing(p) as tmp:
        tmp.write_text("half")
        raise RuntimeError("killed mid-write")
    assert p.read_text() == "old"
    assert [q.name for q in tmp_path.iterdir()] == ["a.txt"]


def test_writers_that_want_a_file_object(tmp_path):
    p = tmp_path / "d.npz"
    with files.replacing(p) as tmp, open(tmp, "wb") as f:
        np.savez(f, a=np.arange(3))
    np.testing.assert_array_equal(np.load(p)["a"], [0, 1, 2])


def test_publish_dir_replaces_a_folder_with_plain_permissions(tmp_path, umask_022):
    final = tmp_path / "model"
    final.mkdir()
    (final / "old.bin").write_text("old")
    new = tmp_path / ".model.new"
    new.mkdir(mode=0o700)
    (new / "points3D.bin").write_text("new")
    os.chmod(new / "points3D.bin", 0o600)
    files.publish_dir(new, final)
    assert sorted(q.name for q in final.iterdir()) == ["points3D.bin"]
    assert _mode(final) == 0o755 and _mode(final / "points3D.bin") == 0o644
    assert sorted(q.name for q in tmp_path.iterdir()) == ["model"]
