"""The map-summarization experiment (Sec. V, IV-B, Fig. 11) and its pieces."""

import datetime as dt
import json

import cv2
import numpy as np
import pycolmap
import pytest

from experiments.map_summarization.__main__ import DEFAULT_SIZE, main, parse
from rp_jax.localize import read_submission
from rp_jax.mapsum import MapPoints, keep_counts_per_part, partition, read_model
from rp_jax.mapsum import experiment as mexp

METHODS = {"rp", "kcover", "random", "most_observed", "rp_kcover"}  # the paper's four + one
RATIOS = ("0.2", "0.5", "0.9")


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """The whole experiment at tiny size, from its command line (1 epoch, 3 ratios)."""
    tmp = tmp_path_factory.mktemp("mapsum")
    workdir = tmp / "run"
    argv = [
        "--size",
        "tiny",
        "--workdir",
        str(workdir),
        "--tfds-dir",
        str(tmp / "tfds"),
        "--config.num_epochs=1",
        f"--config.map.ratios=({','.join(RATIOS)})",
    ]
    assert main(argv) == 0
    return workdir, json.loads((workdir / "metrics.json").read_text())


@pytest.mark.slow
def test_metrics_file_shape_and_values(tiny_run):
    _, metrics = tiny_run
    acc = metrics["accuracy"]
    assert set(acc) == METHODS
    n = metrics["num_queries"]
    assert n == 8  # tiny: 4 positions x 2 cameras on the query date
    for method, per_ratio in acc.items():
        assert tuple(per_ratio) == RATIOS
        for ratio, per_threshold in per_ratio.items():
            assert tuple(per_threshold) == mexp.THRESHOLD_KEYS
            values = [per_threshold[k] for k in mexp.THRESHOLD_KEYS]
            assert all(0.0 <= v <= 100.0 for v in values)
            # The thresholds are nested, so accuracy cannot drop as they loosen.
            assert values[0] <= values[1] <= values[2]
            # A percentage of n queries, consistent with the localized count.
            assert abs(values[2] * n / 100 - round(values[2] * n / 100)) < 1e-6
            assert metrics["num_localized"][method][ratio] >= round(values[2] * n / 100)
    sizes = metrics["map_sizes"]
    assert sizes["full"] == metrics["map"]["points"] > 0
    assert sizes["full"] > sizes["0.2"] > sizes["0.5"] > sizes["0.9"] > 0
    assert metrics["full_map_accuracy"]["5m_10deg"] > 0, "the unpruned map localizes nothing"
    assert metrics["map"]["descriptor_association_rate"] > 0.95  # the stored image's own keypoints
    assert (
        set(metrics["rp"]["schedule"]["labels"]) and len(metrics["rp"]["schedule"]["labels"]) == 9
    )
    assert metrics["queries"]["dates"] == ["2010-09-01"]
    assert {"rp_dataset_and_training_s", "map_s", "localization_s"} <= set(metrics["timings"])
    auc = metrics["diagnostics"]["inlier_auc"]["rp"]
    assert auc is None or 0.0 <= auc <= 1.0


@pytest.mark.slow
def test_outputs_written(tiny_run):
    workdir, metrics = tiny_run
    for name in metrics["figures"]:
        img = cv2.imread(str(workdir / name))
        assert img is not None and img.shape[0] > 200 and img.std() > 10, name
    assert "fig11_accuracy_vs_pruning.png" in metrics["figures"]
    report = (workdir / "report.md").read_text()
    assert "| RP (ours) |" in report and "| K-cover (minimal scene) |" in report
    assert "## What this run shows" in report
    for method in METHODS:
        for ratio in RATIOS:
            poses = read_submission(workdir / "submissions" / f"{method}_{ratio}.txt")
            assert len(poses) == metrics["num_localized"][method][ratio]
    summary = read_model(workdir / "summaries" / "rp_0.5")
    assert summary.num_points3D() == metrics["map_sizes"]["0.5"]


def test_default_size_and_overrides():
    config, workdir = parse(["--config.map.cell_size_m=5"])
    assert (
        config.map.synthetic_size == DEFAULT_SIZE
        and config.data_config == f"synthetic_{DEFAULT_SIZE}"
    )
    assert config.map.cell_size_m == 5.0 and str(workdir).endswith(
        f"map_summarization_{DEFAULT_SIZE}"
    )
    assert config.dataset == "robotcar" and config.schedule == "robotcar"
    assert config.map.query_dates == ("2011-03-04",)  # the paper's query date
    config, _ = parse(["--size", "tiny"])
    assert config.data_config == "synthetic_tiny"


def test_rp_config_drops_map_fields(tmp_path):
    config, _ = parse(["--size", "tiny", "--data-dir", str(tmp_path)])
    cfg = mexp._rp_config(config)
    assert "map" not in cfg and "map" in config
    assert cfg.manual_dir == str(tmp_path.absolute() / "robotcar")


