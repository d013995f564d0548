"""experiments.suite_timing: the order of the runs, pytest's summary, the shares, a whole
measurement on a tiny repository whose 'suite' prints a summary line, and the record as
docs/testing.md shows it."""

import json
import subprocess

import pytest

from experiments import suite_timing as st


def test_pairs_alternate_their_order():
    assert st.run_order(3) == [(0, st.NOW), (0, st.BEFORE), (1, st.BEFORE), (1, st.NOW),
                               (2, st.NOW), (2, st.BEFORE)]
    with pytest.raises(ValueError, match="at least 1"):
        st.run_order(0)


@pytest.mark.parametrize("log, want", [
    ("....\n1122 passed, 9 skipped in 463.00s (0:07:43)\n", ("1122 passed, 9 skipped", 463.0)),
    ("FAILED tests/x.py::t - assert 1\n1 failed, 745 passed, 9 skipped in 877.30s (0:14:37)\n",
     ("1 failed, 745 passed, 9 skipped", 877.3)),
    ("== 2 passed, 1 skipped in 57.1s ==\nlater\n== 3 passed in 1.25s ==\n", ("3 passed", 1.25)),
])
def test_pytest_summary_is_the_last_summary_line(log, want):
    assert st.pytest_summary(log) == want


def test_a_log_without_a_summary_is_refused():
    with pytest.raises(ValueError, match="no pytest summary"):
        st.pytest_summary("ImportError: no module named jax\n")


def _run(pair, suite, pytest_s, user_s):
    return {"pair": pair, "suite": suite, "pytest_s": pytest_s, "make_test_s": pytest_s + 20,
            "user_s": user_s}


def test_shares_per_pair_and_over_both_orders_by_hand():
    runs = [_run(0, st.NOW, 400, 800), _run(0, st.BEFORE, 1000, 1600),
            _run(1, st.BEFORE, 800, 1600), _run(1, st.NOW, 500, 800),
            _run(2, st.NOW, 450, 900)]  # pair 3 unfinished: left out
    s = st.shares(runs)
    assert sorted(s["pairs"]) == [0, 1]
    assert s["pairs"][0]["pytest_s"] == pytest.approx(0.4)
    assert s["pairs"][1]["pytest_s"] == pytest.approx(0.625)
    assert s["pairs"][0]["make_test_s"] == pytest.approx(420 / 1020)
    assert s["pairs"][1]["user_s"] == pytest.approx(0.5)
    assert list(s["balanced"]) == ["1,2"]
    assert s["balanced"]["1,2"]["pytest_s"] == pytest.approx(900 / 1800)
    assert s["median_pytest"] == pytest.approx((0.4 + 0.625) / 2)
    assert st.shares([])["median_pytest"] is None


def test_machine_text_names_the_cpu_kind_and_openblas():
    amd = {"model": "AMD EPYC", "cores": 2, "isa": "AVX2+FMA", "amx_bf16": False}
    intel = {"model": "Intel Xeon", "cores": 2, "isa": "AVX-512", "amx_bf16": True}
    assert st.machine_text(amd, None) == ("a 2-core AMD EPYC (AVX2, no AVX-512), "
                                          "OPENBLAS_CORETYPE not set")
    assert st.machine_text(intel, "Haswell") == ("a 2-core Intel Xeon (AVX-512, AMX-BF16), "
                                                 "OPENBLAS_CORETYPE=Haswell")


def test_the_clones_do_not_use_this_virtual_environment(tmp_path):
    env = {"VIRTUAL_ENV": str(tmp_path), "PATH": f"{tmp_path}/bin:/usr/bin", "HOME": "/root"}
    got = st.clean_env(env, prefix=str(tmp_path))
    assert got == {"PATH": "/usr/bin", "HOME": "/root"}


def _git(*args, cwd):
    subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *args], cwd=cwd,
                   check=True, capture_output=True)


@pytest.fixture()
def repo(tmp_path):
    """Two commits whose 'suite' (``sh suite.sh``) prints a pytest summary: before 8 s,
    now 2 s (1.5 s run again in its clone); every run appends its commit's name to
    ``runs.txt`` outside the clones."""
    repo = tmp_path / "repo"
    repo.mkdir()
    _git("init", "-q", cwd=repo)
    now_again = "[ -e warm ] && { echo '6 passed in 1.50s'; exit; }; touch warm\n"
    for name, line in (("before", "1 failed, 3 passed in 8.00s"), ("now", "5 passed in 2.00s")):
        (repo / "suite.sh").write_text(f"echo {name} >> {tmp_path}/runs.txt\n"
                                       + (now_again if name == "now" else "")
                                       + f"echo '{line}'\n")
        _git("add", "suite.sh", cwd=repo)
        _git("commit", "-q", "-m", name, cwd=repo)
        _git("tag", name, cwd=repo)
    return repo


def _argv(repo, out, *more):
    return ["--repo", str(repo), "--before", "before", "--now", "now", "--command",
            "sh suite.sh", "--out", str(out), "--probe-interval", "0.01", *more]


