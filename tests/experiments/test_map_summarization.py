"""The map-summarization experiment (Sec. V, IV-B, Fig. 11): its command, metrics and pieces."""

import datetime as dt
import json
import os

import cv2
import numpy as np
import pycolmap
import pytest

from experiments.map_summarization import experiment as mexp
from experiments.map_summarization.__main__ import DEFAULT_SIZE, main, parse
from experiments.map_summarization.train import rp_config
from rp_jax.localize import read_submission
from rp_jax.mapsum import MapPoints, read_model
from rp_jax.mapsum.observations import point_categories, query_scores
from rp_jax.sources.colmap_model import opencv_camera
from tests.datasets._tiny import tiny_data_copy

METHODS = [
    "rp_paper",
    "rp",
    "outcome_top",
    "rp_cmu_kcover",
    "kcover",
    "random",
    "most_observed",
    "maplab",
    "oracle_agnostic",
    "oracle_date",
    "oracle_inliers",
]
RATIOS = ["0.5", "0.7", "0.9"]
THRESHOLDS = ["0.25m_2deg", "0.5m_5deg", "5m_10deg"]
RANSAC_ITERATIONS = 250


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """The whole experiment at tiny size, from its command line (1 epoch, 3 ratios)."""
    tmp = tmp_path_factory.mktemp("mapsum")
    workdir = tmp / "run"
    # The session's tiny RobotCar and CMU builds and worlds (rendered and labelled once for
    # every test that reads them; their builds are tested in tests/datasets/).
    data_dir = tiny_data_copy(tmp_path_factory, ["robotcar", "cmu_seasons"], tmp / "data")
    argv = [
        "--size",
        "tiny",
        "--workdir",
        str(workdir),
        "--data-dir",
        str(data_dir),
        "--config.train.num_epochs=1",
        # The CMU-trained RP (rp_cmu rows) for one epoch as well: its 3,300 tiny records
        # for two epochs were a quarter of the fixture.
        "--config.map.cmu_rp_epochs=1",
        f"--config.map.ratios=({','.join(RATIOS)})",
        # A query that fails runs every RANSAC iteration (27 ms at 5000): most of a test's
        # time on a pruned tiny map. The tests' checks are structural; on the tiny world 250
        # iterations give the metrics file of 1000 figure for figure (a query localized
        # stops early at RANSAC's confidence), for 10 s less CPU across this file.
        f"--config.map.ransac_iterations={RANSAC_ITERATIONS}",
    ]
    assert main(argv) == 0
    return workdir, json.loads((workdir / "metrics.json").read_text()), argv


@pytest.mark.slow
def test_metrics_file_shape_and_values(tiny_run):
    _, metrics, _ = tiny_run
    # The tiny world: slice 8, query dates Sep 01 and Jul 28, 4 positions x 2 cameras each.
    assert metrics["queries"] == 16 and metrics["seeds"] == [0]
    assert metrics["query_dates"] == ["2010-09-01", "2011-07-28"]
    n = metrics["queries"]
    for key in ("accuracy", "interval", "paired"):
        assert list(metrics[key]) == METHODS
        for method in METHODS:
            assert list(metrics[key][method]) == RATIOS
            for ratio in RATIOS:
                assert list(metrics[key][method][ratio]) == THRESHOLDS
    for method in METHODS:
        for ratio in RATIOS:
            acc = [metrics["accuracy"][method][ratio][th] for th in THRESHOLDS]
            assert acc == sorted(acc)  # nested thresholds: accuracy cannot drop as they loosen
            for th in THRESHOLDS:
                a = metrics["accuracy"][method][ratio][th]
                assert abs(a * n / 100 - round(a * n / 100)) < 1e-6  # a count of n queries
                lo, hi = metrics["interval"][method][ratio][th]
                assert lo <= a <= hi
                pr = metrics["paired"][method][ratio][th]
                kc = metrics["accuracy"]["kcover"][ratio][th]
                # Discordant counts explain the difference to K-cover exactly.
                assert pr["only_method"] - pr["only_kcover"] == round((a - kc) * n / 100)
                if method == "kcover":
                    assert pr == {"only_method": 0, "only_kcover": 0, "p": 1.0}
    assert set(metrics["inlier_auc"]) == set(METHODS)
    gap = metrics["oracle_date_vs_agnostic"]
    assert list(gap) == RATIOS and all(list(gap[r]) == THRESHOLDS for r in RATIOS)
    # The date oracle knows which points are re-detected: it must rank inliers well.
    assert metrics["inlier_auc"]["oracle_date"] > 0.7
    assert metrics["full_map_accuracy"]["5m_10deg"] > 50, "the unpruned map localizes too little"
    assert metrics["maps"]["0"]["descriptor_association_rate"] > 0.95
    assert len(metrics["rp_training"]["schedule"]["labels"]) == 9
    cov = metrics["image_coverage"]["kcover"]
    assert cov["0.5"]["min"] >= cov["0.9"]["min"] and cov["0.5"]["median"] > cov["0.9"]["median"]
    sizes = metrics["map_sizes"]["0"]
    assert sizes["full"] > sizes["0.5"] > sizes["0.7"] > sizes["0.9"] > 0