def test_point_categories_majority():
    mp = MapPoints(
        np.zeros((3, 3)),
        [1, 2, 3],
        [0, 0, 0, 1, 1],
        [1, 2, 3, 1, 2],
        [0, 0, 0, 1, 1],
        np.zeros((5, 2)),
    )
    cats = mexp.point_categories(mp, np.array([2, 2, 0, -1, -1]))
    np.testing.assert_array_equal(cats, [2, -1, -1])


def test_query_scores_interpolate_the_cycle():
    from rp_jax.schedule import preset

    sched = preset("robotcar")  # 9:00 ... 17:00 hourly
    rep = np.tile(np.arange(9, dtype=float), (2, 1))
    when = dt.datetime(2011, 3, 4, 10, 30)
    np.testing.assert_allclose(mexp.query_scores(rep, sched, when), [1.5, 1.5])


def test_bucket_and_auc():
    t = dt.datetime(2011, 3, 4, 10, 17, 42)
    assert mexp._bucket(t, 10) == dt.datetime(2011, 3, 4, 10, 10)
    assert mexp._auc(np.array([0.1, 0.2, 0.9, 0.8]), np.array([False, False, True, True])) == 1.0
    assert mexp._auc(np.array([1.0, 1.0]), np.array([True, False])) == 0.5
    assert mexp._auc(np.array([1.0, 2.0]), np.array([True, True])) is None


def test_opencv_camera_shifts_principal_point():
    cam = pycolmap.Camera(
        model="OPENCV",
        width=100,
        height=80,
        params=[90.0, 91.0, 50.5, 40.5, -0.3, 0.1, 0.001, 0.002],
    )
    K, dist, w, h = mexp._opencv_camera(cam)
    np.testing.assert_allclose(K, [[90, 0, 50], [0, 91, 40], [0, 0, 1]])
    np.testing.assert_allclose(dist, [-0.3, 0.1, 0.001, 0.002])
    assert (w, h) == (100, 80)


def test_same_points_kept_per_part_by_every_method():
    rng = np.random.default_rng(0)
    xyz = rng.uniform(0, 30, (60, 3))
    obs_point = np.repeat(np.arange(60), 3)
    mp = MapPoints(
        xyz,
        np.arange(60) + 1,
        obs_point,
        rng.integers(1, 6, 180),
        np.arange(180),
        rng.uniform(0, 50, (180, 2)),
    )
    parts = partition(xyz, "grid", cell_size=10.0)
    want = keep_counts_per_part(parts, 0.6)
    from rp_jax.mapsum import summarize

    for method, lib in mexp.METHODS.items():
        kwargs = {"repeatability": rng.uniform(size=60)} if method == "rp" else {}
        if method == "rp_kcover":
            kwargs = {"weights": rng.uniform(0.1, 1.0, size=60)}
        keep = summarize(lib, mp, 0.6, parts, **kwargs)
        np.testing.assert_array_equal(np.bincount(parts[keep], minlength=len(want)), want)


def test_plot_accuracy_vs_pruning(tmp_path):
    acc = {
        m: {r: {k: 10.0 * i for k in mexp.THRESHOLD_KEYS} for i, r in enumerate(RATIOS)}
        for m in METHODS
    }
    full = {k: 80.0 for k in mexp.THRESHOLD_KEYS}
    path = mexp.plot_accuracy_vs_pruning(
        acc, tmp_path / "f.png", full_map=full, thresholds=mexp.THRESHOLD_KEYS
    )
    img = cv2.imread(str(path))
    assert img is not None and img.shape[1] > 2 * img.shape[0]  # three panels side by side


def test_ensure_layout_rejects_a_date_without_queries(tmp_path):
    with pytest.raises(ValueError, match="query dates are"):
        mexp.ensure_cmu_map_layout(
            tmp_path,
            size="tiny",
            seed=0,
            slice_id=8,
            query_dates=[dt.date(2011, 3, 4)],
            progress=False,
        )


def test_ensure_layout_renders_an_older_world_again(tmp_path, monkeypatch):
    from rp_jax.sources.synthetic import presets

    root = tmp_path / "cmu"
    (root / presets.SYNTHETIC_DIR).mkdir(parents=True)
    (root / "stale.jpg").write_bytes(b"old pixels")
    old = {"size": "tiny", "seed": 0, "slice": 8, "query_dates": ["2011-03-04"]}  # world 1
    (root / presets.SYNTHETIC_DIR / "map_subset.json").write_text(json.dumps(old))
    rendered = []

    def fake_run_jobs(jobs, **kwargs):
        rendered.append((len(jobs), (root / "stale.jpg").exists()))
        raise RuntimeError("stop after the render call")

    monkeypatch.setattr(presets, "run_jobs", fake_run_jobs)
    with pytest.raises((RuntimeError, ValueError)):
        mexp.ensure_cmu_map_layout(root, size="tiny", seed=0, slice_id=8,
                                   query_dates=[dt.date(2011, 3, 4)], progress=False)
    assert not (root / "stale.jpg").exists()  # the version-1 frames are gone
    assert all(not stale for _, stale in rendered)
