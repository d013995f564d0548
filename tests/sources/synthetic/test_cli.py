"""Tests of the synthetic world's command line (rp_jax/sources/synthetic/__main__.py)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from rp_jax.sources.synthetic import __main__ as cli
from rp_jax.sources.synthetic import frame_jobs

REPO = Path(__file__).resolve().parents[3]


@pytest.mark.parametrize(
    "argv, message",
    [
        ([], "required"),
        (["kitti", "out"], "invalid choice"),
        (["robotcar", "out", "--size", "huge"], "invalid choice"),
        (["robotcar", "out", "--workers", "0"], ">= 1"),
        (["robotcar", "out", "--seed", "-3"], ">= 0"),
        (["robotcar", "out", "--seed", "abc"], "expected an integer"),
        (["contact-sheet", "sheet.jpg"], "must end in .png"),
        (["contact-sheet", "sheet.png", "--scene", "9"], "0..7"),
    ],
)
def test_bad_arguments_exit_2_with_a_message(argv, message, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    assert exc.value.code == 2
    assert message in capsys.readouterr().err


def test_out_dir_that_is_a_file(tmp_path, capsys):
    f = tmp_path / "a_file"
    f.write_text("x")
    with pytest.raises(SystemExit) as exc:
        cli.main(["webcam_clipart", str(f), "--size", "tiny"])
    assert exc.value.code == 2
    assert f"OUT_DIR {f} is a file, not a folder" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:  # before any work, not a traceback at the end
        cli.main(["webcam_clipart", str(f / "world"), "--size", "tiny"])
    assert exc.value.code == 2
    assert f"OUT_DIR {f / 'world'} cannot be created: {f} is a file" in capsys.readouterr().err


def test_tiny_run_writes_layout(tmp_path, monkeypatch, capsys):
    from test_presets import fake_render, fake_scene

    monkeypatch.setattr(frame_jobs, "scene_of", fake_scene)
    monkeypatch.setattr(frame_jobs, "render_frame", fake_render)
    out = tmp_path / "webcam"
    assert (
        cli.main(["webcam_clipart", str(out), "--size", "tiny", "--workers", "1", "--quiet"]) == 0
    )
    assert capsys.readouterr().out.strip() == str(out)
    assert sorted(p.name for p in (out / "scene_00").glob("*.jpg"))
    assert (out / "scene_00" / "scene.json").exists()


def test_module_entry_point():
    run = subprocess.run(
        [sys.executable, "-m", "rp_jax.sources.synthetic", "kitti", "/tmp/x"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert run.returncode == 2
    assert "webcam_clipart" in run.stderr  # the choices are listed
    ok = subprocess.run(
        [sys.executable, "-m", "rp_jax.sources.synthetic", "cmu_seasons", "--help"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert ok.returncode == 0 and "--size" in ok.stdout


@pytest.mark.slow
def test_a_parallel_render_ends_without_killing_its_workers(tmp_path, tmp_path_factory):
    """Leaving the render pool through ``with`` terminated it: its SIGTERM reached workers
    that were already exiting, and JAX's signal handler printed a stack trace for each
    ("*** SIGTERM received ***"; 4 in each of 3 runs of this command before the fix).

    The command resumes the session's tiny world with two thirds of its frames removed: 32
    frames to render, two processes' worth (``MIN_FRAMES_PER_WORKER``), whose files must be
    those the session rendered in one process."""
    from rp_jax.sources.synthetic import presets
    from tests.datasets._tiny import tiny_world, tiny_world_copy

    out = tiny_world_copy(tmp_path_factory, "cmu_seasons", tmp_path / "cmu")
    jobs = presets.plan("cmu_seasons", out, size="tiny", seed=0).jobs
    removed = jobs[len(jobs) - 2 * frame_jobs.MIN_FRAMES_PER_WORKER:]
    assert len(removed) == 32 and all(job.done() for job in jobs)
    for job in removed:
        job.image_path.unlink()
    run = subprocess.run(
        [sys.executable, "-m", "rp_jax.sources.synthetic", "cmu_seasons", "--size", "tiny",
         "--workers", "2", str(out)],
        cwd=REPO, capture_output=True, text=True, timeout=600, check=False,
    )
    assert run.returncode == 0, run.stderr
    assert "SIGTERM" not in run.stderr and "Aborted" not in run.stderr, run.stderr[-2000:]
    assert "rendering 32" in run.stderr  # the frames removed, and only those
    assert _files(out) == _files(tiny_world(tmp_path_factory, "cmu_seasons"))


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes()
            for p in sorted(root.rglob("*")) if p.is_file()}
