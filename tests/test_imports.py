"""Importing any module of the package starts no JAX backend (ARCHITECTURE.md, Layers).

Entry points call ``rp_jax.platform.configure_cpu()`` after their imports, and it only
works while JAX has not initialised a backend (XLA reads the device count once). A module
that builds a ``jnp`` array at import time starts the backend and silently breaks that set-up.

The check runs in a fresh interpreter (the test session's own JAX is long initialised): it
imports every module under ``rp_jax`` and ``experiments``, asks JAX after each import whether
a backend exists (to name the culprit), then calls ``configure_cpu`` and checks that the
device count it asked for is the one JAX gives.
"""

import ast
import os
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

_CHILD = textwrap.dedent(
    """
    import importlib
    import pkgutil

    from jax._src import xla_bridge

    import experiments
    import rp_jax

    def started():
        # Private, but the most direct check; the public one below backs it up.
        return getattr(xla_bridge, "backends_are_initialized", lambda: False)()

    OPTIONAL = {"torch"}
    names = []
    for package in (rp_jax, experiments):
        names.append(package.__name__)
        for info in pkgutil.walk_packages(package.__path__, package.__name__ + "."):
            if info.name.rsplit(".", 1)[-1] != "__main__":
                names.append(info.name)
    for name in names:
        try:
            importlib.import_module(name)
        except ModuleNotFoundError as e:
            if e.name not in OPTIONAL:
                raise
            continue  # a module of an optional extra (bench: torch) that is not installed
        if started():
            raise SystemExit(f"importing {name} started a JAX backend")

    from rp_jax import platform
    import jax

    platform.configure_cpu(num_devices=3, ynn=False)
    got = len(jax.devices("cpu"))
    if got != 3:
        raise SystemExit(f"configure_cpu(num_devices=3) after the imports gave {got} CPU devices")
    print(f"imported {len(names)} modules")
    """
)


def test_importing_every_module_starts_no_jax_backend():
    env = {k: v for k, v in os.environ.items()
           if k not in ("XLA_FLAGS", "RP_JAX_NO_CPU_SETUP", "JAX_NUM_CPU_DEVICES")}
    proc = subprocess.run([sys.executable, "-c", _CHILD], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:] + proc.stdout[-1000:]
    assert "imported" in proc.stdout



def _imported_modules(path: Path) -> set[str]:
    """Every module a file imports, at the top or inside functions."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
            names.update(f"{node.module}.{a.name}" for a in node.names)
    return names


def test_predict_does_not_import_train():
    """Loading a predictor needs the model and its checkpoints, not the training loop."""
    for name in ("predict", "checkpoints", "model", "platform"):
        imported = _imported_modules(ROOT / "rp_jax" / f"{name}.py")
        assert "rp_jax.train" not in imported, f"rp_jax/{name}.py imports rp_jax.train"


def test_localize_does_not_import_mapsum():
    """mapsum builds on localize (its oracles match 2D-3D); localize must not import mapsum
    back: the COLMAP map model both use lives below them, in rp_jax.sources.colmap_model."""
    for path in sorted((ROOT / "rp_jax" / "localize").glob("*.py")):
        imported = _imported_modules(path)
        offending = sorted(m for m in imported if m.startswith("rp_jax.mapsum"))
        assert not offending, f"{path.relative_to(ROOT)} imports {offending}"
