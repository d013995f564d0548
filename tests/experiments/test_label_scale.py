"""The ``label_scale`` benchmark stage (a Webcam-like viewpoint of many frames labelled as a
build labels it, Sec. IV-A-1): its viewpoints, its fit, its report at tiny size, and its
table in the user documentation.

No timing thresholds: the figures are whatever a shared machine gives; the tests check the
viewpoints the stage builds and the report's structure.
"""

from __future__ import annotations

import datetime as dt
import json

import numpy as np
import pytest

from experiments.benchmark import label_scale_stage, report
from experiments.benchmark.label_scale_stage import NUM_DAYS, fit, viewpoint_days
from experiments.benchmark.run import run_benchmark


def test_smaller_viewpoints_are_spread_subsets_of_larger_ones():
    d1k, d3k, d10k = (viewpoint_days(n) for n in (1_000, 3_000, 10_000))
    assert (len(d1k), len(d3k), len(d10k)) == (48, 143, 477)
    assert set(d1k) <= set(d3k) <= set(d10k) == set(range(NUM_DAYS))
    # The 48 days of 1,000 frames cover the 477 (every season), no gap over 3 even steps.
    assert d1k[0] < 477 / 48 and d1k[-1] > 477 - 477 / 48
    assert np.diff(d1k).max() < 3 * 477 / 48
    with pytest.raises(ValueError, match="num_frames"):
        viewpoint_days(NUM_DAYS * 21 + 1)


def test_the_viewpoint_is_the_webcam_presets_scene_as_it_renders_it(tmp_path):
    from rp_jax.sources.synthetic import presets

    whole = label_scale_stage._plan(tmp_path / "b", "tiny").jobs  # all 477 days
    ours = {j.scene for j in whole}
    preset = presets.plan("webcam_clipart", tmp_path / "p", size="full", seed=0)
    scene = preset.jobs[0].scene  # scene_00 (in its city's own climate)
    assert ours == {scene} and dict(scene.extra).get("climate") == "local"
    # A size's frames, planned alone (its days only), are those of the whole viewpoint.
    days = {label_scale_stage.FIRST_DAY + dt.timedelta(days=d)
            for d in viewpoint_days(42)}
    want = sorted((j for j in whole if j.when.date() in days), key=lambda j: j.when)[:42]
    got = label_scale_stage._jobs_of(tmp_path / "b", "tiny", 42)
    assert [(j.image_path, j.when, j.frame_seed) for j in got] == [
        (j.image_path, j.when, j.frame_seed) for j in want]
    np.testing.assert_array_equal(np.stack([j.R for j in got]), np.stack([j.R for j in want]))


def test_fit_of_cost_against_frames():
    rows = [{"frames": n, "cpu_s": 5.0 + 0.5 * n, "wall_s": 1.0 + 0.25 * n}
            for n in (1_000, 3_000, 10_000)]
    out = fit(rows)
    assert out["linear_fit_cpu"]["b"] == pytest.approx(0.5)
    assert out["linear_fit_cpu"]["a"] == pytest.approx(5.0)
    assert out["log_log_exponent_cpu"] == pytest.approx(1.0, abs=0.01)
    assert out["cpu_per_frame_spread"] == pytest.approx(0.505 / 0.5005 - 1, rel=1e-6)
    quadratic = fit([{"frames": n, "cpu_s": n * n / 1e3, "wall_s": 1.0} for n in (100, 1000)])
    assert quadratic["log_log_exponent_cpu"] == pytest.approx(2.0)
    assert "linear_fit_cpu" not in fit(rows[:1])


@pytest.mark.slow
def test_tiny_stage_renders_once_labels_and_keeps_earlier_sizes(tmp_path):
    js, md = run_benchmark(["label_scale"], tmp_path, size="tiny", progress=False,
                           label_scale_frames=(21,))
    first = json.loads(js.read_text())["label_scale"]
    (row,) = first["label_scale"]
    assert row["frames"] == 21 and row["sources"] == 21  # one day: every image a source
    assert row["records"] > 21 * 50 and row["peak_rss_mb"] > 0 and row["cpu_s"] > 0
    assert not row["resumed"]
    assert first["renders"][0]["rendered"] == 21

    js, md = run_benchmark(["label_scale"], tmp_path, size="tiny", progress=False,
                           label_scale_frames=(42,))
    second = json.loads(js.read_text())["label_scale"]
    assert [r["frames"] for r in second["label_scale"]] == [21, 42]
    assert second["label_scale"][0] == row  # the earlier size is kept as measured
    assert second["renders"][1]["rendered"] == 21  # the first day was on disk already
    assert "linear_fit_cpu" in second
    text = md.read_text()
    assert "## label_scale" in text and "| 42 |" in text
    assert not list(tmp_path.glob("label_scale/tiny/cache_*"))  # removed once measured


def test_the_docs_table_has_each_size_its_machine_and_the_per_frame_spread():
    rows = [{"frames": n, "cpu_s": c, "wall_s": 2 * c, "peak_rss_mb": 480.0 + n / 1000,
             "records": 10_000, "load_average_1min": 1.5, "measured_at": "2030-01-01T10:00:00",
             "cpu_model": "AMD EPYC"} for n, c in ((1000, 200.0), (10000, 2500.0))]
    text = report.docs_label_scale({"label_scale": {"label_scale": rows,
                                                          "ours": {"variant": "84 sources"}}})
    row = "| 1,000 | 200 | 0.200 | 481 | 10,000 | 400 | 1.5 | 2030-01-01 10:00:00 UTC, AMD EPYC |"
    assert row in text
    assert "| 10,000 | 2,500 | 0.250 |" in text
    assert "from 0.200 to 0.250 (+25% from the cheapest)" in text and "at most 490 MB" in text
    assert "No `label_scale` result" in report.docs_label_scale({})
    assert "Rendering the frames" not in text  # no render recorded
    renders = [{"frames": 1000, "rendered": 1000, "seconds": 60.0, "cpu_s": 100.0},
               {"frames": 3000, "rendered": 0, "seconds": 0.01, "cpu_s": 0.01},
               {"frames": 10000, "rendered": 7000, "seconds": 340.0, "cpu_s": 700.0}]
    text = report.docs_label_scale({"label_scale": {
        "label_scale": rows, "renders": renders, "cpu_count": 2, "cpu_model": "AMD EPYC"}})
    assert ("8,000 frames in 400 s of wall time and 800 s of CPU (0.100 s of CPU a frame) "
            "on 2 cores, AMD EPYC.") in text