@pytest.mark.slow
def test_outputs_written_and_a_rerun_reuses_the_seed(tiny_run):
    workdir, metrics, argv = tiny_run
    for name in metrics["figures"]:
        img = cv2.imread(str(workdir / name))
        assert img is not None and img.shape[0] > 200 and img.std() > 10, name
    report = (workdir / "report.md").read_text()
    assert "| RP, paper's protocol |" in report and "(oracle)" in report
    assert "exact McNemar p" in report
    assert "learning_curve.png" in metrics["figures"] and "![learning_curve.png]" in report
    assert "## Provenance" in report and "- Code: " in report and " optax " in report
    seed_dir = workdir / "seed0"
    outcomes = json.loads((seed_dir / "seed.json").read_text())["outcomes"]
    for method in METHODS:
        for ratio in RATIOS:
            poses = read_submission(seed_dir / "submissions" / f"{method}_{ratio}.txt")
            # Every query within (5 m, 10 deg) was localized; none is invented.
            within = sum(o[2] for o in outcomes[method][ratio])
            assert within <= len(poses) <= len(outcomes[method][ratio])
    summary = read_model(seed_dir / "summaries" / "rp_0.5")
    assert summary.num_points3D() == metrics["map_sizes"]["0"]["0.5"]
    # A second run of the same command reuses the finished seed (and the trained RP).
    mtime = os.stat(seed_dir / "seed.json").st_mtime_ns
    assert main(argv) == 0
    assert os.stat(seed_dir / "seed.json").st_mtime_ns == mtime
    assert json.loads((workdir / "metrics.json").read_text())["accuracy"] == metrics["accuracy"]
    # A seed's own process (--processes) loads the run's models from the workdir and finds
    # the run's fingerprint: it reads the finished seed; another fingerprint is refused.
    config, _ = parse(argv)
    done = json.loads((seed_dir / "seed.json").read_text())
    assert mexp.evaluate_seed(config, workdir, 0, done["fingerprint"]) == done
    assert os.stat(seed_dir / "seed.json").st_mtime_ns == mtime
    with pytest.raises(ValueError, match="another run changed them"):
        mexp.evaluate_seed(config, workdir, 0, "0123456789abcdef")


@pytest.mark.slow
def test_a_label_slice_in_a_process_of_its_own_gives_the_same_labels(tiny_run, tmp_path):
    import shutil

    from experiments.map_summarization import outcome_labels
    from experiments.map_summarization.seed_processes import run_in_processes

    workdir, _, argv = tiny_run
    config, _ = parse(argv)
    (done,) = sorted((workdir / outcome_labels.LABEL_DIR).glob("seed*_slice*.npz"))
    seed, slice_id = (int(x) for x in done.stem[len("seed"):].split("_slice"))
    shutil.copytree(workdir / "rp", tmp_path / "rp")  # the run's RobotCar RP, loaded there
    run_in_processes(f"{outcome_labels.__name__}:label_slice",
                     [(config, tmp_path, seed, slice_id)], [done.stem], 2, workdir=tmp_path,
                     progress=False)
    with np.load(tmp_path / outcome_labels.LABEL_DIR / done.name) as ours, \
            np.load(done) as theirs:
        assert sorted(ours.files) == sorted(theirs.files)
        for k in ours.files:
            np.testing.assert_array_equal(ours[k], theirs[k], err_msg=k)


def _seed_result(posed, outcomes_rp, outcomes_kc, dates):
    per = {m: {"0.5": outcomes_kc} for m in METHODS}
    per["rp"] = {"0.5": outcomes_rp}
    auc = {m: {"all": 0.6, dates[0]: 0.6} for m in METHODS}
    cov = {m: {"0.5": [3, 5.0]} for m in METHODS}
    return {
        "queries": {"posed": posed, "dates": dates},
        "outcomes": per,
        "full_map": outcomes_kc,
        "auc": auc,
        "coverage": cov,
    }


