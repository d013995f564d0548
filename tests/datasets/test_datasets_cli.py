"""``python -m rp_jax.datasets build|curves`` (Sec. III-D; Fig. 6 and Fig. 9 curves)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import cv2
import pytest

pytest.importorskip("tensorflow_datasets")

from rp_jax.datasets.__main__ import main
from tests.datasets._tiny import TINY, build_tiny, shared_data_dir


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory):
    # Shared with test_builders.py: the tiny world and build are made once per session, by
    # whichever test asks first (build_tiny's lock keeps another worker's build out).
    data_dir = shared_data_dir(tmp_path_factory)
    build_tiny("webcam_clipart", data_dir)
    return data_dir


def _run(capsys, *argv) -> tuple[int, str, str]:
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def _not_blank(path: Path) -> None:
    image = cv2.imread(str(path))
    assert image is not None, f"{path} is not a readable PNG"
    assert image.shape[0] > 100 and image.shape[1] > 100
    assert image.std() > 5, f"{path} is blank"
    # Curves are coloured lines, not just black axes on white.
    saturation = cv2.cvtColor(image, cv2.COLOR_BGR2HSV)[..., 1]
    assert (saturation > 100).sum() > 50


def test_build_prints_counts_per_split_slot_and_category(capsys, data_dir):
    args = ("build", "webcam_clipart", "--size", "tiny", "--data-dir", str(data_dir))
    code, out, _ = _run(capsys, *args, "--workers", "1")
    assert code == 0
    lines = out.splitlines()
    split_lines = [line for line in lines if line.startswith(("train:", "test:"))]
    assert [line.split(":")[0] for line in split_lines] == ["train", "test"]
    for line in split_lines:
        assert int(line.split()[1]) > 0
    slot_lines = [line for line in lines if "per timestamp:" in line]
    assert len(slot_lines) == 2 and "08:00=" in slot_lines[0] and "18:00=" in slot_lines[0]
    # The per-timestamp counts add up to the split size.
    for split_line, slot_line in zip(split_lines, slot_lines):
        counts = [int(item.split("=")[1]) for item in slot_line.split(": ")[1].split(", ")]
        assert sum(counts) == int(split_line.split()[1])
    assert any("per category:" in line and "building=" in line for line in lines)
    # A second build finds the dataset and does not rebuild it.
    code, out, _ = _run(capsys, *args)
    assert code == 0 and "already built" in out


def test_curves_writes_non_blank_pngs(capsys, data_dir, tmp_path):
    out_png = tmp_path / "figures" / "webcam_curves.png"
    args = ("curves", "webcam_clipart", "--size", "tiny", "--data-dir", str(data_dir))
    code, out, _ = _run(capsys, *args, "--out", str(out_png))
    assert code == 0, out
    _not_blank(out_png)
    categories_png = out_png.with_name("webcam_curves_categories.png")
    _not_blank(categories_png)
    assert f"wrote {out_png}" in out and f"wrote {categories_png}" in out
    own_png = out_png.with_name("webcam_curves_own_date.png")
    _not_blank(own_png)
    assert "own timestamp vs others:" in out
    # The printed curve values are repeatabilities.
    values = [
        float(v.split("=")[1])
        for line in out.splitlines()
        if line.startswith("test:")
        for v in line.split(": ")[1].split(", ")
    ]
    assert values and all(0.0 <= v <= 1.0 for v in values)


def test_a_data_dir_one_may_not_write_in_is_read_but_not_built_in(capsys, data_dir, tmp_path,
                                                                   monkeypatch):
    """A shared, read-only TFDS store: curves read it; build, which writes there, stops first
    (os.access answered as for a plain user: the suite may run with root's rights)."""
    import os

    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: (Path(p) != data_dir or not mode & os.W_OK)
                        and real(p, mode))
    code, _, err = _run(capsys, "curves", "webcam_clipart", "--size", "tiny", "--data-dir",
                        str(data_dir), "--out", str(tmp_path / "c.png"))
    assert code == 0, err
    code, _, err = _run(capsys, "build", "webcam_clipart", "--size", "tiny", "--data-dir",
                        str(data_dir))
    assert code == 2 and f"--data-dir {data_dir} is a folder you may not write in" in err


def test_bad_arguments_give_clear_messages(capsys, tmp_path):
    # --manual-dir selects the real data; a synthetic size beside it is a contradiction.
    code, _, err = _run(capsys, "build", "robotcar", "--size", "tiny", "--manual-dir",
                        str(tmp_path), "--data-dir", str(tmp_path))
    assert code == 2 and "--size tiny is the synthetic world's size" in err
    code, _, err = _run(capsys, "curves", "robotcar", "--size", "tiny", "--data-dir",
                        str(tmp_path / "empty"), "--out", str(tmp_path / "c.png"))
    assert code == 2 and "not built" in err
    # The command it suggests uses this command's own flags.
    assert "python -m rp_jax.datasets build robotcar --size tiny --data-dir" in err
    code, _, err = _run(capsys, "curves", "robotcar", "--out", str(tmp_path / "c.jpg"))
    assert code == 2 and ".png" in err
    code, _, err = _run(capsys, "build", "cmu_seasons", "--manual-dir", str(tmp_path / "missing"))
    assert code == 2 and "not a folder" in err
    manual = tmp_path / "manual"
    manual.mkdir()
    (manual / "notes.txt").write_text("not a dataset")
    code, _, err = _run(capsys, "build", "cmu_seasons", "--manual-dir", str(manual),
                        "--data-dir", str(tmp_path / "tfds"))
    assert code == 2 and "intrinsics.txt" in err
    for argv in (["build", "imagenet"], ["build", "robotcar", "--size", "huge"], ["curves"]):
        with pytest.raises(SystemExit) as exit_info:
            main(argv)
        assert exit_info.value.code == 2
        assert "invalid choice" in capsys.readouterr().err or argv == ["curves"]


def test_released_config_flag_still_works_with_a_warning(capsys, data_dir, tmp_path):
    # --config NAME (a TFDS builder config) was this command's spelling: one more release.
    code, out, err = _run(capsys, "build", "webcam_clipart", "--config", TINY, "--data-dir",
                          str(data_dir))
    assert code == 0 and "already built" in out
    assert f"--config {TINY} is deprecated" in err and "use --size tiny" in err
    code, _, err = _run(capsys, "build", "webcam_clipart", "--config", TINY, "--size", "tiny",
                        "--data-dir", str(data_dir))
    assert code == 2 and "disagree" in err


def test_module_entry_point_help():
    out = subprocess.run(
        [sys.executable, "-m", "rp_jax.datasets", "--help"],
        capture_output=True,
        text=True,
        check=True,
        cwd=Path(__file__).resolve().parents[2],
    )
    assert "build" in out.stdout and "curves" in out.stdout
