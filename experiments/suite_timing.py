"""``python -m experiments.suite_timing``: time ``make test`` of the code now against an
earlier commit on this machine, the way ``docs/testing.md`` compares the suite's times.

Each run is a fresh ``git clone`` of this checkout, checked out at its commit, running the
command (``make test``: creating ``.venv`` from the package cache, then the whole suite,
cold: no compilation cache, no bytecode). The runs follow one another in one script, nothing
else should run meanwhile, and pairs alternate their order (now, before, then before, now,
...): a host that slows or speeds up steadily over the hour then favours neither code
summed over two pairs. A probe beside them times a fixed pure-Python loop every
``--probe-interval`` seconds; its CPU seconds rise when the host is busier, so a run's
median probe says whether the host moved between two runs of a pair (a shared host moved
5 to 13 % between two runs in the record of ``experiments/results/suite_times.md``).

    python -m experiments.suite_timing --before 30ff2ce --pairs 2 --out runs/suite_timing.json
    python -m experiments.suite_timing ... --record experiments/results/suite_times.json

A killed measurement started again with the same arguments keeps the runs it finished and
runs the rest. ``--record`` adds the measurement to the committed record
(``experiments/results/suite_times.json``, ``measurements``, newest first), whose newest
measurement ``docs_block`` renders (through ``python -m experiments.docs_tables``) into
``docs/testing.md``.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Mapping, Sequence
from pathlib import Path

from experiments.benchmark.stats import cpu_peak
from rp_jax import files

CHECKOUT = Path(__file__).resolve().parents[1]
NOW, WARM, BEFORE = "now, cold", "now, warm", "before"
# pytest's last line: "1 failed, 745 passed, 9 skipped in 877.30s (0:14:37)", with -q or
# between "=" rules without it.
_SUMMARY = re.compile(r"^=*\s*((?:\d+ [a-z]+(?:, )?)+) in ([\d.]+)s\b", re.MULTILINE)


def run_order(pairs: int) -> list[tuple[int, str]]:
    """(pair, suite) in the order they run: pair 0 the code now first, pair 1 the code
    before first, and so on, so that each two pairs run now, before, before, now."""
    if pairs < 1:
        raise ValueError(f"--pairs must be at least 1, not {pairs}")
    return [(p, s) for p in range(pairs) for s in ((NOW, BEFORE) if p % 2 == 0 else (BEFORE, NOW))]


def pytest_summary(log: str) -> tuple[str, float]:
    """(``"1122 passed, 9 skipped"``, pytest's wall seconds) from the last summary line of a
    pytest output; ValueError where it has none (the suite did not finish)."""
    found = _SUMMARY.findall(log)
    if not found:
        raise ValueError("no pytest summary line ('N passed ... in S s') in the output")
    tests, seconds = found[-1]
    return tests.strip().rstrip(","), float(seconds)


def machine_text(cpu: Mapping, coretype: str | None) -> str:
    """``"a 2-core AMD EPYC (AVX2, no AVX-512), OPENBLAS_CORETYPE not set"``, as the record
    names its machines."""
    isa = {"AVX-512": "AVX-512", "AVX2+FMA": "AVX2, no AVX-512"}.get(cpu["isa"], cpu["isa"])
    if cpu.get("amx_bf16"):
        isa += ", AMX-BF16"
    blas = f"OPENBLAS_CORETYPE={coretype}" if coretype else "OPENBLAS_CORETYPE not set"
    return f"a {cpu['cores']}-core {cpu['model']} ({isa}), {blas}"


def shares(runs: Sequence[Mapping]) -> dict:
    """The code now against the code before: per pair and summed over each two pairs in
    opposite orders (now, before, before, now), for pytest's wall, ``make test``'s wall and
    user CPU (and ``warm_pytest_s``, a warm run's pytest wall, where the pair has one);
    ``median_pytest`` over the pairs. Pairs are numbered from 0 in ``pairs`` and
    from 1 in ``balanced``'s names (``"1,2"``); pairs without both runs are left out."""
    by_pair: dict[int, dict[str, Mapping]] = {}
    for r in runs:
        by_pair.setdefault(r["pair"], {})[r["suite"]] = r
    keys = ("pytest_s", "make_test_s", "user_s")

    def ratio(now: Sequence[Mapping], before: Sequence[Mapping]) -> dict:
        sums = {k: (sum(r[k] for r in now), sum(r[k] for r in before)) for k in keys}
        return {k: a / b if b else None for k, (a, b) in sums.items()}

    done = sorted(p for p, two in by_pair.items() if {NOW, BEFORE} <= set(two))
    pairs = {p: ratio([by_pair[p][NOW]], [by_pair[p][BEFORE]]) for p in done}
    for p in done:  # the same clone again, right after its cold run (--warm)
        if WARM in by_pair[p]:
            warm, before = by_pair[p][WARM], by_pair[p][BEFORE]
            pairs[p]["warm_pytest_s"] = warm["pytest_s"] / before["pytest_s"]
    balanced = {f"{p + 1},{p + 2}": ratio([by_pair[p][NOW], by_pair[p + 1][NOW]],
                                      [by_pair[p][BEFORE], by_pair[p + 1][BEFORE]])
                for p in done if p % 2 == 0 and p + 1 in pairs}
    return {"pairs": pairs, "balanced": balanced,
            "median_pytest": statistics.median(s["pytest_s"] for s in pairs.values())
            if pairs else None}


class Probe:
    """A thread timing a fixed pure-Python loop every ``interval`` seconds, each sample
    filed under the run going on (``label``); ``median(label)`` in CPU seconds."""

    def __init__(self, interval: float, loops: int = 1_500_000):
        self.interval, self.loops = interval, loops
        self.label: str | None = None
        self.samples: dict[str, list[float]] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _work(self) -> float:
        start, s = time.thread_time(), 0
        for i in range(self.loops):
            s += i * i % 7
        return time.thread_time() - start

    def _run(self) -> None:
        while not self._stop.is_set():
            label, seconds = self.label, self._work()
            if label is not None and label == self.label:
                self.samples.setdefault(label, []).append(seconds)
            self._stop.wait(self.interval)

    def median(self, label: str) -> float | None:
        got = self.samples.get(label)
        return round(statistics.median(got), 4) if got else None

    def __enter__(self) -> Probe:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()


def clean_env(env: Mapping[str, str], prefix: str = sys.prefix) -> dict[str, str]:
    """``env`` without this interpreter's virtual environment (``VIRTUAL_ENV`` and its
    ``bin`` on ``PATH``): each clone makes and uses its own."""
    out = {k: v for k, v in env.items() if k != "VIRTUAL_ENV"}
    if "PATH" in out and prefix != getattr(sys, "base_prefix", prefix):
        out["PATH"] = os.pathsep.join(d for d in out["PATH"].split(os.pathsep)
                                      if Path(d) != Path(prefix) / "bin")
    return out


def _git(*args: str, cwd: Path) -> str:
    return subprocess.run(["git", *args], cwd=cwd, check=True, capture_output=True,
                          text=True).stdout.strip()


def time_runs(repo: Path, commit: str, clone: Path, command: str, logs: Sequence[Path],
              env: Mapping[str, str], started=lambda k: None) -> list[dict]:
    """Clone ``repo`` into ``clone`` (removed first and after), check out ``commit`` and run
    ``command`` there once per log, each run's output in its log (``started(k)`` is called
    before run k): each run's wall and CPU seconds (this process's waited-for children,
    ``make`` and everything below it) and pytest's summary."""
    shutil.rmtree(clone, ignore_errors=True)
    subprocess.run(["git", "clone", "--quiet", str(repo), str(clone)], check=True)
    runs = []
    try:
        _git("checkout", "--quiet", commit, cwd=clone)
        for k, log in enumerate(logs):
            started(k)
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            start = time.monotonic()
            with files.replacing(log) as tmp, open(tmp, "w") as out:
                code = subprocess.run(command, shell=True, cwd=clone, env=dict(env),
                                      stdout=out, stderr=subprocess.STDOUT).returncode
            wall = time.monotonic() - start
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            try:
                tests, pytest_s = pytest_summary(log.read_text(errors="replace"))
            except ValueError as e:
                raise RuntimeError(f"{command!r} at {commit[:7]} ended ({code}) without "
                                   f"finishing the suite: {e}; its output is {log}") from None
            runs.append({"code": commit[:7], "tests": tests, "pytest_s": round(pytest_s, 1),
                         "make_test_s": round(wall, 1),
                         "user_s": round(after.ru_utime - before.ru_utime, 1),
                         "sys_s": round(after.ru_stime - before.ru_stime, 1),
                         "exit_status": code})
    finally:
        shutil.rmtree(clone, ignore_errors=True)
    return runs


def _settings(args, now: str, before: str, coretype: str | None) -> dict:
    return {"repo": str(args.repo.resolve()), "command": args.command, "now": now,
            "before": before, "pairs": args.pairs,
            "coretype": coretype, "probe_interval_s": args.probe_interval,
            **({"warm": True} if args.warm else {})}


# ------------------------------------------- the record as docs/testing.md shows it (docs_tables)

def _before_run(runs: Sequence[Mapping]) -> Mapping:
    """The suite before wherever it stands (a pair run in the other order lists the suite now
    first)."""
    return next((r for r in runs if r["suite"] == "before"), runs[0])


def measurement_lines(m: Mapping) -> list[str]:
    """The lines of one ``python -m experiments.suite_timing`` measurement: its runs in the
    order they ran, each pair's share and the share summed over two pairs in opposite
    orders."""
    rows = ["| pair | suite | tests | pytest wall | `make test` wall | user CPU | probe |",
            "|---|---|---|---|---|---|---|"]
    rows += [f"| {r['pair'] + 1} | {r['suite']} | {r['tests']} | {r['pytest_s']:.0f} s | "
             f"{r['make_test_s']:.0f} s | {r['user_s']:.0f} s | "
             + (f"{r['probe_s']:.3f} s |" if r.get("probe_s") is not None else "- |")
             for r in m["runs"]]
    shares = m["shares"]
    pairs = sorted((int(p) + 1, s) for p, s in shares["pairs"].items())  # numbered from 1
    text = ("The suite now against the suite before, pytest wall: "
            + ", ".join(f"pair {p} {100 * s['pytest_s']:.1f} %" for p, s in pairs))
    warm = [f"pair {p} {100 * s['warm_pytest_s']:.1f} %" for p, s in pairs
            if "warm_pytest_s" in s]
    if warm:  # the same clone again, right after its cold run
        text += "; warm, " + ", ".join(warm)
    for name, s in shares["balanced"].items():
        text += (f"; pairs {name.replace(',', ' and ')} summed (one in each order) "
                 f"{100 * s['pytest_s']:.1f} % of the pytest wall, "
                 f"{100 * s['make_test_s']:.1f} % of `make test`'s, "
                 f"{100 * s['user_s']:.1f} % of the user CPU")
    settings = m["settings"]
    return [*rows, "", text + ".", "",
            f"Measured on {m['machine']}, with `python -m experiments.suite_timing --before "
            f"<the suite before> --pairs {settings['pairs']}`: fresh clones running "
            f"`{settings['command']}` one after the other, cold, nothing else running; the "
            f"probe is the median CPU time of a fixed pure-Python loop timed every "
            f"{settings['probe_interval_s']:g} s during the run: it rises when the host is "
            "busier."]


def docs_block(data: Mapping | None) -> str:
    """The suite's times now against before: the newest ``experiments.suite_timing``
    measurement, what a cold run spends making JAX programs, the old suite's tests alone, and
    one row per earlier pair (``experiments/results/suite_times.json``)."""
    if not data:
        return "_No suite timing is committed under `experiments/results/`._\n"
    measurements = data.get("measurements") or []
    lines = measurement_lines(measurements[0]) + [""] if measurements else []
    prof = data["profile"]
    jax = prof["jax_s"]
    # Each of these lines names its machine: the measurement above may be of another CPU.
    lines += [f"On {data['machine']}, a cold run's workers spent {sum(jax.values()):.0f} s of "
              f"their {prof['user_s']:.0f} s of CPU making JAX programs (tracing "
              f"{jax['trace']:.0f} s, lowering {jax['lower']:.0f} s, XLA's compile "
              f"{jax['compile']:.0f} s; the timing plugin below)."]
    records = [data, *data.get("other_machines", ())]
    same_record = next((r for r in records if r.get("same_tests")), None)
    if same_record:  # the old suite's own tests, run on the code now
        same = same_record["same_tests"]
        lines += ["", f"The tests the suite before had, alone, on {same_record['machine']} "
                  f"({same['what']}): "
                  f"{same['tests']} in {same['pytest_s']:.0f} s of pytest against "
                  f"{same['before_pytest_s']:.0f} s for the suite before in the same script, "
                  f"{100 * same['pytest_s'] / same['before_pytest_s']:.0f} %."]
    # Newest first: the record's own pair and the other pairs each carry their date (a
    # stable sort keeps the record's own pair first among those of its date).
    pairs = [(r["machine"], runs) for r in sorted(records, key=lambda r: r["date"], reverse=True)
             for runs in (r["runs"], (r.get("repeat") or {}).get("runs")) if runs]
    pairs = [(m["machine"], [r for r in m["runs"] if r["pair"] == p])
             for m in measurements[1:] for p in sorted({r["pair"] for r in m["runs"]})] + pairs
    if pairs:
        lines += ["", "Earlier pairs, newest first, of earlier states of the suite as well "
                  "(each described in the record):", "",
                  "| machine | first | before | now, cold | now / before | now, warm / before |",
                  "|---|---|---|---|---|---|"]
        for machine, runs in pairs:
            before = _before_run(runs)
            by = {r["suite"]: r for r in runs}
            cold, warm = by["now, cold"], by.get("now, warm")
            cold_share, warm_share = (f"{100 * r['pytest_s'] / before['pytest_s']:.0f} %"
                                      if r else "-" for r in (cold, warm))
            lines.append(f"| {machine} | {runs[0]['suite'].split(',')[0]} | "
                         f"{before['pytest_s']:.0f} s | "
                         f"{cold['pytest_s']:.0f} s | {cold_share} | {warm_share} |")
    return "\n".join(lines) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m experiments.suite_timing",
        description="Time the test suite of the code now against an earlier commit: fresh "
                    "clones, cold, pairs in alternating order, a CPU probe beside them.")
    parser.add_argument("--before", required=True, help="the earlier commit (e.g. 30ff2ce)")
    parser.add_argument("--now", default="HEAD", help="the code now (default: HEAD; "
                        "uncommitted changes are not in a clone)")
    parser.add_argument("--pairs", type=int, default=2,
                        help="pairs to run, alternating their order (default 2: now, before, "
                             "before, now)")
    parser.add_argument("--command", default="make test", help="what each clone runs")
    parser.add_argument("--repo", type=Path, default=CHECKOUT,
                        help="the repository to clone (default: this checkout)")
    parser.add_argument("--out", type=Path, default=Path("runs/suite_timing.json"),
                        help="the result, rewritten after each run; a run started again with "
                             "the same arguments keeps the runs it holds")
    parser.add_argument("--clones", type=Path, default=None,
                        help="where the clones go (default: a temporary folder)")
    parser.add_argument("--probe-interval", type=float, default=15.0,
                        help="seconds between the probe's timings (default 15)")
    parser.add_argument("--warm", action="store_true",
                        help="run the suite now again in the same clone right after its cold "
                             "run (warm: its compilation cache and bytecode kept)")
    parser.add_argument("--record", type=Path, default=None,
                        help="add the measurement to this record (suite_times.json's "
                             "measurements, newest first)")
    args = parser.parse_args(argv)
    if args.pairs < 1:
        parser.error(f"--pairs must be at least 1, not {args.pairs}")
    if args.out.suffix != ".json":
        parser.error(f"--out {args.out}: a .json file (its runs' logs go beside it, in "
                     f"{args.out.with_suffix('')})")
    repo = args.repo.resolve()
    try:
        now, before = (_git("rev-parse", "--verify", f"{c}^{{commit}}", cwd=repo)
                       for c in (args.now, args.before))
    except subprocess.CalledProcessError as e:
        parser.error(f"not a commit of {repo}: {e.stderr.strip()}")
    coretype = os.environ.get("OPENBLAS_CORETYPE") or None
    settings = _settings(args, now, before, coretype)
    result = {"settings": settings, "date": dt.date.today().isoformat(),
              "machine": machine_text(cpu_peak(), coretype), "runs": []}
    if args.out.exists():
        try:
            earlier = json.loads(args.out.read_text())
        except (OSError, ValueError) as e:
            parser.error(f"--out {args.out}: not a measurement this command wrote ({e})")
        if earlier.get("settings") != settings:
            print(f"{args.out} holds a measurement of other settings "
                  f"({earlier.get('settings')}); give another --out", file=sys.stderr)
            return 2
        result["runs"] = earlier["runs"]
    logs = args.out.with_suffix("")
    logs.mkdir(parents=True, exist_ok=True)
    done = {(r["pair"], r["suite"]) for r in result["runs"]}
    order = run_order(args.pairs)
    with tempfile.TemporaryDirectory(dir=args.clones) as clones, \
            Probe(args.probe_interval) as probe:
        for i, (pair, suite) in enumerate(order):
            suites = [NOW, WARM] if suite == NOW and args.warm else [suite]
            if all((pair, s) in done for s in suites):
                continue
            # A cold run whose warm run was killed runs again with it: the clone is gone.
            result["runs"] = [r for r in result["runs"]
                              if r["pair"] != pair or r["suite"] not in suites]
            commit = now if suite == NOW else before
            labels = [f"{pair}-{s.split(',')[0]}" + ("-warm" if s == WARM else "")
                      for s in suites]

            def started(k, suites=suites, labels=labels, i=i, pair=pair, commit=commit):
                probe.label = labels[k]
                print(f"[{i + 1}/{len(order)}] pair {pair + 1}, the suite {suites[k]} "
                      f"({commit[:7]}): {args.command} in "
                      + ("the same clone again" if k else "a fresh clone"),
                      file=sys.stderr, flush=True)

            runs = time_runs(repo, commit, Path(clones) / labels[0], args.command,
                             [logs / f"{label}.log" for label in labels],
                             clean_env(os.environ), started)
            probe.label = None
            for s, label, run in zip(suites, labels, runs, strict=True):
                run = {"pair": pair, "suite": s, **run, "probe_s": probe.median(label)}
                result["runs"].append(run)
                print(f"    {run['tests']} in {run['pytest_s']} s of pytest, "
                      f"{run['make_test_s']} s of {args.command}, {run['user_s']} s user CPU",
                      file=sys.stderr, flush=True)
            files.write_json(args.out, result)
    summary = shares(result["runs"])
    result["shares"] = summary
    files.write_json(args.out, result)
    for p, s in summary["pairs"].items():
        user = f"{100 * s['user_s']:.1f} %" if s["user_s"] is not None else "-"
        warm = (f"; warm {100 * s['warm_pytest_s']:.1f} %" if "warm_pytest_s" in s else "")
        print(f"pair {p + 1}: the suite now takes {100 * s['pytest_s']:.1f} % of the suite "
              f"before's pytest wall ({user} of its user CPU){warm}")
    for name, s in summary["balanced"].items():
        print(f"pairs {name.replace(',', ' and ')} summed (both orders): "
              f"{100 * s['pytest_s']:.1f} % of the pytest wall")
    if args.record is not None:
        record = json.loads(args.record.read_text()) if args.record.exists() else {}
        # The same measurement recorded again (resumed, or recorded twice) replaces itself.
        record["measurements"] = [result, *(m for m in record.get("measurements", ())
                                            if m.get("settings") != settings)]
        files.write_json(args.record, record, indent=1)  # the record's own layout
        # The documentation's tables are generated from the record: until they are, the
        # suite's own check of them (tests/test_docs.py) fails.
        print(f"added the measurement to {args.record}; `python -m experiments.docs_tables` "
              "regenerates the documentation's tables from it")
    return 0


if __name__ == "__main__":
    sys.exit(main())