def test_pool_scores_posed_queries_only_and_pairs_them():
    ok, no = [True] * 3, [False] * 3
    # Seed A: 4 queries, the last two without a pose (as on a real CMU download).
    a = _seed_result(
        [True, True, False, False], [ok, ok, ok, ok], [ok, no, no, no], ["2010-09-01"] * 4
    )
    # Seed B: 2 posed queries.
    b = _seed_result([True, True], [ok, no], [no, no], ["2010-09-01"] * 2)
    pooled = mexp.pool([a, b], ["0.5"], resamples=200)
    assert pooled["queries"] == 4 and pooled["queries_without_pose"] == 2
    # rp localizes 3 of the 4 posed queries, K-cover 1: only rp 2, only K-cover 0.
    assert pooled["accuracy"]["rp"]["0.5"]["5m_10deg"] == 75.0
    assert pooled["accuracy"]["kcover"]["0.5"]["5m_10deg"] == 25.0
    assert pooled["paired"]["rp"]["0.5"]["5m_10deg"] == {
        "only_method": 2,
        "only_kcover": 0,
        "p": 0.5,
    }
    # Two clusters (seed A's and seed B's date), each +1 of 2 posed queries: +50 points
    # whichever clusters a resample draws.
    assert pooled["paired_interval"]["rp"]["0.5"]["5m_10deg"] == [50.0, 50.0]
    assert pooled["paired_interval"]["kcover"]["0.5"]["5m_10deg"] == [0.0, 0.0]
    with pytest.raises(ValueError, match="no query has a ground-truth pose"):
        mexp.pool([_seed_result([False], [ok], [ok], ["2010-09-01"])], ["0.5"])


def test_default_size_seeds_and_overrides():
    config, workdir = parse(["--config.map.cell_size_m=5"])
    assert config.map.synthetic_size == DEFAULT_SIZE
    assert config.input.data_config == f"synthetic_{DEFAULT_SIZE}"
    assert config.map.cell_size_m == 5.0
    assert str(workdir).endswith(f"map_summarization_{DEFAULT_SIZE}")
    assert config.input.dataset == "robotcar" and config.input.schedule == "robotcar"
    assert config.map.query_dates == ()  # every query date of the layout
    assert config.map.seeds == (0, 1, 2)
    assert config.map.ratios == (0.5, 0.6, 0.7, 0.8, 0.9)
    config, _ = parse(["--size", "tiny", "--seeds", "3,5"])
    assert config.input.data_config == "synthetic_tiny" and config.map.seeds == (3, 5)
    config, _ = parse(["--seeds=4"])
    assert config.map.seeds == (4,)
    for bad in (["--seeds", "a,b"], ["--seeds", "-1"], ["--seeds"]):
        with pytest.raises(SystemExit):
            parse(bad)


def test_rp_config_drops_map_fields(tmp_path):
    config, _ = parse(["--size", "tiny", "--manual-dir", str(tmp_path)])
    cfg = rp_config(config)
    assert "map" not in cfg and "map" in config
    assert cfg.input.manual_dir == str(tmp_path.absolute() / "robotcar")


def test_point_categories_majority():
    mp = MapPoints(
        np.zeros((3, 3)),
        [1, 2, 3],
        [0, 0, 0, 1, 1],
        [1, 2, 3, 1, 2],
        [0, 0, 0, 1, 1],
        np.zeros((5, 2)),
    )
    cats = point_categories(mp, np.array([2, 2, 0, -1, -1]))
    np.testing.assert_array_equal(cats, [2, -1, -1])


def test_query_scores_interpolate_the_cycle():
    from rp_jax.schedule import preset

    sched = preset("robotcar")  # 9:00 ... 17:00 hourly
    rep = np.tile(np.arange(9, dtype=float), (2, 1))
    when = dt.datetime(2011, 3, 4, 10, 30)
    np.testing.assert_allclose(query_scores(rep, sched, when), [1.5, 1.5])


def test_bucket():
    t = dt.datetime(2011, 3, 4, 10, 17, 42)
    assert mexp.bucket(t, 10) == dt.datetime(2011, 3, 4, 10, 10)
    assert mexp.bucket(t, 60) == dt.datetime(2011, 3, 4, 10, 0)


def test_opencv_camera_shifts_principal_point():
    cam = pycolmap.Camera(
        model="OPENCV",
        width=100,
        height=80,
        params=[90.0, 91.0, 50.5, 40.5, -0.3, 0.1, 0.001, 0.002],
    )
    K, dist, w, h = opencv_camera(cam)
    np.testing.assert_allclose(K, [[90, 0, 50], [0, 91, 40], [0, 0, 1]])
    np.testing.assert_allclose(dist, [-0.3, 0.1, 0.001, 0.002])
    assert (w, h) == (100, 80)


