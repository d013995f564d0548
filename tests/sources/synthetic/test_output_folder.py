"""The synthetic generator writes only into its own folder (issue 14, item 3)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from rp_jax.sources.synthetic import __main__ as cli
from rp_jax.sources.synthetic import frame_jobs, output_folder, presets
from tests.sources.synthetic.test_presets import fake_render, fake_scene


@pytest.fixture
def fake_world(monkeypatch):
    monkeypatch.setattr(frame_jobs, "scene_of", fake_scene)
    monkeypatch.setattr(frame_jobs, "render_frame", fake_render)


def _checksums(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def _download_copy(root: Path) -> Path:
    """A stand-in for a copy of a real CMU download (the files the generator also writes)."""
    (root / "slice6" / "database").mkdir(parents=True)
    (root / "intrinsics.txt").write_text("c0 OPENCV 1024 768 868.99 866.06 525.94 420.04 "
                                         "-0.399 0.189 0.0002 0.0006\n")
    (root / "slice6" / "ground-truth-database-images-slice6.txt").write_text("user's poses\n")
    (root / "slice6" / "database" / "img_00001_c0_1303494005000000us.jpg").write_bytes(b"jpg")
    return root


def _generate(out, seed=5, **kwargs):
    return presets.generate("cmu_seasons", out, size="tiny", seed=seed, workers=1,
                            progress=False, **kwargs)


def test_refuses_a_folder_it_did_not_write(fake_world, tmp_path, capsys):
    root = _download_copy(tmp_path / "copy")
    before = _checksums(root)
    with pytest.raises(output_folder.OutputFolderError,
                       match=r"not written by the synthetic generator"
                             r".*intrinsics.txt.*--overwrite"):
        _generate(root)
    assert _checksums(root) == before  # nothing written
    code = cli.main(["cmu_seasons", str(root), "--size", "tiny", "--workers", "1", "--quiet"])
    assert code == 2 and "--overwrite" in capsys.readouterr().err
    assert _checksums(root) == before
    # Asked to: every frame is rendered over the files there, then the folder is marked.
    _generate(root, overwrite=True)
    assert _checksums(root) != before
    marker = json.loads((root / output_folder.PARAMETERS_JSON).read_text())
    assert marker == {"generator": "rp_jax.sources.synthetic", "preset": "cmu_seasons",
                      "size": "tiny", "seed": 5, "world": presets.WORLD_VERSION}


def test_refuses_its_own_folder_of_other_parameters(fake_world, tmp_path):
    a = _generate(tmp_path / "a", seed=5)
    done = json.loads((a / "_synthetic" / "generation.json").read_text())
    assert {k: done[k] for k in ("generator", "preset", "size", "seed", "world")} == {
        "generator": "rp_jax.sources.synthetic", "preset": "cmu_seasons", "size": "tiny",
        "seed": 5, "world": presets.WORLD_VERSION}
    before = _checksums(a)
    with pytest.raises(output_folder.OutputFolderError,
                       match=r"other parameters: seed 5 \(asked 6\).*mix two worlds"):
        _generate(a, seed=6)
    with pytest.raises(output_folder.OutputFolderError, match=r"preset 'cmu_seasons' \(asked "):
        presets.generate("webcam_clipart", a, size="tiny", seed=5, workers=1, progress=False)
    assert _checksums(a) == before
    _generate(a, seed=5)  # the same parameters: resumed, nothing changes
    assert _checksums(a) == before
    # --overwrite replaces the whole render: the same files as seed 6 rendered afresh.
    _generate(a, seed=6, overwrite=True)
    assert _checksums(a) == _checksums(_generate(tmp_path / "b", seed=6))


def test_a_killed_render_is_still_its_own(fake_world, tmp_path, monkeypatch):
    calls = []

    def killed(job):
        if len(calls) == 3:
            raise KeyboardInterrupt
        calls.append(job)
        return fake_render(job)

    monkeypatch.setattr(frame_jobs, "render_frame", killed)
    with pytest.raises(KeyboardInterrupt):
        _generate(tmp_path / "a")
    assert not (tmp_path / "a" / "_synthetic" / "generation.json").exists()
    monkeypatch.setattr(frame_jobs, "render_frame", fake_render)
    _generate(tmp_path / "a")  # resumes: no --overwrite needed
    with pytest.raises(output_folder.OutputFolderError, match="seed 5"):
        _generate(tmp_path / "a", seed=7)
