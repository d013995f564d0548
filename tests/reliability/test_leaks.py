"""Nothing a run starts outlives it or piles up (issue 14, "Leaks").

* label workers exit when their build is SIGKILLed (they went on for minutes), and so do a
  map-summarization run's seed processes;
* a killed build's partial TFDS folder (``incomplete.*``) is removed by the next build of
  the same dataset/config/version, and only then;
* building leaves no empty ``/tmp/tmp*tfds`` folder (TFDS made one per builder).
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

_LABEL_TWO_VIEWPOINTS = textwrap.dedent("""
    import sys
    from pathlib import Path
    from rp_jax.groundtruth import viewpoint
    from tests.groundtruth import _scenes
    from tests.reliability import _slow_loader

    folder = Path(sys.argv[1])
    views = {}
    for vp in ("a", "b"):
        caps = [_scenes.make_capture(f"i{k}", 0, k, viewpoint=vp) for k in range(2)]
        for k, c in enumerate(caps):
            _scenes.IMAGES[f"{vp}/{c.image_id}"] = _scenes.textured_image(k)
        views[vp] = _scenes.to_disk(caps, folder)
    for _ in viewpoint.label_viewpoints(views, load_image=_slow_loader.load_forever,
                                        num_timestamps=2, workers=2):
        pass
""")


def _alive(pid: int) -> bool:
    """Running (a zombie waiting for init to reap it counts as gone)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state != "Z"


def _children_exit_with_their_killed_parent(script: str, folder: Path, started, what: str):
    """Runs ``script`` (given ``folder``), waits for ``started()`` to list the pids of its two
    worker processes busy in their jobs, SIGKILLs it and asserts they are gone within 10 s."""
    parent = subprocess.Popen([sys.executable, "-c", script, str(folder)], cwd=ROOT,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    children: list[int] = []
    try:
        deadline = time.monotonic() + 120
        while len(children) < 2 and time.monotonic() < deadline and parent.poll() is None:
            time.sleep(0.2)
            children = started()
        assert len(children) == 2, f"the two {what} never started their jobs"
        parent.send_signal(signal.SIGKILL)
        parent.wait()
        deadline = time.monotonic() + 10
        while any(_alive(c) for c in children) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not [c for c in children if _alive(c)], f"{what} outlived their parent"
    finally:
        if parent.poll() is None:
            parent.kill()
        for c in children:  # only on failure: the processes this test started, by pid
            if _alive(c):
                os.kill(c, signal.SIGKILL)


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")
def test_label_workers_exit_when_the_build_is_killed(tmp_path):
    _children_exit_with_their_killed_parent(
        _LABEL_TWO_VIEWPOINTS, tmp_path,
        lambda: [int(p.name) for p in (tmp_path / "pids").glob("*")], "label workers")


_TWO_SEEDS = textwrap.dedent("""
    import sys
    from pathlib import Path
    from experiments.map_summarization import seed_processes

    seed_processes.evaluate_in_processes("tests.experiments._seed_driver", None,
                                         Path(sys.argv[1]), [90, 91], "abc", 2,
                                         progress=False)
""")


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads /proc")
def test_seed_processes_exit_when_their_run_is_killed(tmp_path):
    # The stand-in driver writes started<seed> (its pid) and sleeps a minute.
    _children_exit_with_their_killed_parent(
        _TWO_SEEDS, tmp_path,
        lambda: [int(p.read_text()) for p in tmp_path.glob("started*") if p.read_text()],
        "seed processes")


def test_a_builder_leaves_no_temporary_folder(tmp_path, monkeypatch):
    from rp_jax.datasets import loading

    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp))
    builder = loading.get_builder("webcam_clipart", config="synthetic_tiny",
                                  data_dir=tmp_path / "tfds")
    assert not builder.is_prepared()
    assert list(tmp.iterdir()) == []


def test_a_killed_builds_partial_folder_is_removed_by_the_next_build(tmp_path, monkeypatch):
    from rp_jax.datasets import loading, provenance

    builder = loading.get_builder("webcam_clipart", config="synthetic_tiny",
                                  data_dir=tmp_path / "tfds")
    version = Path(builder.data_dir)
    stale = version.parent / f"incomplete.ABC123_{version.name}"
    other = version.parent / "incomplete.XYZ789_0.0.1"  # another version's: not ours to touch
    for folder in (stale, other):
        folder.mkdir(parents=True)
        (folder / "webcam_clipart-train.array_record-00000-of-00001").write_bytes(b"x" * 64)
    seen = {}
    # The build itself is not what is tested: it is replaced by a look at the folder.
    monkeypatch.setattr(type(builder), "download_and_prepare",
                        lambda self, **kw: seen.setdefault("stale", stale.exists()))
    provenance.prepare(builder)
    assert seen == {"stale": False}
    assert other.exists()


def test_a_build_waits_for_another_build_of_the_same_version(tmp_path):
    from rp_jax.datasets import loading, provenance

    builder = loading.get_builder("webcam_clipart", config="synthetic_tiny",
                                  data_dir=tmp_path / "tfds")
    version = Path(builder.data_dir)
    lock_holder = textwrap.dedent(f"""
        import time
        from rp_jax.datasets import loading, provenance
        b = loading.get_builder("webcam_clipart", config="synthetic_tiny",
                                data_dir={str(tmp_path / "tfds")!r})
        with provenance.build_lock(b):
            print("locked", flush=True)
            time.sleep(600)
    """)
    holder = subprocess.Popen([sys.executable, "-c", lock_holder], cwd=ROOT,
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        live = version.parent / f"incomplete.LIVE01_{version.name}"
        live.mkdir()
        # While another build holds the lock its partial folder is live: a build waits.
        import threading

        entered = threading.Event()

        def build():
            with provenance.build_lock(builder):
                entered.set()

        t = threading.Thread(target=build, daemon=True)
        t.start()
        assert not entered.wait(1.0)
        assert live.exists()
        holder.kill()  # killed mid-build: the kernel releases its lock
        holder.wait()
        assert entered.wait(30)
        t.join(30)
        assert not live.exists()
    finally:
        if holder.poll() is None:
            holder.kill()
            holder.wait()
