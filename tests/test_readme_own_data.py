"""The README's "Your own data" section runs as written (issue 13, "Done when").

Its fenced blocks are read from README.md itself, so an edit to the README is tested as it
stands: every ``$ python -m ...`` line of a ``console`` block runs (in-process, through the
command's ``main``, to keep the test short) in a folder holding the data the section names,
made by ``tests/_own_data.py``: an untrained predictor at ``runs/rp``, the tiny textured-plane
scene (``sparse/``, ``images/``, ``queries/``, ``queries_with_intrinsics.txt``,
``ground_truth.txt``), its hloc files under ``hloc/`` and ``photos/street.jpg`` with an EXIF
capture time. Each line the README shows as output must be printed, numbers aside (the
README's come from the same kind of tiny scene; ``...`` stands for lines left out), with
the exit status the README implies (2 for an ``error:`` line, else 0). The ``python`` blocks
run too.
"""

from __future__ import annotations

import contextlib
import importlib
import io
import re
import shlex
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tests._own_data import (
    make_predictor,
    make_scene,
    render,
    texture,
    write_hloc_features,
    write_hloc_global,
)

README = Path(__file__).resolve().parent.parent / "README.md"
SECTION = "## Your own data"


def section_blocks(text: str, heading: str = SECTION) -> list[tuple[str, str]]:
    """(language, body) of each fenced block between ``heading`` and the next ``## ``."""
    start = text.index(heading + "\n")
    end = text.find("\n## ", start + len(heading))
    body = text[start:] if end < 0 else text[start:end]
    return [(m.group(1), m.group(2))
            for m in re.finditer(r"^```(\w*)\n(.*?)^```$", body, re.DOTALL | re.MULTILINE)]


def console_steps(block: str) -> list[tuple[str, list[str]]]:
    """(command, expected output lines) per ``$`` line; ``\\`` continues a command."""
    steps: list[tuple[str, list[str]]] = []
    lines = block.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        i += 1
        if not line.startswith("$ "):
            if steps:
                steps[-1][1].append(line)
            continue
        command = line[2:]
        while command.endswith("\\"):
            command = command[:-1] + " " + lines[i].strip()
            i += 1
        steps.append((command, []))
    return steps


def _masked(line: str) -> str:
    """A line with every number replaced (values differ from scene to scene)."""
    return re.sub(r"\d+(?:\.\d+)?", "#", line.strip())


def _run(command: str) -> tuple[int, str]:
    """``python -m MODULE ARGS`` through ``MODULE.__main__.main(ARGS)``: (status, output)."""
    argv = shlex.split(command)
    assert argv[:2] == ["python", "-m"], f"not a `python -m` command: {command}"
    main = importlib.import_module(f"{argv[2]}.__main__").main
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        try:
            status = main(argv[3:])
        except SystemExit as e:  # argparse's errors
            status = e.code if isinstance(e.code, int) else 1
    return int(status or 0), out.getvalue()


@pytest.fixture(scope="module")
def own_data(tmp_path_factory) -> Path:
    """The files the README's examples name, in one folder."""
    root = tmp_path_factory.mktemp("own_data")
    scene = make_scene(root)
    make_predictor(root / "runs" / "rp")
    (root / "hloc").mkdir()
    write_hloc_features(scene, root / "hloc" / "feats-superpoint-n4096-r1024.h5")
    write_hloc_global(scene, root / "hloc" / "global-feats-netvlad.h5")
    (root / "photos").mkdir()
    R, t = scene.query_poses[scene.query_names[1]]
    exif = Image.Exif()
    exif.get_ifd(0x8769)[0x9003] = "2024:06:01 09:30:00"  # DateTimeOriginal
    Image.fromarray(render(texture(), R, t)).save(root / "photos" / "street.jpg", exif=exif,
                                                  quality=95)
    return root


def test_the_section_has_commands_and_code():
    blocks = section_blocks(README.read_text())
    commands = [c for lang, body in blocks if lang == "console" for c, _ in console_steps(body)]
    modules = {shlex.split(c)[2] for c in commands}
    assert {"rp_jax.keypoints", "rp_jax.mapsum", "rp_jax.localize"} <= modules, modules
    assert any(lang == "python" for lang, _ in blocks)
    steps = console_steps("$ python -m a x \\\n    --b c\nout 1\n...\n$ python -m d\n")
    assert steps == [("python -m a x  --b c", ["out 1", "..."]), ("python -m d", [])]


@pytest.mark.slow
def test_readme_own_data_runs_verbatim(own_data, monkeypatch):
    monkeypatch.chdir(own_data)
    blocks = section_blocks(README.read_text())
    for lang, body in blocks:
        if lang == "console":
            for command, expected in console_steps(body):
                status, output = _run(command)
                printed = [_masked(line) for line in output.splitlines()]
                shown = [line for line in expected if line.strip() and line.strip() != "..."]
                want = 2 if any(": error: " in line for line in shown) else 0
                assert status == want, (f"$ {command}\nexit {status}, README implies {want}\n"
                                        f"{output}")
                missing = [line for line in shown if _masked(line) not in printed]
                assert not missing, (f"$ {command}\nREADME shows lines it did not print:\n"
                                     + "\n".join(missing) + f"\n--- it printed:\n{output}")
        elif lang == "python":
            scope: dict = {}
            exec(compile(body, "README.md (Your own data)", "exec"), scope)  # noqa: S102
    # What the commands wrote is where the README says.
    kp = np.load(own_data / "keypoints" / "street.npz")
    assert kp["curves"].shape[1] == len(kp["schedule_labels"]) == 21
    assert (own_data / "summary" / "model").is_dir()
    assert (own_data / "localized" / "submission.txt").exists()