def test_plot_accuracy_vs_pruning_with_intervals(tmp_path):
    from rp_jax.plots import plot_accuracy_vs_pruning

    acc = {m: {r: {k: 10.0 * i for k in THRESHOLDS} for i, r in enumerate(RATIOS)} for m in METHODS}
    ivl = {m: {r: {k: [0.0, 30.0] for k in THRESHOLDS} for r in RATIOS} for m in METHODS}
    path = plot_accuracy_vs_pruning(
        acc,
        tmp_path / "f.png",
        intervals=ivl,
        full_map={k: 80.0 for k in THRESHOLDS},
        thresholds=THRESHOLDS,
    )
    img = cv2.imread(str(path))
    assert img is not None and img.shape[1] > 2 * img.shape[0]  # three panels side by side


def test_methods_and_recipes_of_a_config():
    config, _ = parse(["--size", "tiny"])
    assert mexp.methods_of(config) == METHODS  # the default rows
    # The recommended row is the outcome scorer's time-agnostic twin, top per part.
    assert mexp.recipe_of("rp", config) == ("outcome_agnostic", "top")
    config.map.candidates = ("rp_cmu", "rp_paper", "rp_cmu")
    assert mexp.methods_of(config) == METHODS[:2] + ["rp_cmu"] + METHODS[4:]
    config.map.rp_method = "rp_cmu_kcover"
    assert mexp.recipe_of("rp", config) == mexp.RP_RECIPES[config.map.rp_method]
    assert mexp.recipe_of("kcover", config) is None
    config.map.rp_method = "rp_magic"
    with pytest.raises(ValueError, match="unknown RP recipe 'rp_magic'"):
        mexp.methods_of(config)


def test_pool_pairs_a_candidate_recipe_with_rp():
    ok, no = [True] * 3, [False] * 3
    a = _seed_result([True] * 4, [ok, ok, no, no], [no] * 4, ["2010-09-01"] * 4)
    a["outcomes"]["rp_conditional"] = {"0.5": [no, ok, ok, ok]}
    a["auc"]["rp_conditional"] = {"all": 0.5}
    a["coverage"]["rp_conditional"] = {"0.5": [3, 5.0]}
    pooled = mexp.pool([a], ["0.5"], resamples=50)
    # rp_conditional alone localizes queries 3 and 4, rp alone query 1.
    # ... and with one (seed, date) cluster the clustered interval is the difference itself:
    # (3 - 2) of 4 queries = +25 points.
    assert pooled["paired_vs_rp"]["rp_conditional"]["0.5"]["5m_10deg"] == {
        "only_method": 2, "only_rp": 1, "p": 1.0, "interval": [25.0, 25.0]}
    # every candidate recipe (the default ones and rp_conditional), not the baselines, not
    # the oracles, not rp
    assert set(pooled["paired_vs_rp"]) == {"rp_conditional", "outcome_top", "rp_cmu_kcover"}


def test_pool_refuses_seeds_of_different_methods():
    ok = [True] * 3
    a = _seed_result([True], [ok], [ok], ["2010-09-01"])
    b = _seed_result([True], [ok], [ok], ["2010-09-01"])
    del b["outcomes"]["random"]
    with pytest.raises(ValueError, match="different methods"):
        mexp.pool([a, b], ["0.5"])


def test_pool_pairs_the_two_oracles():
    ok, no = [True] * 3, [False] * 3
    a = _seed_result([True] * 4, [ok] * 4, [ok] * 4, ["2010-09-01"] * 4)
    a["outcomes"]["oracle_date"] = {"0.5": [ok, ok, ok, no]}
    a["outcomes"]["oracle_agnostic"] = {"0.5": [no, no, ok, ok]}
    gap = mexp.pool([a], ["0.5"], resamples=50)["oracle_date_vs_agnostic"]["0.5"]["5m_10deg"]
    # One world and one date: one cluster, so the interval is the difference itself.
    assert gap == {"only_date": 2, "only_agnostic": 1, "p": 1.0, "interval": [25.0, 25.0]}


