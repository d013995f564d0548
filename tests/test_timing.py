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


def test_the_listener_adds_only_the_compile_events(monkeypatch):
    monkeypatch.setattr(_timing, "_programs", type(_timing._programs)(
        _timing._programs.default_factory))
    before = dict(_timing._jax_seconds)
    _timing._on_duration("/jax/core/compile/backend_compile_duration", 1.5, fun_name="jit(f)")
    _timing._on_duration("/jax/some/other_duration", 7.0, fun_name="jit(f)")
    assert _timing._jax_since(before) == {"trace": 0.0, "lower": 0.0, "compile": 1.5}
    # Per program: tracing names the function, lowering and compiling jit(function).
    _timing._on_duration("/jax/core/compile/jaxpr_trace_duration", 0.25, fun_name="f")
    _timing._on_duration("/jax/core/compile/jaxpr_to_mlir_module_duration", 0.5,
                         fun_name="jit(f)")
    _timing._on_duration("/jax/core/compile/jaxpr_to_mlir_module_duration", 0.5,
                         fun_name="jit(<lambda>)")
    assert dict(_timing._programs) == {
        "f": {"trace": 0.25, "lower": 0.5, "compile": 1.5, "made": 1},
        "<lambda>": {"trace": 0.0, "lower": 0.5, "compile": 0.0, "made": 1}}


def test_summary_ranks_the_programs_of_every_process(tmp_path):
    folder = tmp_path / "times"
    folder.mkdir()
    made = {"gw0-1": {"init": {"trace": 0.5, "lower": 1.0, "compile": 2.0, "made": 2},
                      "add": {"trace": 0.0, "lower": 0.25, "compile": 0.25, "made": 3}},
            "gw1-2": {"init": {"trace": 0.25, "lower": 0.5, "compile": 1.0, "made": 1}}}
    for process, programs in made.items():
        (folder / f"{process}.jsonl").write_text(
            json.dumps({"kind": "test", "name": "t::x", "when": "call", "file": "t",
                        "wall": 1.0, "cpu": 1.0}) + "\n"
            + json.dumps({"kind": "programs", "programs": programs}) + "\n")
    lines = _timing.summary(folder, top=2).splitlines()
    ranked = lines[lines.index("Top 2 programs by it, summed over the processes: times made "
                               "(lowered and compiled, or read from the cache), trace, lower, "
                               "compile s") + 1:]
    assert ranked == ["     3      0.8      1.5      3.0  init",
                      "     3      0.0      0.2      0.2  add"]


def test_each_process_span_and_its_idle_end(tmp_path):
    folder = tmp_path / "times"
    folder.mkdir()
    rows = {"gw0-1": [(100.0, 2.0), (110.0, 5.0)], "gw1-2": [(101.0, 1.0), (130.0, 4.0)]}
    for process, phases in rows.items():
        with open(folder / f"{process}.jsonl", "w") as f:
            for end, wall in phases:
                f.write(json.dumps({"kind": "test", "name": "t::x", "when": "call",
                                    "file": "t", "wall": wall, "cpu": wall, "end": end}) + "\n")
            # A fixture row is not a test phase: its end does not count.
            f.write(json.dumps({"kind": "fixture", "name": "f", "scope": "module", "file": "t",
                                "wall": 1.0, "cpu": 1.0, "end": 500.0}) + "\n")
    # gw0 starts first (at 98), ends at 110; gw1 ends at 130, 20 s after gw0.
    assert _timing._process_spans(_timing._read(folder)) == {"gw0-1": (0.0, 12.0),
                                                              "gw1-2": (2.0, 32.0)}
    text = _timing.summary(folder)
    assert "     0.0     12.0  gw0-1 (idle at the end: 20.0)" in text
    assert "     2.0     32.0  gw1-2 (idle at the end: 0.0)" in text
    # Rows of a run before the end times: no such section.
    (folder / "gw0-1.jsonl").unlink()
    (folder / "gw1-2.jsonl").write_text(json.dumps(
        {"kind": "test", "name": "t::x", "when": "call", "file": "t", "wall": 1.0,
         "cpu": 1.0}) + "\n")
    assert "idle at the end" not in _timing.summary(folder)
