"""Map summarization by condition on the RobotCar-Seasons-like layout (Sec. V, IV-B)."""

import json

import pytest

from experiments.map_summarization import conditions as mc
from experiments.map_summarization import conditions_report as mcr
from rp_jax.datasets import builder
from rp_jax.sources import robotcar_seasons as rcs
from rp_jax.sources.layout import LayoutError
from tests.datasets._tiny import tiny_data_copy, tiny_world_copy

RATIOS = ("0.5", "0.9")
# As tests/experiments/test_map_summarization.py: the checks are structural, and on the tiny
# world 250 RANSAC iterations give the metrics of 1000 figure for figure (all but the paths
# and timings of metrics.json).
RANSAC_ITERATIONS = 250


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The command on the tiny world (the reference, dusk, night and rain traversals)."""
    tmp = tmp_path_factory.mktemp("mapsum_conditions")
    workdir = tmp / "run"
    # The session's tiny whole-day RobotCar build (the rp_paper row's RP learns on it).
    data_dir = tiny_data_copy(tmp_path_factory, ["robotcar_day"], tmp / "data")
    # The session's tiny worlds where the command looks for them: the evaluated one (seed 0)
    # and the outcome scorers' label world (seed 1), rendered once in the session.
    for seed in (0, 1):
        tiny_world_copy(tmp_path_factory, "robotcar_seasons",
                        builder.synthetic_root(data_dir, "robotcar_seasons", "tiny", seed), seed)
    code = mc.main(["--size", "tiny", "--seeds", "0", "--workdir", str(workdir), "--quiet",
                    "--data-dir", str(data_dir),
                    f"--config.map.ratios=({','.join(RATIOS)})",
                    f"--config.map.ransac_iterations={RANSAC_ITERATIONS}"])
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
    # Every row's inlier AUC, the paper's rule among them, in the report's own table.
    auc_table = text.split("### How each row ranks the full map's PnP inliers")[1]
    assert "| RP over the whole day, paper's rule |" in auc_table.split("###")[0]
    for name in metrics["figures"]:
        assert (workdir / name).stat().st_size > 0
    assert sorted(metrics["figures"]) == sorted(
        f"accuracy_vs_pruning_{g}.png" for g in ("night", "twilight", "day"))


def test_a_second_run_reuses_the_seeds(tiny, capsys):
    workdir, metrics = tiny
    seed_file = workdir / "seed0" / "seed.json"
    label_file = workdir / "outcome_labels" / "robotcar_seasons_seed1.npz"
    fit_file = workdir / "outcome_scorer_robotcar_seasons" / "fit.json"
    rp_log = workdir / "rp_day" / "metrics.jsonl"  # the whole-day RP: trained once
    before = [f.stat().st_mtime_ns for f in (seed_file, label_file, fit_file, rp_log)]
    assert mc.main(["--size", "tiny", "--seeds", "0", "--workdir", str(workdir), "--quiet",
                    "--data-dir", str(workdir.parent / "data" / "tfds"),
                    f"--config.map.ratios=({','.join(RATIOS)})",
                    f"--config.map.ransac_iterations={RANSAC_ITERATIONS}"]) == 0
    assert [f.stat().st_mtime_ns for f in (seed_file, label_file, fit_file, rp_log)] == before
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
    if matters:  # said of the world, or of counterfactual copies of it
        assert "Time matters at night in this world" in "\n".join(mcr._primary_lines(p))
        assert "in these counterfactual worlds" in "\n".join(mcr._primary_lines(p, True))


def test_a_night_the_full_map_cannot_localize_is_not_read_as_no_difference():
    p = mc.primary(_metrics(0.0, 0.0, full=0.0))
    assert p["full_map_localizes_none"] and not p["time_matters"]
    assert "Not measurable" in "\n".join(mcr._primary_lines(p))
    p = mc.primary(_metrics(0.0, 0.0, full=2.5))
    assert not p["full_map_localizes_none"]
    assert "No interval is entirely above zero" in "\n".join(mcr._primary_lines(p))


def test_no_night_query_means_not_measured():
    p = mc.primary({"groups": {"day": {}}})
    assert p == {"group": "night", "available": False}
    assert "Not measured" in "\n".join(mcr._primary_lines(p))


def test_a_layout_without_its_reference_model_is_refused(tmp_path):
    (tmp_path / "images" / "night" / "left").mkdir(parents=True)
    config = mc.get_config("tiny")
    config.map.root = str(tmp_path)
    with pytest.raises(LayoutError, match="_synthetic/reference_model"):
        mc.ensure_layout(config, 0, progress=False)


def test_a_bad_flag_names_the_command_as_it_is_typed(tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        mc.main(["--seeds", "0,x", "--workdir", str(tmp_path / "w")])
    assert stop.value.code == 2
    assert capsys.readouterr().err.splitlines()[-1].startswith(
        "python -m experiments.map_summarization.conditions: error: argument --seeds: '0,x'")


def test_unknown_conditions_are_refused_before_any_work(tmp_path, capsys):
    code = mc.main(["--size", "tiny", "--workdir", str(tmp_path / "w"),
                    "--config.map.conditions=('night','midnight')"])
    assert code == 2
    err = capsys.readouterr().err
    assert "config.map.conditions" in err and "midnight" in err
    assert not (tmp_path / "w" / "metrics.json").exists()


def test_the_outcome_rows_learn_only_from_worlds_never_evaluated(tiny):
    import numpy as np

    from rp_jax.mapsum.localization_outcomes import OutcomeLabels

    workdir, metrics = tiny
    assert set(mc.OUTCOME_ROWS) <= set(metrics["methods"])
    assert metrics["outcome_scorers"]["label_groups"] == ["robotcar_seasons/seed1"]
    labels = OutcomeLabels.load(workdir / "outcome_labels" / "robotcar_seasons_seed1.npz")
    assert set(np.asarray(labels.group).tolist()) == {"robotcar_seasons/seed1"}
    # Every query of the label world's conditions (the tiny world: dusk, night, rain).
    assert sorted({str(n).split("/")[0] for n in labels.names}) == ["dusk", "night", "rain"]
    assert metrics["outcome_scorers"]["queries"] == labels.num_queries
    # The contrast is the paired difference of the two rows' accuracies.
    gap = metrics["contrasts"]["outcome_top - outcome_agnostic_top"]
    acc = metrics["accuracy"]
    for r in RATIOS:
        for th, cell in gap[r].items():
            assert cell["difference"] == pytest.approx(
                acc["outcome_top"][r][th] - acc["outcome_agnostic_top"][r][th], abs=0.02)
            assert cell["interval"][0] <= cell["difference"] <= cell["interval"][1]
    assert "against its twin and K-cover" in (workdir / "report.md").read_text()


def test_label_worlds_that_are_also_evaluated_are_refused(tmp_path, capsys):
    code = mc.main(["--size", "tiny", "--seeds", "0,1", "--workdir", str(tmp_path / "w"),
                    "--quiet", "--data-dir", str(tmp_path / "data" / "tensorflow_datasets")])
    assert code == 2
    err = capsys.readouterr().err
    assert "outcome_seeds=(1,) shares [1]" in err and "never gives a label" in err
    assert not (tmp_path / "w").exists() and not (tmp_path / "data").exists()


def test_a_given_layout_runs_without_the_outcome_rows():
    config = mc.get_config("tiny")
    assert mc.rows_of(config) == mc.ROWS
    config.map.root = "/some/layout"
    # The RP learns on another street (robotcar_day): it scores a given layout too.
    assert mc.rows_of(config) == (*mc.BASE_ROWS, *mc.RP_ROWS)


def test_the_papers_rule_scores_with_an_rp_over_the_whole_day(tiny):
    workdir, metrics = tiny
    rp = metrics["rp_day"]
    assert rp["schedule"] == "robotcar_day" and rp["timestamps"] == 24
    # Trained on the whole-day world's training viewpoints only (vp01 is its test split).
    assert rp["train_viewpoints"] + rp["validation_viewpoints"] == 1
    seed = json.loads((workdir / "seed0" / "seed.json").read_text())
    n = len(seed["queries"]["names"])
    assert all(len(seed["outcomes"]["rp_paper"][r]) == n for r in RATIOS)
    assert metrics["labels"]["rp_paper"] == mc.CONDITION_LABELS["rp_paper"]
    assert "RP over the whole day" in (workdir / "report.md").read_text()


def test_contrasts_pair_the_rows_query_by_query():
    # Two worlds, one condition each; outcomes per query as [0.25 m, 0.5 m, 5 m] flags.
    def seed(k, a, b, posed):
        return {"seed": k, "queries": {"posed": posed, "dates": ["2014-12-16"] * len(posed)},
                "outcomes": {"outcome_top": {"0.9": [[x] * 3 for x in a]},
                             "outcome_agnostic_top": {"0.9": [[x] * 3 for x in b]}}}

    per_seed = [seed(0, [1, 1, 0, 0], [1, 0, 0, 1], [True] * 4),
                seed(1, [1, 0, 1], [0, 0, 0], [True, True, False])]
    gap = mc.contrasts(per_seed, ["0.9"], mc.ROWS)["outcome_top - outcome_agnostic_top"]
    cell = gap["0.9"]["5m_10deg"]
    # Posed queries: 6; time-aware localizes 3, its twin 2 (the unposed third is not read).
    assert cell["difference"] == pytest.approx(100 * (3 - 2) / 6, abs=0.01)
    assert (cell["only_row"], cell["only_against"]) == (2, 1)
    assert mc.contrasts(per_seed, ["0.9"], mc.BASE_ROWS) == {}


@pytest.mark.parametrize("size", ["tiny", "small", "full"])
def test_the_whole_day_rp_is_the_model_its_own_experiment_trains(size):
    # The by-condition run reuses a finished `python -m experiments.robotcar_day --size SIZE`
    # in <workdir>/rp_day only if every field that makes the model is the same.
    from experiments.map_summarization.train import day_config
    from experiments.robotcar_day.config import get_config as day_experiment
    from rp_jax.train import DATA_FIELDS, MODEL_FIELDS, field_value

    ours, theirs = day_config(mc.get_config(size)).to_dict(), day_experiment(size).to_dict()
    for field in (*MODEL_FIELDS, *DATA_FIELDS, "train.num_epochs", "model.time_fields"):
        assert field_value(ours, field) == field_value(theirs, field), field
    assert ours["input"]["schedule"] == "robotcar_day"


def test_a_given_layout_trains_the_rp_and_never_the_outcome_scorers(tmp_path, monkeypatch):
    class Reached(Exception):
        pass

    trained = []

    class FakeRP:
        params: dict = {}

    def fake_rp(config, rp_dir, progress=True):
        trained.append(rp_dir.name)
        return FakeRP(), {}

    def no_scorers(*args, **kwargs):
        raise AssertionError("a given layout has no other world to label the scorers from")

    def evaluate(config, seed, predictors, *args, **kwargs):
        assert set(predictors) == {"robotcar"} and kwargs["row_names"] == mc.rows_of(config)
        raise Reached

    monkeypatch.setattr(mc, "train_day_predictor", fake_rp)
    monkeypatch.setattr(mc.layout_outcomes, "train_layout_scorers", no_scorers)
    monkeypatch.setattr(mc, "evaluate_world", evaluate)
    config = mc.get_config("tiny")
    config.map.root = str(tmp_path / "layout")
    with pytest.raises(LayoutError, match="layout: no such folder"):  # checked before training
        mc.run(config, tmp_path / "run", progress=False)
    assert trained == [] and not (tmp_path / "run").exists()
    (tmp_path / "layout" / mc.REFERENCE_MODEL_DIR).mkdir(parents=True)  # what it checks
    (tmp_path / "layout" / mc.V2_QUERIES).parent.mkdir(parents=True)
    (tmp_path / "layout" / mc.V2_QUERIES).touch()
    with pytest.raises(Reached):
        mc.run(config, tmp_path / "run", progress=False)
    assert trained == ["rp_day"]


@pytest.mark.slow
def test_seeds_in_processes_give_the_outcomes_of_one_process(tiny, tmp_path, capsys,
                                                            monkeypatch):
    import shutil

    from rp_jax import progress

    monkeypatch.delenv(progress.QUIET_ENV, raising=False)  # the fixture's --quiet set it

    workdir, _ = tiny
    run = tmp_path / "run"  # the fixture's trained models, none of its seeds
    shutil.copytree(workdir, run, ignore=shutil.ignore_patterns("seed*", "metrics.json"))
    config = mc.get_config("tiny")  # the fixture's command line
    config.input.data_dir = str(workdir.parent / "data" / "tfds")
    config.map.ratios = tuple(float(r) for r in RATIOS)
    config.map.ransac_iterations = RANSAC_ITERATIONS
    config.map.seeds = (0, 2)
    config.map.processes = 2
    metrics = mc.run(config, run)
    assert "world seed 0, world seed 2 in 2 processes" in capsys.readouterr().err  # progress
    assert metrics["seeds"] == [0, 2] and metrics["queries"] > 0
    # Seed 0 in a process of its own: what the fixture's run computed in its one process.
    in_a_process, alone = (json.loads((d / "seed0" / "seed.json").read_text())
                           for d in (run, workdir))
    for d in (in_a_process, alone):
        d.pop("timings")
    assert in_a_process == alone


@pytest.mark.slow
def test_a_label_world_in_a_process_of_its_own_gives_the_same_labels(tiny, tmp_path):
    import numpy as np

    from experiments.map_summarization import layout_outcomes, outcome_labels
    from experiments.map_summarization.seed_processes import run_in_processes

    workdir, _ = tiny
    config = mc.get_config("tiny")  # the fixture's command line
    config.input.data_dir = str(workdir.parent / "data" / "tfds")
    config.map.ransac_iterations = RANSAC_ITERATIONS
    name = f"{mc.ROBOTCAR_SEASONS.name}_seed1.npz"  # the fixture's label world, in-process
    run_in_processes(f"{layout_outcomes.__name__}:label_world",
                     [(config, mc.ROBOTCAR_SEASONS, 1, tmp_path, mc.ROBOTCAR_LOCATION)],
                     ["label world 1"], 2, workdir=tmp_path, progress=False)
    with np.load(tmp_path / name) as ours, \
            np.load(workdir / outcome_labels.LABEL_DIR / name) as theirs:
        assert sorted(ours.files) == sorted(theirs.files)
        for k in ours.files:
            np.testing.assert_array_equal(ours[k], theirs[k], err_msg=k)


def test_a_counterfactual_world_is_named_as_one_in_the_report(tmp_path):
    assert mc.counterfactual_of(tmp_path) is None
    (tmp_path / "_synthetic").mkdir()
    (tmp_path / mc.COUNTERFACTUAL_JSON).write_text(json.dumps({
        "factor": "still_noiseless", "description": "no motion blur and no sensor noise",
        "conditions": ["night", "night-rain"], "source": "/somewhere/robotcar_seasons"}))
    record = mc.counterfactual_of(tmp_path)
    assert record == {"factor": "still_noiseless",
                      "description": "no motion blur and no sensor noise",
                      "conditions": ["night", "night-rain"]}
    lines = "\n".join(mcr._counterfactual_lines({"0": record, "3": record}))
    assert "**Counterfactual worlds**" in lines and "world seeds 0, 3" in lines
    assert "night, night-rain: no motion blur and no sensor noise" in lines
    assert mcr._counterfactual_lines(None) == []


def test_mapped_lamps_give_the_outcome_scorers_the_lamps_light(tiny, tmp_path):
    import numpy as np

    from experiments.map_summarization import layout_outcomes, methods, outcome_labels
    from experiments.map_summarization import outcome_scorer as mos
    from rp_jax.mapsum.localization_outcomes import OutcomeLabels
    from rp_jax.mapsum.outcome_scorer import mapped_lamp_light

    workdir, _ = tiny
    config = mc.get_config("tiny")  # the fixture's command line, with the lamps
    config.input.data_dir = str(workdir.parent / "data" / "tfds")
    config.map.ransac_iterations = RANSAC_ITERATIONS
    config.map.mapped_lamps = True
    labels, table, queries = layout_outcomes.world_outcomes(
        config, mc.ROBOTCAR_SEASONS, 1, tmp_path, place=mc.ROBOTCAR_LOCATION, progress=False)
    name = f"{mc.ROBOTCAR_SEASONS.name}_seed1.npz"  # the fixture's label world, no lamps
    theirs = OutcomeLabels.load(workdir / outcome_labels.LABEL_DIR / name)
    with np.load(workdir / outcome_labels.LABEL_DIR / name) as z, np.load(tmp_path / name) as ours:
        assert str(z["fingerprint"]) != str(ours["fingerprint"])
        np.testing.assert_array_equal(table[:, :-1], z["point_table"])
    np.testing.assert_array_equal(labels.inlier, theirs.inlier)  # the same outcomes

    root = mc.ensure_layout(config, 1, progress=False)
    world = mc.build_map(config, root, {}, 1, progress=False)
    lamps = mc.street_lamps(config, 1)
    assert len(lamps) >= 2 and world.lamps is not None
    np.testing.assert_allclose(world.lamps, lamps)
    np.testing.assert_allclose(table[:, -1], mapped_lamp_light(world.map_points.xyz, lamps),
                               rtol=1e-5)
    assert table[:, -1].std() > 0.1  # near and far from a lamp

    scorers = mos.fit_scorers(mos.settings_of(config),
                              mos.stack_groups([(labels, table, queries)]), ["seed1"],
                              tmp_path / "scorers", "lamps", place=mc.ROBOTCAR_LOCATION,
                              lamps=True, progress=False)
    assert scorers.reads_lamps and not scorers.reads_rp
    fit = json.loads((tmp_path / "scorers" / "fit.json").read_text())
    assert fit["asked"]["features"][-1] == "mapped_lamp_light"
    obs = world.observations
    when = rcs.traversal_start("night")
    ctx = methods.WorldContext(
        config=config, seed=1, map_points=world.map_points, parts=world.parts,
        point_descriptors=world.point_descriptors,
        queries=[{"bucket": when, "image_path": root / "nowhere.jpg"}],
        extra={"observations": obs, "reconstruction": world.reconstruction, "point_rep": {},
               "lamps": world.lamps})
    at_time, _ = mos._world_scores("outcome")(ctx, scorers)
    scores = at_time(methods.At(time=when, date=when.date()))
    assert scores.shape == (world.map_points.num_points,) and np.isfinite(scores).all()
    ctx.extra["lamps"] = None
    ctx._cache.clear()
    with pytest.raises(ValueError, match="mapped_lamps"):
        mos._world_scores("outcome")(ctx, scorers)[0](methods.At(time=when, date=when.date()))


def test_mapped_lamps_need_the_synthetic_world(tmp_path, capsys):
    code = mc.main(["--size", "tiny", "--workdir", str(tmp_path / "w"),
                    f"--config.map.root={tmp_path}", "--config.map.mapped_lamps=True"])
    assert code == 2
    err = capsys.readouterr().err
    assert "config.map.mapped_lamps=True" in err and "config.map.root" in err
    assert not (tmp_path / "w" / "metrics.json").exists()


def test_runs_compared_for_the_lamps_column_must_differ_in_nothing_else():
    import copy
    from pathlib import Path

    path = (Path(__file__).parents[2] / "experiments" / "results"
            / "map_summarization_conditions_nights_cf" / "metrics.json")
    run = json.loads(path.read_text())
    text = mcr.mapped_lamps_markdown(run, run)
    assert text.count("| night, ") == 4 and "time-aware minus twin, lamps" in text
    night = run["groups"]["night"]["accuracy"]
    assert f"| {night['outcome_top']['0.9']['5m_10deg']:.1f} |" in text
    for change in (lambda m: m["groups"]["night"]["accuracy"]["kcover"]["0.9"].update(
                       {"5m_10deg": 99.0}),
                   lambda m: m.update(seeds=[0, 1]),
                   lambda m: m["outcome_scorers"].update(label_groups=["robotcar_seasons/seed5"])):
        other = copy.deepcopy(run)
        change(other)
        with pytest.raises(ValueError, match="differ"):
            mcr.mapped_lamps_markdown(run, other)