@pytest.mark.slow
def test_a_layout_where_half_the_queries_have_no_pose(tiny_run, tmp_path):
    """As on a real download: the posed half is scored, the rest localized and counted."""
    import shutil

    from rp_jax.sources import cmu_seasons
    from rp_jax.sources.synthetic import presets, write_layout

    workdir, metrics, argv = tiny_run
    root = tmp_path / "cmu"
    shutil.copytree(metrics["dataset"]["map"][0], root)
    poses = cmu_seasons.read_query_ground_truth(root, 8)
    assert len(poses) == 16
    kept = sorted(poses)[::2]
    (root / presets.EVALUATION_DIR / "ground-truth-query-images-slice8.txt").unlink()
    write_layout.write_cmu_query_poses(root / "slice8", [(n, *poses[n]) for n in kept])
    tfds_dir = argv[argv.index("--data-dir") + 1]
    # The fixture's RobotCar RP, trained on the same records with the same config (the map's
    # layout is not part of it): the command loads it instead of training it again.
    shutil.copytree(workdir / "rp", tmp_path / "run" / "rp")
    half = [
        "--size", "tiny", "--workdir", str(tmp_path / "run"), "--data-dir", tfds_dir,
        "--config.train.num_epochs=1", f"--config.map.root={root}", "--config.map.ratios=(0.5,)",
        f"--config.map.ransac_iterations={RANSAC_ITERATIONS}",
        # What this test checks is the scoring of a half-posed layout, not the rows: the
        # paper's recipe alone needs no CMU predictor and no outcome labels (the fixture
        # runs the default rows).
        "--config.map.rp_method=rp_paper", "--config.map.candidates=()",
    ]
    assert main(half) == 0
    out = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert out["queries"] == 8 and out["queries_without_pose"] == 8
    report = (tmp_path / "run" / "report.md").read_text()
    assert "8 with a ground-truth pose (8 without one" in report
    # Every query was localized and written, posed or not.
    sub = read_submission(tmp_path / "run" / "seed0" / "submissions" / "full_map.txt")
    assert set(sub) - set(kept), "no unposed query in the submission"


def test_a_bad_recipe_exits_2_before_any_work(tmp_path, capsys):
    argv = ["--size", "tiny", "--workdir", str(tmp_path / "w"), "--config.map.rp_method=bogus"]
    assert main(argv) == 2
    assert "unknown RP recipe 'bogus'" in capsys.readouterr().err
    assert not (tmp_path / "w").exists()


@pytest.mark.slow
def test_rp_conditional_recipe_end_to_end_on_the_tiny_world(tiny_run, tmp_path):
    """``rp_conditional`` (issue 17) on the fixture's world: every query is localized on a
    summary of the same size as K-cover's, per bucket; its scores are the scorer's means."""
    import jax

    from experiments.map_summarization.train import conditional_network
    from rp_jax import predict
    from rp_jax.conditional.model import init_params
    from rp_jax.mapsum.conditional_scores import ConditionalScorer

    workdir, metrics, argv = tiny_run
    # ``rp`` on the RobotCar RP here, so that no CMU RP is needed.
    config, _ = parse([*argv, "--config.map.ratios=(0.5,)", "--config.map.rp_method=rp_kcover",
                       "--config.map.candidates=('rp_conditional','rp_conditional_kcover')"])
    net = conditional_network(config)
    assert net.conditions == ("sun",)
    # Untrained weights: the recipe's path (scores at each bucket, the rules, localization)
    # is what is tested here; the fit is tested in tests/conditional.
    scorer = ConditionalScorer(net, init_params(net, jax.random.key(0)), place=(40.44, -79.99))
    predictors = {"robotcar": predict.load(workdir / "rp"), "conditional": scorer}
    # The rows checked here and K-cover, which they are sized by (the default rows are the
    # fixture's).
    out = mexp.evaluate_world(config, 0, predictors, tmp_path / "seed0", fingerprint="t",
                              progress=False,
                              row_names=["kcover", "rp_conditional", "rp_conditional_kcover"])
    kept = out["kept_points"]
    for method in ("rp_conditional", "rp_conditional_kcover"):
        assert len(out["outcomes"][method]["0.5"]) == metrics["queries"]
        # One summary per query-time bucket (the score depends on the query's time), each
        # as large as K-cover's.
        assert len(kept[method]["0.5"]) > 1
        assert kept[method]["0.5"] == kept["kcover"]["0.5"] * len(kept[method]["0.5"])
    assert out["auc"]["rp_conditional"]["all"] is not None
    assert "conditional_scores_s" in out["timings"]


