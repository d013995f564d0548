"""Map summarization by condition on the RobotCar-Seasons-like layout (Sec. V, IV-B)."""

import json

import pytest

from experiments.map_summarization import conditions as mc
from rp_jax.sources import robotcar_seasons as rcs
from rp_jax.sources.layout import LayoutError

RATIOS = ("0.5", "0.9")


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The command on the tiny world (the reference, dusk, night and rain traversals)."""
    tmp = tmp_path_factory.mktemp("mapsum_conditions")
    workdir = tmp / "run"
    code = mc.main(["--size", "tiny", "--seeds", "0", "--workdir", str(workdir), "--quiet",
                    "--data-dir", str(tmp / "data" / "tensorflow_datasets"),
                    f"--config.map.ratios=({','.join(RATIOS)})",
                    "--config.map.ransac_iterations=1000"])
    assert code == 0
    return workdir, json.loads((workdir / "metrics.json").read_text())


def test_every_query_is_scored_in_its_condition_and_group(tiny):
    workdir, metrics = tiny
    seed = json.loads((workdir / "seed0" / "seed.json").read_text())
    conds = seed["queries"]["conditions"]
    assert sorted(set(conds)) == ["dusk", "night", "rain"]  # never the reference traversal
    assert all(name.startswith(f"{c}/") for name, c in zip(seed["queries"]["names"], conds))
    assert list(metrics["per_condition"]) == ["dusk", "night", "rain"]
    assert {k: v["conditions"] for k, v in metrics["groups"].items()} == {
        "night": ["night"], "twilight": ["dusk"], "day": ["rain"]}
    # The groups partition the queries; each condition is one traversal on a date of its own.
    assert sum(g["queries"] for g in metrics["groups"].values()) == metrics["queries"]
    assert sum(c["queries"] for c in metrics["per_condition"].values()) == metrics["queries"]
    dates = metrics["condition_dates"]
    assert all(len(v) == 1 for v in dates.values())
    assert dates["night"] == [rcs.CAPTURE_DATES["night"].isoformat()]
    assert len({v[0] for v in dates.values()}) == len(dates)
    assert metrics["methods"] == list(mc.ROWS) and metrics["ratios"] == list(RATIOS)
    assert metrics["labels"]["oracle_date"] == mc.CONDITION_LABELS["oracle_date"]
    assert "own condition's re-detection" in (workdir / "report.md").read_text()


def test_the_report_names_the_primary_comparison(tiny):
    workdir, metrics = tiny
    p = metrics["primary"]
    assert p["group"] == "night" and p["available"]
    assert list(p["cells"]) == ["0.9/0.5m_5deg", "0.9/5m_10deg"]  # 0.8 is not in this run
    assert p["time_matters"] == any(c["interval"][0] > 0 for c in p["cells"].values())
    text = (workdir / "report.md").read_text()
    assert "### Primary comparison: does knowing the condition help at night?" in text
    assert "### Full map by condition" in text
    for name in metrics["figures"]:
        assert (workdir / name).stat().st_size > 0
    assert sorted(metrics["figures"]) == sorted(
        f"accuracy_vs_pruning_{g}.png" for g in ("night", "twilight", "day"))


def test_a_second_run_reuses_the_seeds(tiny, capsys):
    workdir, metrics = tiny
    seed_file = workdir / "seed0" / "seed.json"
    before = seed_file.stat().st_mtime_ns
    assert mc.main(["--size", "tiny", "--seeds", "0", "--workdir", str(workdir), "--quiet",
                    "--data-dir", str(workdir.parent / "data" / "tensorflow_datasets"),
                    f"--config.map.ratios=({','.join(RATIOS)})",
                    "--config.map.ransac_iterations=1000"]) == 0
    assert seed_file.stat().st_mtime_ns == before
    assert json.loads((workdir / "metrics.json").read_text())["accuracy"] == metrics["accuracy"]


def test_each_query_says_what_it_found_in_the_full_map(tiny):
    workdir, metrics = tiny
    q = json.loads((workdir / "seed0" / "seed.json").read_text())["queries"]
    full = json.loads((workdir / "seed0" / "seed.json").read_text())["full_map"]
    n = len(q["names"])
    assert all(len(q[k]) == n for k in mc.EVIDENCE)
    assert all(i <= m for i, m in zip(q["full_map_inliers"], q["full_map_matches"]))
    assert all(r <= k for r, k in zip(q["redetected"], q["keypoints"]))
    # A query localized within any threshold had a pose from at least min_inliers inliers.
    assert all(i >= metrics["min_inliers"] for i, ok in zip(q["full_map_inliers"], full)
               if any(ok))
    night = metrics["per_condition"]["night"]["evidence"]
    assert night == mc.query_evidence([{"queries": q}], ["night"])
    assert "re-detected" in (workdir / "report.md").read_text()


def test_query_evidence_takes_medians_of_the_posed_queries_of_the_conditions():
    q = {"posed": [True, True, False, True], "conditions": ["night", "night", "night", "sun"],
         "keypoints": [10, 30, 1000, 500], "redetected": [1, 3, 100, 50],
         "full_map_matches": [2, 4, 100, 60], "full_map_inliers": [0, 2, 90, 40]}
    assert mc.query_evidence([{"queries": q}], ["night"]) == {
        "keypoints": 20.0, "redetected": 2.0, "full_map_matches": 3.0, "full_map_inliers": 1.0}
    assert mc.query_evidence([{"queries": q}], ["dawn"]) is None
    old = {k: v for k, v in q.items() if k != "redetected"}  # a run before the field
    assert mc.query_evidence([{"queries": old}], ["night"]) is None


def test_restricted_counts_only_the_named_conditions():
    per_seed = [{"seed": 0, "queries": {"posed": [True, True, False, True],
                                        "conditions": ["night", "dusk", "night", "sun"]}}]
    out = mc.restricted(per_seed, ["night", "sun"])
    assert out[0]["queries"]["posed"] == [True, False, False, True]
    assert per_seed[0]["queries"]["posed"] == [True, True, False, True]  # not changed


def _metrics(lo_80: float, lo_90: float, full: float = 30.0) -> dict:
    def cell(lo):
        return {"only_date": 3, "only_agnostic": 1, "interval": [lo, lo + 4.0]}

    acc = {r: {"0.5m_5deg": 10.0, "5m_10deg": 20.0} for r in ("0.8", "0.9")}
    return {"groups": {"night": {
        "queries": 40,
        "full_map_accuracy": {"0.25m_2deg": 0.0, "0.5m_5deg": full, "5m_10deg": full},
        "accuracy": {"oracle_date": acc, "oracle_agnostic": acc},
        "oracle_date_vs_agnostic": {
            "0.8": {"0.5m_5deg": cell(lo_80), "5m_10deg": cell(lo_80)},
            "0.9": {"0.5m_5deg": cell(lo_90), "5m_10deg": cell(lo_90)}},
    }}}


@pytest.mark.parametrize(("lo_80", "lo_90", "matters"), [
    (-1.0, -0.5, False), (0.0, -2.0, False), (-1.0, 0.5, True), (2.0, -1.0, True)])
def test_time_matters_only_where_an_interval_is_entirely_above_zero(lo_80, lo_90, matters):
    p = mc.primary(_metrics(lo_80, lo_90))
    assert p["available"] and len(p["cells"]) == 4
    assert p["time_matters"] is matters


def test_a_night_the_full_map_cannot_localize_is_not_read_as_no_difference():
    p = mc.primary(_metrics(0.0, 0.0, full=0.0))
    assert p["full_map_localizes_none"] and not p["time_matters"]
    assert "Not measurable" in "\n".join(mc._primary_lines(p))
    p = mc.primary(_metrics(0.0, 0.0, full=2.5))
    assert not p["full_map_localizes_none"]
    assert "No interval is entirely above zero" in "\n".join(mc._primary_lines(p))


def test_no_night_query_means_not_measured():
    p = mc.primary({"groups": {"day": {}}})
    assert p == {"group": "night", "available": False}
    assert "Not measured" in "\n".join(mc._primary_lines(p))


def test_a_layout_without_its_reference_model_is_refused(tmp_path):
    (tmp_path / "images" / "night" / "left").mkdir(parents=True)
    config = mc.get_config("tiny")
    config.map.root = str(tmp_path)
    with pytest.raises(LayoutError, match="_synthetic/reference_model"):
        mc.ensure_layout(config, 0, progress=False)


def test_unknown_conditions_are_refused_before_any_work(tmp_path, capsys):
    code = mc.main(["--size", "tiny", "--workdir", str(tmp_path / "w"),
                    "--config.map.conditions=('night','midnight')"])
    assert code == 2
    err = capsys.readouterr().err
    assert "config.map.conditions" in err and "midnight" in err
    assert not (tmp_path / "w" / "metrics.json").exists()
