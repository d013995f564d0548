"""A non-editable install works from any directory (issue: an install that works anywhere).

The wheel is built offline from the checkout (``pip wheel --no-build-isolation``; the test
extra brings setuptools), installed without dependencies into a fresh folder that comes
first on ``PYTHONPATH`` (the dependencies are this environment's), and used from an empty
working directory: the data specs travel inside the package, the commands answer
``--help``, and the default data directory is the user's cache, not ``./data``.
"""

import os
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("wheel")
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
         "-w", str(tmp / "dist"), str(ROOT)],
        capture_output=True, text=True, timeout=600,
    )
    assert build.returncode == 0, build.stderr[-3000:]
    (wheel,) = (tmp / "dist").glob("rp_jax-*.whl")
    target = tmp / "site"
    install = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(target),
         str(wheel)],
        capture_output=True, text=True, timeout=600,
    )
    assert install.returncode == 0, install.stderr[-3000:]
    elsewhere = tmp / "elsewhere"
    elsewhere.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("RP_JAX_DATA_DIR", "PYTHONPATH")}
    env.update(PYTHONPATH=str(target), XDG_CACHE_HOME=str(tmp / "cache"))
    return wheel, target, elsewhere, env


def _run(installed, *args):
    _, _, cwd, env = installed
    return subprocess.run([sys.executable, *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=300)


def test_the_wheel_carries_the_data_specs_and_the_license(installed):
    names = zipfile.ZipFile(installed[0]).namelist()
    for spec in sorted((ROOT / "data_specs").glob("*.json")):
        assert f"rp_jax/data_specs/{spec.name}" in names
    assert any(n.endswith("licenses/LICENSE") for n in names)


def test_the_installed_package_works_from_another_directory(installed):
    _, target, _, env = installed
    code = textwrap.dedent(
        """
        import rp_jax
        from rp_jax import schedule
        from rp_jax.datasets import loading
        print(rp_jax.__file__)
        for name in ("webcam_clipart", "cmu_seasons", "robotcar"):
            print(name, schedule.preset(name).num_timestamps)
        print(loading.default_data_dir())
        """
    )
    proc = _run(installed, "-c", code)
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = proc.stdout.split("\n")
    assert lines[0].startswith(str(target)), lines[0]  # the wheel's copy, not the checkout
    assert lines[1:4] == ["webcam_clipart 21", "cmu_seasons 12", "robotcar 9"], lines
    assert lines[4] == str(Path(env["XDG_CACHE_HOME"]) / "rp_jax" / "tensorflow_datasets")


@pytest.mark.parametrize(
    "command",
    [["rp_jax.keypoints"], ["rp_jax.mapsum", "summarize"], ["rp_jax.localize"],
     ["rp_jax.datasets", "build"], ["experiments.webcam_clipart"]],
)
def test_each_command_answers_help_from_another_directory(installed, command):
    proc = _run(installed, "-m", *command, "--help")
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "usage:" in proc.stdout
