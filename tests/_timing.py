"""Where the suite's time goes: wall and CPU seconds per test phase and per fixture set-up.

A pytest plugin, off unless asked for::

    RP_JAX_TEST_TIMES=/tmp/times pytest -p tests._timing -n 2 --dist loadfile
    python -m tests._timing /tmp/times     # the top twenty tests, files and fixtures

Each process (every xdist worker) appends JSON lines to ``<dir>/<worker>.jsonl``: one per
test phase (set-up, call, tear-down) and one per fixture set-up, each with its wall seconds,
the time it ended (``end``, seconds since the epoch) and its CPU seconds (this process's,
all threads, plus those of the child processes it waited for in the meantime). On a machine
others share, wall time follows the load; CPU time much less so, which is why both are kept.
Each row also has the seconds this process spent making JAX programs in the meantime
(``jax.monitoring``'s duration events: tracing to a jaxpr, lowering to MLIR, XLA's backend
compile; a program read from the compilation cache costs its tracing and lowering only);
those of the commands a test starts are not seen. At the end of the session each process
adds one row of those seconds per program name (the function jitted: ``init``,
``<lambda>``, ``broadcast_in_dim`` for an operation run outside ``jax.jit``), with how many
times each was made.
"""

from __future__ import annotations

import collections
import json
import os
import resource
import sys
import time
from pathlib import Path

import pytest

TIMES_ENV = "RP_JAX_TEST_TIMES"


def _cpu() -> float:
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


class _Recorder:
    def __init__(self, folder: Path):
        folder.mkdir(parents=True, exist_ok=True)
        worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
        self._file = open(folder / f"{worker}-{os.getpid()}.jsonl", "a")  # noqa: SIM115

    def write(self, **row) -> None:
        self._file.write(json.dumps(row) + "\n")
        self._file.flush()


_recorder: _Recorder | None = None
# Seconds per jax.monitoring duration event, summed since the process started.
_EVENTS = {"/jax/core/compile/jaxpr_trace_duration": "trace",
           "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower",
           "/jax/core/compile/backend_compile_duration": "compile"}
_jax_seconds = dict.fromkeys(_EVENTS.values(), 0.0)


def _program_row() -> dict:
    """A program's seconds per stage (``"trace"``, ``"lower"``, ``"compile"``) and ``"made"``,
    how many times it was lowered."""
    return {**dict.fromkeys(_EVENTS.values(), 0.0), "made": 0}


_programs: dict = collections.defaultdict(_program_row)  # by program name


def _program_name(fun_name: str) -> str:
    """``jit(f)`` (how lowering and compiling name a program) and ``f`` (tracing) as one."""
    return fun_name[4:-1] if fun_name.startswith("jit(") and fun_name.endswith(")") else fun_name


def _on_duration(event: str, seconds: float, **kwargs) -> None:
    name = _EVENTS.get(event)
    if name is not None:
        _jax_seconds[name] += seconds
        program = _programs[_program_name(str(kwargs.get("fun_name", "?")))]
        program[name] += seconds
        program["made"] += name == "lower"


def pytest_configure(config):
    global _recorder
    folder = os.environ.get(TIMES_ENV)
    if folder:
        _recorder = _Recorder(Path(folder))
        import jax.monitoring

        jax.monitoring.register_event_duration_secs_listener(_on_duration)


def _jax_since(before: dict) -> dict:
    return {k: _jax_seconds[k] - before[k] for k in _jax_seconds}


@pytest.hookimpl(hookwrapper=True)
def pytest_fixture_setup(fixturedef, request):
    if _recorder is None:
        yield
        return
    wall, cpu, jx = time.perf_counter(), _cpu(), dict(_jax_seconds)
    yield
    _recorder.write(kind="fixture", name=fixturedef.argname, scope=fixturedef.scope,
                    file=request.node.nodeid.split("::")[0],
                    wall=time.perf_counter() - wall, cpu=_cpu() - cpu, end=time.time(),
                    **_jax_since(jx))


def _phase(item, when):
    if _recorder is None:
        yield
        return
    wall, cpu, jx = time.perf_counter(), _cpu(), dict(_jax_seconds)
    yield
    _recorder.write(kind="test", name=item.nodeid, when=when,
                    file=item.nodeid.split("::")[0],
                    wall=time.perf_counter() - wall, cpu=_cpu() - cpu, end=time.time(),
                    **_jax_since(jx))


def pytest_sessionfinish(session):
    if _recorder is not None and _programs:
        _recorder.write(kind="programs", programs=dict(_programs))


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_setup(item):
    yield from _phase(item, "setup")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item):
    yield from _phase(item, "call")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_teardown(item):
    yield from _phase(item, "teardown")


