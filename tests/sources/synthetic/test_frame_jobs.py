"""Rendering frame jobs in processes (rp_jax/sources/synthetic/frame_jobs.py)."""

import dataclasses
import threading

from rp_jax.sources.synthetic import frame_jobs, presets
from tests.sources.synthetic._dying_scene import DyingScene


def test_a_killed_rendering_process_is_named_not_waited_for(tmp_path, monkeypatch):
    jobs = [dataclasses.replace(j, scene=DyingScene(**dataclasses.asdict(j.scene)))
            for j in presets.plan("cmu_seasons", tmp_path / "world", size="tiny").jobs[:4]]
    monkeypatch.setattr(frame_jobs, "MIN_FRAMES_PER_WORKER", 1)  # 4 frames on 2 processes
    raised = []

    def render():
        try:
            frame_jobs.run_jobs(jobs, workers=2, progress=False)
        except Exception as e:  # noqa: BLE001 - checked below
            raised.append(e)

    thread = threading.Thread(target=render, daemon=True)
    thread.start()
    thread.join(timeout=90)
    assert not thread.is_alive(), "the render still waits for frames its dead workers took"
    (error,) = raised
    assert isinstance(error, frame_jobs.RenderProcessError), error
    assert "ended before it finished" in str(error) and "4 of 4 frames not rendered" in str(error)
    assert "fewer workers than 2" in str(error) and 'if __name__ == "__main__":' in str(error)
    assert not any(path.exists() for job in jobs for path in job.outputs)
