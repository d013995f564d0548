"""rp_jax.files.OutputFolder: a command's --out never loses a user's file, and a failed run
leaves nothing of itself (issue 27, findings 3 and 8)."""

import os
from pathlib import Path

import pytest

from rp_jax import files


def test_a_users_file_stops_the_run_before_any_work(tmp_path):
    (tmp_path / "summary.json").write_text("mine")
    with pytest.raises(files.OutputExistsError, match="summary.json, not written by this"), \
            files.OutputFolder(tmp_path, ["summary.json", "model"]):
        raise AssertionError("the body ran")
    assert (tmp_path / "summary.json").read_text() == "mine"
    with files.OutputFolder(tmp_path, ["summary.json"], overwrite=True):
        files.write_text(tmp_path / "summary.json", "ours")
    assert (tmp_path / "summary.json").read_text() == "ours"


def test_its_own_outputs_are_replaced_but_an_edited_one_is_the_users(tmp_path):
    out = tmp_path / "out"
    with files.OutputFolder(out, ["a.npz", "model"]):
        files.write_bytes(out / "a.npz", b"1")
        (out / "model").mkdir()
    with files.OutputFolder(out, ["a.npz", "model"]):  # a second run: no question
        files.write_bytes(out / "a.npz", b"22")
    (out / "a.npz").write_bytes(b"edited by hand")
    os.utime(out / "a.npz", ns=(1, 1))
    with pytest.raises(files.OutputExistsError, match="a.npz"), \
            files.OutputFolder(out, ["a.npz"]):
        pass


def test_a_failed_run_leaves_nothing_behind(tmp_path):
    out = tmp_path / "new"
    with pytest.raises(RuntimeError), files.OutputFolder(out, ["a.npz", "b.png", "model"]):
        files.write_bytes(out / "a.npz", b"1")
        (out / "model").mkdir()
        (out / "model" / "x.bin").write_bytes(b"x")
        raise RuntimeError("half-way")
    assert not out.exists()
    # In a folder of the user's, only what the run wrote goes; the rest stays.
    keep = tmp_path / "kept"
    keep.mkdir()
    (keep / "notes.txt").write_text("mine")
    with pytest.raises(RuntimeError), files.OutputFolder(keep, ["a.npz"]):
        files.write_bytes(keep / "a.npz", b"1")
        raise RuntimeError("half-way")
    assert sorted(p.name for p in keep.iterdir()) == ["notes.txt"]


def test_out_that_is_a_file(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(files.OutputExistsError, match="is a file"), \
            files.OutputFolder(tmp_path / "f", ["a"]):
        pass


def test_folder_problem_names_why_a_folder_cannot_be_written(tmp_path, monkeypatch):
    (tmp_path / "notes").write_text("x")
    assert files.folder_problem(tmp_path) is None
    assert files.folder_problem(tmp_path / "new" / "deeper") is None  # created when written
    assert files.folder_problem(tmp_path / "notes") == "is a file, not a folder"
    assert files.folder_problem(tmp_path / "notes" / "run" / "x") == (
        f"cannot be created: {tmp_path / 'notes'} is a file")
    assert not list(tmp_path.glob("new"))  # it only reads
    # No permission (a plain user's view; the suite may run with root's rights, which
    # os.access answers as allowed, so the answer is given here).
    locked = tmp_path / "locked"
    locked.mkdir()
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: Path(p) != locked and real(p, mode))
    assert files.folder_problem(locked) == "is a folder you may not write in"
    assert files.folder_problem(locked / "run") == (
        f"cannot be created: you may not write in {locked}")


def test_out_that_cannot_be_created(tmp_path):
    (tmp_path / "notes").write_text("x")
    with pytest.raises(files.FolderNotWritableError, match=r"--out .*notes/out cannot be "
                       r"created: .*notes is a file"), \
            files.OutputFolder(tmp_path / "notes" / "out", ["a"]):
        pass