def test_rp_conditional_with_the_query_images_own_conditions(tiny_run, tmp_path):
    """A model that reads the weather and the appearance: the synthetic world's weather
    record and each query image's look are given, and each query gets its own summary."""
    import jax

    from experiments.map_summarization.train import conditional_network
    from rp_jax import predict
    from rp_jax.conditional.model import init_params
    from rp_jax.mapsum.conditional_scores import ConditionalScorer

    workdir, metrics, argv = tiny_run
    config, _ = parse([*argv, "--config.map.ratios=(0.5,)", "--config.map.rp_method=rp_kcover",
                       "--config.map.candidates=('rp_conditional_kcover',)",
                       "--config.map.conditional_conditions=sun,weather,appearance"])
    net = conditional_network(config)
    assert net.conditions == ("sun", "weather", "appearance")
    scorer = ConditionalScorer(net, init_params(net, jax.random.key(0)), place=(40.44, -79.99))
    predictors = {"robotcar": predict.load(workdir / "rp"), "conditional": scorer}
    out = mexp.evaluate_world(config, 0, predictors, tmp_path / "seed0", fingerprint="t",
                              progress=False, row_names=["kcover", "rp_conditional_kcover"])
    n = metrics["queries"] + metrics["queries_without_pose"]
    assert out["conditional_summary_per_query"] is True
    assert out["query_conditions"] == {"conditions": ["sun", "weather", "appearance"],
                                       "weather_known": n, "appearance_known": n, "queries": n}
    kept = out["kept_points"]["rp_conditional_kcover"]["0.5"]
    assert len(kept) == n and set(kept) == set(out["kept_points"]["kcover"]["0.5"])
    assert out["auc"]["rp_conditional_kcover"]["all"] is not None


def test_report_pairs_each_candidate_with_rp():
    from experiments.map_summarization import report

    cell = {"only_method": 7, "only_rp": 1, "p": 0.0703}
    metrics = {"ratios": ["0.5", "0.9"], "paired_vs_rp": {"rp_conditional_kcover": {
        "0.5": {"5m_10deg": cell, "0.5m_5deg": cell},
        "0.9": {"5m_10deg": {"only_method": 20, "only_rp": 3, "p": 2e-4},
                "0.5m_5deg": {"only_method": 1, "only_rp": 15, "p": 1e-3}}}}}
    table = report.paired_rp_table(metrics, {"rp_conditional_kcover": "cond"}, "5m_10deg")
    assert table[2] == "| cond | +7 / -1 (p 0.0703) | +20 / -3 (p 2.0e-04) |"
    said = report.findings_vs_rp(metrics, {"rp_conditional_kcover": "cond"})
    assert "more queries than rp at no ratio, fewer at 0.9" in said[0]  # 0.5m_5deg
    assert "more queries than rp at 0.9, fewer at none" in said[1]  # 5m_10deg


def _tiny_context(dates, posed, hits, n_points=4):
    """A WorldContext of a map of ``n_points`` single-observation points and the given
    queries' re-detections (no images needed: the oracle rows read only these)."""
    from experiments.map_summarization import methods

    mp = MapPoints(np.zeros((n_points, 3)), np.arange(n_points) + 1, np.arange(n_points),
                   np.ones(n_points, int), np.arange(n_points), np.zeros((n_points, 2)),
                   image_names={1: "db.jpg"})
    config, _ = parse(["--size", "tiny"])
    queries = [{"date": d, "pose": (np.eye(3), np.zeros(3)) if p else None,
                "bucket": dt.datetime.combine(d, dt.time(10))} for d, p in zip(dates, posed)]
    return methods.WorldContext(config=config, seed=0, map_points=mp,
                                parts=np.zeros(n_points, np.int64),
                                point_descriptors=np.zeros((n_points, 128)), queries=queries,
                                hits=[np.asarray(h, np.int64) for h in hits])


def test_oracle_rows_never_score_a_query_with_its_own_redetection():
    """The own-date oracle row: query 0 alone re-detects point 0, so point 0 scores below
    the points the other query of its date re-detects (the old row counted every posed
    query of the date, the query included); the matched agnostic row sees one query of
    another date, as many as the date oracle sees."""
    from experiments.map_summarization import methods

    a, b = dt.date(2010, 9, 1), dt.date(2011, 7, 28)
    ctx = _tiny_context([a, a, b, b], [True] * 4, [[0], [1, 2], [3], [3]])
    date_row, agnostic_row = methods.ROWS["oracle_date"], methods.ROWS["oracle_agnostic"]
    assert methods.per_of(date_row, {}) == "query"
    s0 = date_row.score(ctx, methods.At(ctx.queries[0]["bucket"], a, 0))
    np.testing.assert_array_equal(np.floor(s0), [0, 1, 1, 0])  # the count, less the tiebreak
    s1 = date_row.score(ctx, methods.At(ctx.queries[1]["bucket"], a, 1))
    np.testing.assert_array_equal(np.floor(s1), [1, 0, 0, 0])
    keep = date_row.select(ctx, date_row, 0.5, methods.At(ctx.queries[0]["bucket"], a, 0))
    assert not keep[0] and keep[1] and keep[2]
    s = agnostic_row.score(ctx, methods.At(ctx.queries[0]["bucket"], a))
    np.testing.assert_array_equal(np.floor(s), [0, 0, 0, 1])  # one query of date b
    with pytest.raises(ValueError, match="one query at a time"):
        date_row.score(ctx, methods.At(ctx.queries[0]["bucket"], a))
    # Three posed queries of date a, one of date b (as on a download where half the
    # queries have no pose): the agnostic twin sees the one it can, not an error.
    ctx = _tiny_context([a, a, a, b, b], [True, True, True, True, False],
                        [[0], [1], [2], [3], []])
    s = agnostic_row.score(ctx, methods.At(ctx.queries[0]["bucket"], a))
    np.testing.assert_array_equal(np.floor(s), [0, 0, 0, 1])


