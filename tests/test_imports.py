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


_HELP_CHILD = textwrap.dedent(
    """
    import sys
    from rp_jax.keypoints import __main__ as keypoints
    from rp_jax.localize import __main__ as localize
    from rp_jax.mapsum import __main__ as mapsum

    for command in (keypoints, mapsum, localize):
        command._parser().format_help()
    print(sorted(m for m in ("jax", "scipy", "pycolmap", "tensorflow") if m in sys.modules))
    """
)


def test_the_commands_answer_help_without_jax_or_scipy():
    """``python -m rp_jax.keypoints / mapsum / localize --help`` answer in well under a
    second: building their parsers imports none of the heavy libraries (importing JAX alone
    took 3 to 4 s of CPU)."""
    proc = subprocess.run([sys.executable, "-c", _HELP_CHILD], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip() == "[]", proc.stdout


_WORKER_CHILD = textwrap.dedent(
    """
    import sys
    import rp_jax.localize.matching
    import rp_jax.mapsum.statistics
    import rp_jax.sources.colmap_model
    import rp_jax.sources.robotcar
    import rp_jax.sources.synthetic.frame_jobs

    print(sorted(m for m in ("scipy.stats", "scipy.sparse", "scipy.spatial", "pycolmap",
                             "jax", "tensorflow") if m in sys.modules))
    """
)


def test_what_spawned_workers_import_takes_no_heavy_library():
    """The rendering processes (``frame_jobs``) and the labelling and seed processes of the
    map-summarization commands import these modules first thing; scipy.stats, scipy.sparse,
    scipy.spatial and pycolmap are imported where they are used (a second of CPU each
    process otherwise: a spawned process imports again what its parent had)."""
    proc = subprocess.run([sys.executable, "-c", _WORKER_CHILD], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip() == "[]", proc.stdout


def test_lazy_packages_keep_their_functions_named_like_submodules():
    """``rp_jax.mapsum`` and ``rp_jax.localize`` import their names on first use;
    ``partition`` and ``vlad`` are also submodules' names, and stay the functions."""
    import rp_jax.localize
    import rp_jax.localize.vlad
    import rp_jax.mapsum
    import rp_jax.mapsum.partition  # noqa: F401

    assert callable(rp_jax.mapsum.partition) and rp_jax.mapsum.partition.__name__ == "partition"
    assert callable(rp_jax.localize.vlad) and rp_jax.localize.vlad.__name__ == "vlad"
    assert rp_jax.mapsum.kcover_keep.__module__ == "rp_jax.mapsum.kcover"
    assert rp_jax.localize.match_2d3d.__module__ == "rp_jax.localize.matching"
    for package in (rp_jax.mapsum, rp_jax.localize):
        assert set(package.__all__) <= set(dir(package))
        assert all(getattr(package, name) is not None for name in package.__all__)


def test_localize_does_not_import_mapsum():
    """mapsum builds on localize (its oracles match 2D-3D); localize must not import mapsum
    back: the COLMAP map model both use lives below them, in rp_jax.sources.colmap_model."""
    for path in sorted((ROOT / "rp_jax" / "localize").glob("*.py")):
        imported = _imported_modules(path)
        offending = sorted(m for m in imported if m.startswith("rp_jax.mapsum"))
        assert not offending, f"{path.relative_to(ROOT)} imports {offending}"


# The layers of ARCHITECTURE.md and the README's Layout section, lowest first. A module may
# import from its own layer and the layers below, never from a higher one; command-line
# modules (``__main__``) sit on top. Within a layer, two packages must not import each other.
LAYERS = {
    "foundations": ("rp_jax", "rp_jax.schedule", "rp_jax.time_encoding", "rp_jax.model",
                    "rp_jax.losses", "rp_jax.categories", "rp_jax.rotations", "rp_jax.platform",
                    "rp_jax.files", "rp_jax.sun", "rp_jax.plots", "rp_jax.page", "rp_jax.bf16",
                    "rp_jax.worker_processes",
                    "rp_jax.progress", "rp_jax.command_line", "rp_jax.distributed"),
    "data": ("rp_jax.sources",),
    "labelling": ("rp_jax.groundtruth",),
    "learning": ("rp_jax.configs", "rp_jax.datasets", "rp_jax.checkpoints", "rp_jax.train",
                 "rp_jax.predict", "rp_jax.evaluation", "rp_jax.shipped",
                 "rp_jax.conditional"),
    "applications": ("rp_jax.mapsum", "rp_jax.localize", "rp_jax.keypoints"),
    "drivers": ("experiments",),
    "entry points": ("rp_jax.commands",),
}
_RANK = {prefix: i for i, (_, prefixes) in enumerate(LAYERS.items()) for prefix in prefixes}
_TOP = len(LAYERS) - 1


def _modules() -> dict[str, Path]:
    out = {}
    for base in ("rp_jax", "experiments"):
        for path in sorted((ROOT / base).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


def _layer(module: str) -> tuple[int, str]:
    """(rank, package) of a module: the longest listed prefix decides."""
    if module.rsplit(".", 1)[-1] == "__main__":
        return _TOP, module
    prefixes = [p for p in _RANK if module == p or module.startswith(p + ".")]
    if not prefixes:
        raise AssertionError(f"{module} is in no layer: add it to LAYERS (and the README)")
    best = max(prefixes, key=len)
    return _RANK[best], best


def _project_imports(path: Path, module: str, modules: dict[str, Path]) -> set[str]:
    found = set()
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text())):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join(up + ([base] if base else []))
            names = [f"{base}.{a.name}" for a in node.names] + [base]
        for name in names:
            while name and name not in modules:
                name = name.rpartition(".")[0]
            if name and name != module:
                found.add(name)
    return found


def test_every_module_has_a_layer():
    for module in _modules():
        assert _layer(module), module


def test_imports_point_down_the_layers_and_packages_form_no_cycle():
    modules = _modules()
    upward, edges = [], set()
    for module, path in modules.items():
        rank, package = _layer(module)
        for target in _project_imports(path, module, modules):
            t_rank, t_package = _layer(target)
            if t_rank > rank:
                upward.append(f"{module} ({list(LAYERS)[rank]}) imports {target} "
                              f"({list(LAYERS)[t_rank]})")
            elif t_rank == rank and t_package != package and rank != _TOP:
                edges.add((package, t_package))
    assert not upward, "\n".join(sorted(upward))
    cycles = sorted(f"{a} <-> {b}" for a, b in edges if (b, a) in edges and a < b)
    assert not cycles, cycles


def test_no_module_imports_itself_through_others():
    """No circle of imports between modules, the function-level ones included (a module
    importing its own package's ``__init__`` is no circle: the package is set up first).
    A circle works while every import in it is deferred, and breaks the day one of them
    moves to the top of its file; it also means the two ideas were not apart."""
    modules = _modules()
    graph = {m: sorted(t for t in _project_imports(p, m, modules) if not m.startswith(t + "."))
             for m, p in modules.items()}
    state, cycles = {}, []

    def visit(module, stack):
        state[module] = "open"
        stack.append(module)
        for target in graph[module]:
            if state.get(target) == "open":
                cycles.append(" -> ".join(stack[stack.index(target):] + [target]))
            elif target not in state:
                visit(target, stack)
        stack.pop()
        state[module] = "done"

    for module in sorted(graph):
        if module not in state:
            visit(module, [])
    assert not cycles, "\n".join(cycles)
