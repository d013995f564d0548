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