def test_the_registry_names_every_row_of_a_run_once():
    from experiments.map_summarization import methods

    config, _ = parse(["--size", "tiny"])
    names = methods.methods_of(config)
    assert names == METHODS and len(set(names)) == len(names)
    labels = methods.labels_of(config)
    assert labels["rp"].startswith("RP (recommended: ") and set(labels) == set(names)
    assert methods.oracles_of(config) == ["oracle_agnostic", "oracle_date", "oracle_inliers"]
    # rp (outcome_agnostic_top), outcome_top and rp_cmu_kcover
    assert methods.predictors_needed(config) == ["robotcar", "cmu", "outcome", "outcome_agnostic"]
    with pytest.raises(ValueError, match="already registered"):
        methods.register(methods.ROWS["kcover"])
    with pytest.raises(ValueError, match="per='hourly'"):
        methods.Row("x", "x", "method", "hourly", methods.top_per_part)


def _metrics_for_report():
    """A hand-made metrics dict: rp above K-cover at 80 and 90 % at (5 m, 10 deg), its
    intervals entirely above zero there, K-cover 40 % and rp 76 % of a 95 % full map."""
    ratios, ths = ["0.5", "0.9"], THRESHOLDS
    acc = {"rp": {"0.5": 90.0, "0.9": 76.0}, "kcover": {"0.5": 89.0, "0.9": 40.0}}
    ivl = {"rp": {"0.5": [-1.0, 3.0], "0.9": [20.0, 50.0]}, "kcover": {"0.5": [0, 0],
                                                                      "0.9": [0, 0]}}
    return {
        "ratios": ratios, "thresholds": list(ths), "methods": ["rp", "kcover"],
        "reference": "kcover", "recommended": "rp", "queries": 40, "seeds": [0],
        "labels": {"rp": "RP (recommended)", "kcover": "K-cover"},
        "accuracy": {m: {r: {t: acc[m][r] for t in ths} for r in ratios} for m in acc},
        "interval": {m: {r: {t: [acc[m][r] - 5, acc[m][r] + 5] for t in ths} for r in ratios}
                     for m in acc},
        "paired": {m: {r: {t: {"only_method": 3, "only_kcover": 1, "p": 0.6} for t in ths}
                       for r in ratios} for m in acc},
        "paired_interval": {m: {r: {t: ivl[m][r] for t in ths} for r in ratios} for m in acc},
        "full_map_accuracy": {t: 95.0 for t in ths},
        "inlier_auc": {"rp": 0.7, "kcover": None},
        "selecting_auc": {"rp": 0.81, "kcover": 0.6},
    }


def test_tables_markdown_and_the_bar_from_a_metrics_dict():
    from experiments.map_summarization import report

    metrics = _metrics_for_report()
    text = report.tables_markdown(metrics)
    assert "Primary comparison: **RP (recommended)** (`rp`)" in text
    assert "| 5m_10deg | +1.0 [-1.0, +3.0] | +36.0 [+20.0, +50.0] |" in text
    assert "| RP (recommended) | 90.0 [85.0, 95.0] | 76.0* [71.0, 81.0] |" in text
    assert "| RP (recommended) | 0.700 | 0.810 |" in text
    bar = report.bar_check(metrics)
    # Above at one ratio per threshold only, and 76 of 95 % = 80 %: the second part fails.
    assert bar[0] == "- The bar (NOT met):"
    assert "above K-cover at two or more ratios at one threshold: no" in bar[2]
    assert "76.0 of 95.0 % = 80 %" in bar[3] and bar[3].startswith("  - keeps >= 80 %")
    assert ": yes" in bar[1] and ": yes" in bar[4]
    metrics["paired_interval"]["rp"]["0.5"]["5m_10deg"] = [0.5, 3.0]
    assert report.bar_check(metrics)[0] == "- The bar (met):"
    metrics["paired_interval"]["rp"]["0.5"]["0.5m_5deg"] = [-4.0, -0.5]
    assert "below at 0.5 0.5m_5deg" in report.bar_check(metrics)[1]
    # A run that also counted its own ratios shows both selecting AUCs; the bar reads the grid's.
    metrics["selecting_auc_run_ratios"] = {"rp": 0.75, "kcover": 0.55}
    text = report.tables_markdown(metrics)
    assert "| RP (recommended) | 0.700 | 0.810 | 0.750 |" in text
    assert "ratios 5 %, 10 %, ..., 95 % a point is kept at" in text
    assert "selecting inlier AUC >= 0.8: yes (0.810)" in report.bar_check(metrics)[4]


