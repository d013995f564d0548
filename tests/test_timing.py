"""The suite's timing plugin (tests/_timing.py): its summary of where the time goes."""

import json

from tests import _timing


def _write(folder, rows):
    folder.mkdir(exist_ok=True)
    with open(folder / "gw0-1.jsonl", "w") as f:
        for r in rows:
            f.write(json.dumps(r) + "\n")


def test_summary_sums_each_tests_phases_and_its_jax_programs(tmp_path):
    a, b = "tests/test_a.py::test_one", "tests/test_b.py::test_two"
    _write(tmp_path / "times", [
        {"kind": "test", "name": a, "when": "setup", "file": "tests/test_a.py", "wall": 1.0,
         "cpu": 0.5, "trace": 0.25, "lower": 0.5, "compile": 2.0},
        {"kind": "test", "name": a, "when": "call", "file": "tests/test_a.py", "wall": 3.0,
         "cpu": 2.5, "trace": 0.25, "lower": 0.0, "compile": 1.0},
        # A row of a run before the JAX columns: counted as none.
        {"kind": "test", "name": b, "when": "call", "file": "tests/test_b.py", "wall": 2.0,
         "cpu": 2.0},
        {"kind": "fixture", "name": "world", "scope": "module", "file": "tests/test_a.py",
         "wall": 0.75, "cpu": 0.5, "trace": 0.0, "lower": 0.0, "compile": 0.0},
    ])
    text = _timing.summary(tmp_path / "times", top=5)
    lines = text.splitlines()
    assert lines[0] == "2 tests in 2 files: 6 s wall, 5 s CPU summed over the workers"
    assert "     4.0      3.0  tests/test_a.py::test_one" in lines
    assert "    0.8      0.5  tests/test_a.py::world (module)" in text
    assert ("JAX programs made in the test processes (trace + lower + XLA compile, s): "
            "trace 0.5, lower 0.5, compile 3.0") in lines
    ranked = lines[lines.index("Top 5 tests by it: trace, lower, compile s") + 1:]
    assert ranked == ["     0.5      0.5      3.0  tests/test_a.py::test_one",
                      "     0.0      0.0      0.0  tests/test_b.py::test_two"]


def test_the_listener_adds_only_the_compile_events():
    before = dict(_timing._jax_seconds)
    _timing._on_duration("/jax/core/compile/backend_compile_duration", 1.5)
    _timing._on_duration("/jax/some/other_duration", 7.0)
    assert _timing._jax_since(before) == {"trace": 0.0, "lower": 0.0, "compile": 1.5}