def _read(folder: Path) -> dict[str, list[dict]]:
    """{process (file stem): its rows}."""
    return {f.stem: [json.loads(line) for line in f.read_text().splitlines() if line]
            for f in sorted(folder.glob("*.jsonl"))}


def summary(folder: Path, top: int = 20) -> str:
    """The ``top`` tests, files and fixtures by wall time, with their CPU time."""
    by_process = _read(folder)
    rows = [r for process_rows in by_process.values() for r in process_rows]
    tests: dict = collections.defaultdict(lambda: [0.0, 0.0])
    files: dict = collections.defaultdict(lambda: [0.0, 0.0])
    fixtures: dict = collections.defaultdict(lambda: [0.0, 0.0, 0])
    jax_by_test: dict = collections.defaultdict(lambda: dict.fromkeys(_EVENTS.values(), 0.0))
    programs: dict = collections.defaultdict(_program_row)
    for r in rows:
        if r["kind"] == "programs":
            for name, v in r["programs"].items():
                for k in programs[name]:
                    programs[name][k] += v.get(k, 0)
        elif r["kind"] == "test":
            for table, key in ((tests, r["name"]), (files, r["file"])):
                table[key][0] += r["wall"]
                table[key][1] += r["cpu"]
            for k in _EVENTS.values():
                jax_by_test[r["name"]][k] += r.get(k, 0.0)
        else:
            f = fixtures[f"{r['file']}::{r['name']} ({r['scope']})"]
            f[0] += r["wall"]
            f[1] += r["cpu"]
            f[2] += 1
    total_wall = sum(v[0] for v in files.values())
    total_cpu = sum(v[1] for v in files.values())
    out = [f"{len(tests)} tests in {len(files)} files: {total_wall:.0f} s wall, "
           f"{total_cpu:.0f} s CPU summed over the workers"]
    for title, table in (("tests (set-up + call + tear-down)", tests), ("files", files),
                         ("fixture set-ups", fixtures)):
        out.append(f"\nTop {top} {title}: wall s, CPU s")
        for key, v in sorted(table.items(), key=lambda kv: -kv[1][0])[:top]:
            extra = f" x{v[2]}" if len(v) > 2 and v[2] > 1 else ""
            out.append(f"{v[0]:8.1f} {v[1]:8.1f}  {key}{extra}")
    spans = _process_spans(by_process)
    if spans:
        last = max(end for _, end in spans.values())
        out.append("\nTest phases of each process, seconds from the first one's start "
                   "(idle at the end: before the last process finished)")
        for process, (start, end) in spans.items():
            out.append(f"{start:8.1f} {end:8.1f}  {process} (idle at the end: "
                       f"{last - end:.1f})")
    totals = {k: sum(v[k] for v in jax_by_test.values()) for k in _EVENTS.values()}
    out.append("\nJAX programs made in the test processes (trace + lower + XLA compile, s): "
               + ", ".join(f"{k} {v:.1f}" for k, v in totals.items()))
    out.append(f"Top {top} tests by it: trace, lower, compile s")
    for key, v in sorted(jax_by_test.items(), key=lambda kv: -sum(kv[1].values()))[:top]:
        out.append(f"{v['trace']:8.1f} {v['lower']:8.1f} {v['compile']:8.1f}  {key}")
    if programs:
        out.append(f"\nTop {top} programs by it, summed over the processes: times made (lowered "
                   "and compiled, or read from the cache), trace, lower, compile s")
        spent = {k: sum(v[e] for e in _EVENTS.values()) for k, v in programs.items()}
        for key, v in sorted(programs.items(), key=lambda kv: -spent[kv[0]])[:top]:
            out.append(f"{v['made']:6d} {v['trace']:8.1f} {v['lower']:8.1f} "
                       f"{v['compile']:8.1f}  {key}")
    return "\n".join(out)


def _process_spans(by_process: dict) -> dict:
    """{process: (first test phase's start, last one's end)}, seconds from the earliest
    start of any process; the processes whose rows say when they ended (``end``)."""
    spans = {}
    for process, rows in by_process.items():
        timed = [(r["end"] - r["wall"], r["end"]) for r in rows
                 if r["kind"] == "test" and "end" in r]
        if timed:
            spans[process] = (min(s for s, _ in timed), max(e for _, e in timed))
    if not spans:
        return {}
    t0 = min(s for s, _ in spans.values())
    return {p: (s - t0, e - t0) for p, (s, e) in spans.items()}


if __name__ == "__main__":
    print(summary(Path(sys.argv[1]), int(sys.argv[2]) if len(sys.argv) > 2 else 20))