def test_the_selecting_rank_reads_a_top_per_part_rule_over_the_whole_grid():
    """Twenty points in one part scored 19, 18, ..., 0: over the grid 5 %...95 % pruned the
    point of rank k is kept at the ratios whose keep count exceeds k, so the selecting rank
    of points 0..18 is 19..1 and point 19 (kept at none) 0; over the run's ratios 50 % and
    90 % alone the bottom half is one tie. The AUC reads what the rank says: with points 0
    and 12 the inliers, the grid rank separates 12 from the points below it."""
    from experiments.map_summarization import methods, world

    n = 20
    a = dt.date(2010, 9, 1)
    ctx = _tiny_context([a], [True], [[]], n_points=n)
    row = methods.Row("by_score", "by score", "method", "world", methods.top_per_part,
                      score=lambda ctx, at: np.arange(n, 0, -1, dtype=float))
    units = [(methods.At(ctx.queries[0]["bucket"], a), [0])]
    candidates = [np.arange(n)]
    grid = world.selecting_rank(ctx, row, units, world.SELECTING_GRID, candidates)[0]
    assert world.SELECTING_GRID[0] == 0.05 and world.SELECTING_GRID[-1] == 0.95
    np.testing.assert_array_equal(grid, [*range(19, 0, -1), 0])
    run = world.selecting_rank(ctx, row, units, [0.5, 0.9], candidates)[0]
    np.testing.assert_array_equal(run, [2, 2] + [1] * 8 + [0] * 10)
    # Counts made at the run's ratios carry over: the rest of the grid adds the same rank.
    rest = [r for r in world.SELECTING_GRID if r not in (0.5, 0.9)]
    np.testing.assert_array_equal(
        world.selecting_rank(ctx, row, units, rest, candidates, start=[run])[0], grid)
    labels = np.zeros(n, bool)
    labels[[0, 12]] = True
    full = world.FullMap([], [], {}, candidates + [None], [labels, None])
    aucs = world.selecting_aucs(full, {"grid": [grid, None], "run": [run, None]})
    # Grid: point 0 outranks all 18 negatives, point 12 the 7 below it. Run: point 0 ties
    # point 1 (0.5) and outranks the 17 below, point 12 ties the 9 others of the bottom
    # half (4.5).
    assert aucs["grid"] == pytest.approx((18 + 7) / 36)
    assert aucs["run"] == pytest.approx((17.5 + 4.5) / 36)
    # A query without candidates (not localized by the full map) is skipped, not scored.
    assert world.selecting_rank(ctx, row, units, world.SELECTING_GRID, [None]) == [None]


def test_the_spread_of_two_runs_of_one_command():
    """Two runs differing in rp at 90 % (76 -> 79) and K-cover at 50 % (89 -> 88.5), the
    full map 95 -> 94: each cell and the primary comparison in each run, by hand."""
    from experiments.map_summarization import report

    earlier, later = _metrics_for_report(), _metrics_for_report()
    for th in THRESHOLDS:
        later["accuracy"]["rp"]["0.9"][th] = 79.0
        later["accuracy"]["kcover"]["0.5"][th] = 88.5
        later["full_map_accuracy"][th] = 94.0
    text = report.spread_markdown(earlier, later)
    assert "| RP (recommended) | 90.0 -> 90.0 (+0.0) | 76.0 -> 79.0 (+3.0) |" in text
    assert "| K-cover | 89.0 -> 88.5 (-0.5) | 40.0 -> 40.0 (+0.0) |" in text
    assert "- Full map: 0.5m_5deg 95.0 -> 94.0 (-1.0); 5m_10deg 95.0 -> 94.0 (-1.0)." in text
    assert ("- Primary comparison (rp minus kcover) at 5m_10deg: 50 % +1.0 -> +1.5; "
            "90 % +36.0 -> +39.0.") in text
    # 8 cells (2 rows x 2 ratios x 2 thresholds): 3.0 twice, 0.5 twice, 0 four times.
    assert ("Largest change +3.0 points (RP (recommended), 90 %, 5m_10deg); median absolute "
            "change 0.2 points over 8 cells.") in text