def test_a_measurement_runs_the_pairs_in_alternating_order_and_resumes(repo, tmp_path, capsys):
    out = tmp_path / "timing.json"
    record_file = tmp_path / "suite_times.json"
    record_file.write_text(json.dumps({"runs": [], "measurements": [{"machine": "older"}]}))
    assert st.main(_argv(repo, out, "--pairs", "2", "--record", str(record_file))) == 0
    # The docs' tables come from the record: the command says how to bring them up to date.
    assert "python -m experiments.docs_tables" in capsys.readouterr().out
    assert (tmp_path / "runs.txt").read_text().split() == ["now", "before", "before", "now"]
    result = json.loads(out.read_text())
    assert [(r["pair"], r["suite"]) for r in result["runs"]] == st.run_order(2)
    before = next(r for r in result["runs"] if r["suite"] == st.BEFORE)
    assert (before["tests"], before["pytest_s"]) == ("1 failed, 3 passed", 8.0)
    assert result["shares"]["pairs"]["0"]["pytest_s"] == pytest.approx(0.25)
    assert result["shares"]["balanced"]["1,2"]["pytest_s"] == pytest.approx(0.25)
    assert (out.parent / "timing" / "0-now.log").read_text().strip() == "5 passed in 2.00s"
    # The record gains the measurement, newest first, and keeps what it held.
    record = json.loads(record_file.read_text())
    assert record["measurements"] == [result, {"machine": "older"}] and record["runs"] == []

    # Killed after its first run: started again, it runs only the three others.
    (tmp_path / "runs.txt").unlink()
    result["runs"] = result["runs"][:1]
    out.write_text(json.dumps(result))
    assert st.main(_argv(repo, out, "--pairs", "2")) == 0
    assert (tmp_path / "runs.txt").read_text().split() == ["before", "before", "now"]
    assert len(json.loads(out.read_text())["runs"]) == 4
    # Other settings: refused, the file kept.
    assert st.main(_argv(repo, out, "--pairs", "4")) == 2
    assert len(json.loads(out.read_text())["runs"]) == 4
    # Recorded again once finished: the record holds it once.
    assert st.main(_argv(repo, out, "--pairs", "2", "--record", str(record_file))) == 0
    assert st.main(_argv(repo, out, "--pairs", "2", "--record", str(record_file))) == 0
    assert [m.get("machine") for m in json.loads(record_file.read_text())["measurements"]] == [
        result["machine"], "older"]


def test_warm_runs_the_suite_now_again_in_its_clone(repo, tmp_path):
    out = tmp_path / "timing.json"
    assert st.main(_argv(repo, out, "--pairs", "1", "--warm")) == 0
    # The 'suite' writes a file into its clone: the warm run finds the cold run's.
    assert (tmp_path / "runs.txt").read_text().split() == ["now", "now", "before"]
    result = json.loads(out.read_text())
    assert [r["suite"] for r in result["runs"]] == [st.NOW, st.WARM, st.BEFORE]
    assert [r["tests"] for r in result["runs"]] == ["5 passed", "6 passed", "1 failed, 3 passed"]
    assert result["shares"]["pairs"]["0"]["warm_pytest_s"] == pytest.approx(1.5 / 8)
    # Killed during the warm run: its cold run is made again with it.
    (tmp_path / "runs.txt").unlink()
    result["runs"] = [r for r in result["runs"] if r["suite"] != st.WARM]
    out.write_text(json.dumps(result))
    assert st.main(_argv(repo, out, "--pairs", "1", "--warm")) == 0
    assert (tmp_path / "runs.txt").read_text().split() == ["now", "now"]
    assert sorted(r["suite"] for r in json.loads(out.read_text())["runs"]) == sorted(
        [st.NOW, st.WARM, st.BEFORE])


def test_a_suite_that_does_not_finish_names_its_log(repo, tmp_path):
    out = tmp_path / "t.json"
    argv = _argv(repo, out, "--pairs", "1")
    argv[argv.index("sh suite.sh")] = "echo 'ImportError: jax'; exit 3"
    with pytest.raises(RuntimeError, match=r"ended \(3\) without finishing.*0-now\.log"):
        st.main(argv)


@pytest.mark.parametrize("argv, message", [
    (["--before", "nosuch", "--out", "t.json"], "not a commit of"),
    (["--before", "before", "--out", "t"], "a .json file"),
    (["--before", "before", "--out", "bad.json"], "not a measurement this command wrote"),
    (["--before", "before", "--pairs", "0"], "at least 1"),
])
def test_bad_arguments_are_refused(repo, tmp_path, capsys, monkeypatch, argv, message):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "bad.json").write_text("{half")
    with pytest.raises(SystemExit):
        st.main(["--repo", str(repo), *argv])
    assert message in capsys.readouterr().err
    assert (tmp_path / "bad.json").read_text() == "{half"  # nothing of the user's rewritten


