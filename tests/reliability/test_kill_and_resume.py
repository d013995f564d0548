"""SIGKILL at a stage, then the same command again: the result of an uninterrupted run.

The process is killed by itself at a chosen point (deterministic, unlike a timer): while
rendering the synthetic world (after a few frames were written), while
labelling (after the first viewpoint is labelled and cached, inside TFDS's partial build
folder) and while an orbax checkpoint is being written (after the save started, before it
was finalised). No ``finally`` runs, as with a real kill. The re-run must give records, or
parameters, identical to those of a run never killed, and leave no partial folder behind.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from tests.datasets._tiny import tiny_world
from tests.reliability.test_bad_input import DAYS, _webcam_download

ROOT = Path(__file__).resolve().parents[2]
KEYS = ("patch", "xy", "label", "label_mask", "viewpoint", "image_id", "keypoint_id")


def _killed(script: str) -> None:
    """Run ``script`` in a fresh interpreter; it must die of SIGKILL."""
    done = subprocess.run([sys.executable, "-c", textwrap.dedent(script)], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == -9, f"not killed (exit {done.returncode}):\n{done.stderr[-2000:]}"


def _files(root: Path) -> dict[str, str]:
    import hashlib

    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.mark.slow
def test_a_render_killed_midway_resumes_to_the_same_files(tmp_path, tmp_path_factory):
    from rp_jax.sources.synthetic import __main__ as synthetic_cli

    argv = ["webcam_clipart", "--size", "tiny", "--workers", "1", "--quiet"]
    _killed(f"""
        import os, signal
        from rp_jax.sources.synthetic import __main__ as cli, frame_jobs
        render, frames = frame_jobs.render_job, []
        def render_then_die(job):
            out = render(job)  # this frame is written
            frames.append(1)
            if len(frames) == 3:
                os.kill(os.getpid(), signal.SIGKILL)
            return out
        frame_jobs.render_job = render_then_die
        cli.main({[argv[0], str(tmp_path / "killed"), *argv[1:]]!r})
    """)
    assert synthetic_cli.main([argv[0], str(tmp_path / "killed"), *argv[1:]]) == 0  # again
    # Never killed: the session's tiny world, rendered by the same generator in one process
    # (once for every test that reads it).
    never_killed = tiny_world(tmp_path_factory, argv[0])
    resumed, reference = _files(tmp_path / "killed"), _files(never_killed)
    assert resumed.keys() == reference.keys()
    assert resumed == reference


def _records(tfds_dir: Path) -> dict:
    from rp_jax.datasets import loading

    return {split: loading.load_columns("webcam_clipart", split, keys=KEYS, config="real",
                                        data_dir=tfds_dir)
            for split in loading.splits("webcam_clipart", config="real", data_dir=tfds_dir)}


def test_a_build_killed_while_labelling_resumes_to_the_same_records(tmp_path):
    from rp_jax.datasets import __main__ as datasets_cli

    download = _webcam_download(tmp_path / "dl", {"a": DAYS, "b": DAYS, "c": DAYS})
    argv = ["build", "webcam_clipart", "--config", "real", "--manual-dir", str(download),
            "--workers", "1", "--data-dir"]
    _killed(f"""
        import os, signal
        from rp_jax.datasets import __main__ as cli
        from rp_jax.groundtruth import viewpoint
        label_one, calls = viewpoint._label_one, []
        def label_then_die(*args, **kwargs):
            out = label_one(*args, **kwargs)  # labelled and cached
            calls.append(1)
            if len(calls) == 2:
                os.kill(os.getpid(), signal.SIGKILL)
            return out
        viewpoint._label_one = label_then_die
        cli.main({argv + [str(tmp_path / "killed")]!r})
    """)
    version = next((tmp_path / "killed" / "webcam_clipart" / "real").glob("incomplete.*"))
    assert datasets_cli.main(argv + [str(tmp_path / "killed")]) == 0  # the same command
    assert not version.exists(), "the killed build's partial folder is still there"
    assert datasets_cli.main(argv + [str(tmp_path / "never_killed")]) == 0
    resumed, reference = _records(tmp_path / "killed"), _records(tmp_path / "never_killed")
    assert resumed.keys() == reference.keys()
    for split in reference:
        for key in KEYS:
            np.testing.assert_array_equal(resumed[split][key], reference[split][key])


@pytest.mark.slow
def test_training_killed_while_writing_a_checkpoint_resumes_to_the_same_parameters(tmp_path):
    import chex

    from rp_jax import train
    from tests.test_train import small_config, task

    config, src = small_config(num_epochs=2), task(64, 0)
    reference = train.train_and_evaluate(config, tmp_path / "reference", src, progress=False)
    _killed(f"""
        import os, signal
        from rp_jax import checkpoints, train
        from tests.test_train import small_config, task
        writer, saves = checkpoints.writer, []
        def dies_mid_write(*args, **kwargs):
            manager = writer(*args, **kwargs)
            save = manager.save
            def save_then_die(step, *a, **kw):
                out = save(step, *a, **kw)  # the write has started, not been finalised
                saves.append(step)
                if len(saves) == 2:
                    os.kill(os.getpid(), signal.SIGKILL)
                return out
            manager.save = save_then_die
            return manager
        train.checkpoints.writer = dies_mid_write
        train.train_and_evaluate(small_config(num_epochs=2), {str(tmp_path / "run")!r},
                                 task(64, 0), progress=False)
    """)
    resumed = train.train_and_evaluate(config, tmp_path / "run", src, progress=False)
    assert int(resumed.step) == int(reference.step)
    chex.assert_trees_all_close(train.params_to_numpy(resumed.params),
                                train.params_to_numpy(reference.params), atol=1e-6)
    epochs = [line for line in (tmp_path / "run" / "metrics.jsonl").read_text().splitlines()
              if line.strip()]
    assert len(epochs) == 2  # epoch 2's line was never written: it was trained again
