"""docs/own_data.md and docs/bad_input.md run as written (issue 27, finding 9).

Every ``$`` line of their ``console`` blocks runs in a folder holding the data the guide
names (tests/test_readme_own_data.py's ``own_data``: an untrained predictor at ``runs/rp``,
the tiny textured-plane scene, ``photos/street.jpg``): ``python -m`` commands in-process
through their ``main`` (quicker), other lines (the guide's first one copies a scikit-image
photo) in a shell. Each line a block shows as output must be printed, numbers aside, with the
exit status the block implies (2 for an ``error:`` line). The guide must open with a command
that uses a shipped model on a photo the install provides, and name only shipped models
that exist.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from rp_jax import shipped
from tests.test_readme_own_data import _masked, _run, console_steps, own_data  # noqa: F401

DOCS = Path(__file__).resolve().parent.parent / "docs"
GUIDE = DOCS / "own_data.md"
BAD_INPUT = DOCS / "bad_input.md"


def _blocks(path: Path) -> list[tuple[str, str]]:
    return [(m.group(1), m.group(2)) for m in
            re.finditer(r"^```(\w*)\n(.*?)^```$", path.read_text(), re.DOTALL | re.MULTILINE)]


def _steps(path: Path) -> list[tuple[str, list[str]]]:
    return [s for lang, body in _blocks(path) if lang == "console" for s in console_steps(body)]


def test_the_guide_opens_with_a_shipped_model_on_a_photo_the_install_has():
    steps = _steps(GUIDE)
    first_command = next(c for c, _ in steps if c.startswith("python -m rp_jax."))
    assert "rp_jax.keypoints" in first_command
    assert any(f"--predictor {name}" in first_command for name in shipped.names())
    assert "skimage.data" in steps[0][0]  # the photo comes with a dependency


def test_the_docs_name_only_shipped_models_that_exist():
    for path in (GUIDE, BAD_INPUT):
        named = set(re.findall(r"\b([a-z_]+-synthetic)\b", path.read_text()))
        assert named <= set(shipped.names()), (path.name, named)
        assert named or path != GUIDE


def _shell(command: str, cwd: Path) -> tuple[int, str]:
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    proc = subprocess.run(["bash", "-c", command], cwd=cwd, env=env, text=True,
                          capture_output=True, timeout=300, check=False)
    return proc.returncode, proc.stdout + proc.stderr


def _step(command: str, folder: Path) -> tuple[int, str]:
    """One ``$`` line, run in ``folder`` (the current directory): (exit status, output)."""
    argv = shlex.split(command)
    if argv[:3] == ["python", "-m", argv[2]] and argv[2].startswith("rp_jax."):
        return _run(command)
    return _shell(command, folder)


@pytest.fixture(scope="module")
def guide_run(own_data):  # noqa: F811
    """own_data.md's ``$`` lines run once, in order, in the folder of its examples:
    (command, lines shown, status, output) each. bad_input.md's examples run in that folder
    after them (it says so), whichever of the two tests runs first."""
    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(own_data)
        return [(command, shown, *_step(command, own_data))
                for command, shown in _steps(GUIDE)]


@pytest.mark.slow
@pytest.mark.parametrize("doc", [GUIDE, BAD_INPUT], ids=lambda p: p.name)
def test_the_docs_run_as_written(doc, own_data, guide_run, monkeypatch):  # noqa: F811
    monkeypatch.chdir(own_data)
    runs = guide_run if doc == GUIDE else (
        (command, expected, *_step(command, own_data)) for command, expected in _steps(doc))
    for command, expected, status, output in runs:
        printed = [_masked(line) for line in output.splitlines()]
        shown = [line for line in expected if line.strip() and line.strip() != "..."]
        want = 2 if any(": error: " in line for line in shown) else 0
        assert status == want, f"{doc.name}\n$ {command}\nexit {status}, want {want}\n{output}"
        missing = [line for line in shown if _masked(line) not in printed]
        assert not missing, (f"{doc.name}\n$ {command}\nshown but not printed:\n"
                             + "\n".join(missing) + f"\n--- it printed:\n{output}")
    if doc == GUIDE:
        assert (own_data / "keypoints" / "rocket_repeatability.png").is_file()
        for lang, body in _blocks(doc):
            if lang == "python":
                exec(compile(body, str(doc), "exec"), {})  # noqa: S102