def _measurement(machine, pytest_s):
    """A suite_timing result as its file holds it: pairs of (now, before) pytest seconds."""
    order = st.run_order(len(pytest_s))
    runs = [{"pair": p, "suite": s, "code": "abc1234", "tests": "9 passed",
             "pytest_s": pytest_s[p][s == st.BEFORE],
             "make_test_s": pytest_s[p][s == st.BEFORE] + 20.0,
             "user_s": 2 * pytest_s[p][s == st.BEFORE], "probe_s": 0.17}
            for p, s in order]
    result = {"settings": {"pairs": len(pytest_s), "command": "make test",
                           "probe_interval_s": 15.0},
              "date": "2030-01-03", "machine": machine, "runs": runs,
              "shares": st.shares(runs)}
    return json.loads(json.dumps(result))


def test_the_docs_block_gives_the_newest_measurement_and_one_row_per_earlier_pair():
    runs = [{"suite": s, "code": "abc", "tests": "9 passed", "pytest_s": p, "make_test_s": p + 4,
             "user_s": 2 * p} for s, p in (("before", 400.0), ("now, cold", 300.0),
                                           ("now, warm", 280.0))]
    record = {"date": "2030-01-01", "machine": "AMD EPYC", "what": "fresh clones", "runs": runs,
              "profile": {"pytest_s": 290.0, "user_s": 500.0,
                          "jax_s": {"trace": 10.0, "lower": 20.0, "compile": 70.0}}}
    text = st.docs_block(record)
    assert ("On AMD EPYC, a cold run's workers spent 100 s of their 500 s of CPU making JAX "
            "programs") in text
    assert "| AMD EPYC | before | 400 s | 300 s | 75 % | 70 % |" in text
    assert "| pair |" not in text and "The tests the suite before had" not in text
    assert "2030" not in text and "abc" not in text  # dates and codes stay in the record
    # Another machine's pair (newer), run with the suite now first; the record's own pair
    # again; the old suite's tests alone.
    again = {"what": "in the other order", "runs": [dict(runs[1], pytest_s=330.0),
                                                      dict(runs[0], pytest_s=440.0)]}
    same = {"what": "the ids both collect", "tests": "8 passed", "pytest_s": 150.0,
            "before_pytest_s": 420.0}
    intel = {"machine": "an Intel Xeon", "date": "2030-01-02", "what": "again",
             "runs": [dict(runs[1], pytest_s=700.0), dict(runs[0], pytest_s=800.0)]}
    record = dict(record, repeat=again, same_tests=same, other_machines=[intel])
    text = st.docs_block(record)
    rows = [line for line in text.splitlines() if line.startswith("| ") and " s |" in line]
    assert rows == ["| an Intel Xeon | now | 800 s | 700 s | 88 % | - |",
                    "| AMD EPYC | before | 400 s | 300 s | 75 % | 70 % |",
                    "| AMD EPYC | now | 440 s | 330 s | 75 % | - |"]
    assert ("The tests the suite before had, alone, on AMD EPYC (the ids both collect): "
            "8 passed in 150 s "
            "of pytest against 420 s for the suite before in the same script, 36 %.") in text
    # Two suite_timing measurements: the newest in full, the older one's pairs as rows.
    newest = _measurement("a 2-core AMD EPYC", [(300.0, 600.0), (330.0, 600.0)])
    older = _measurement("a 2-core Intel Xeon", [(250.0, 500.0)])
    text = st.docs_block(dict(record, measurements=[newest, older]))
    assert ("| 1 | now, cold | 9 passed | 300 s | 320 s | 600 s | 0.170 s |\n"
            "| 1 | before | 9 passed | 600 s | 620 s | 1200 s | 0.170 s |\n"
            "| 2 | before | 9 passed | 600 s | 620 s | 1200 s | 0.170 s |\n"
            "| 2 | now, cold | 9 passed | 330 s | 350 s | 660 s | 0.170 s |") in text
    assert ("The suite now against the suite before, pytest wall: pair 1 50.0 %, pair 2 55.0 %; "
            "pairs 1 and 2 summed (one in each order) 52.5 % of the pytest wall, "
            "54.0 % of `make test`'s, 52.5 % of the user CPU.") in text  # 670 / 1240
    assert "Measured on a 2-core AMD EPYC, with `python -m experiments.suite_timing" in text
    assert "| a 2-core Intel Xeon | now | 500 s | 250 s | 50 % | - |" in text.split(
        "Earlier pairs")[1].splitlines()[4]  # the older measurement's pair, newest row
    assert "2030" not in text and "abc" not in text
    assert "warm" not in text.split("Earlier pairs")[0]  # no warm run measured
    newest["runs"].insert(1, dict(newest["runs"][0], suite="now, warm", pytest_s=240.0))
    newest["shares"] = json.loads(json.dumps(st.shares(newest["runs"])))  # 240 / 600
    text = st.docs_block(dict(record, measurements=[newest]))
    assert "| 1 | now, warm | 9 passed | 240 s |" in text
    assert "pair 2 55.0 %; warm, pair 1 40.0 %; pairs 1 and 2 summed" in text
    assert "No suite timing" in st.docs_block(None)
