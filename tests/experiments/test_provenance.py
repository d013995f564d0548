"""A run's provenance says when and where it ran, so a results table can name its machine."""

import re

from experiments import provenance


def test_gather_names_the_command_code_date_and_machine():
    prov = provenance.gather(["/usr/bin/python3", "-m", "experiments.webcam_clipart", "--quiet"])
    assert prov["command"] == "python -m experiments.webcam_clipart --quiet"
    assert re.fullmatch(r"\d{4}-\d\d-\d\d \d\d:\d\d UTC", prov["date"])
    assert prov["machine"].endswith(" cores") and prov["machine"] == provenance.machine()
    lines = provenance.markdown(prov)
    assert f"- Finished {prov['date']} on {prov['machine']}." in lines
    # A provenance written before these fields renders as before.
    old = {k: v for k, v in prov.items() if k not in ("date", "machine")}
    assert not any(line.startswith("- Finished") for line in provenance.markdown(old))


def test_the_code_is_the_one_the_run_started_with(monkeypatch, tmp_path):
    """A run takes hours; a commit made meanwhile is not its code (the driver asks at its
    start, ``gather`` at its end)."""
    head = {"rev-parse": "a" * 40, "status": ""}
    monkeypatch.setattr(provenance, "_git", lambda *args: head[args[0]])
    monkeypatch.setattr(provenance, "_CHECKOUT", tmp_path)
    (tmp_path / ".git").mkdir()
    provenance.code.cache_clear()
    try:
        assert provenance.code() == "git " + "a" * 40  # the run starts
        head.update({"rev-parse": "b" * 40, "status": " M rp_jax/train.py"})  # a commit
        assert provenance.gather(["python"])["code"] == "git " + "a" * 40  # the run ends
        provenance.code.cache_clear()  # another process, started now
        assert provenance.code() == "git " + "b" * 40 + " + uncommitted changes"
    finally:
        provenance.code.cache_clear()
