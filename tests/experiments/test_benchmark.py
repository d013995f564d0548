"""Tests of the benchmark harness (experiments/benchmark): the PyTorch peer is the same
network as ours (Sec. III-B), the statistics, and the report's shape at tiny size.

No timing thresholds: speeds on a shared machine are whatever they are; only the structure
of the report and the equality of the two implementations are checked.

PyTorch is the optional ``bench`` extra (not installed in CI): the tests that run the
PyTorch peer are skipped without it, the rest of the harness is tested everywhere.
"""

from __future__ import annotations

import importlib.util
import json
import mmap

import numpy as np
import pytest

from experiments.benchmark.__main__ import main
from experiments.benchmark.config import SIZES
from experiments.benchmark.match_stage import synthetic_descriptors
from experiments.benchmark.model_benches import check_torch_equals_jax
from experiments.benchmark.run import run_benchmark
from experiments.benchmark.stats import cpu_peak, pairwise_ratio, summarize_samples

HAVE_TORCH = importlib.util.find_spec("torch") is not None
if HAVE_TORCH:
    import torch

    from experiments.benchmark import torch_reference as tr

needs_torch = pytest.mark.skipif(not HAVE_TORCH,
                                 reason="needs torch (the bench extra: pip install -e .[bench])")


@needs_torch
def test_torch_reference_equals_ours():
    check = check_torch_equals_jax(SIZES["tiny"], num_points=8, seed=1)
    assert check["output_max_abs_diff"] <= 1e-5
    assert check["feature_max_abs_diff"] <= 1e-5 * max(1.0, check["feature_scale"])
    assert check["feature_scale"] > 1e-3  # the encoder features are not all zero
    assert check["time_encoding_max_abs_diff"] <= 1e-6
    assert check["loss_abs_diff"] <= 1e-5
    assert check["grad_max_rel_diff"] <= 1e-4


@needs_torch
def test_layout_mistakes_are_detected():
    """A wrong kernel layout or PyTorch's symmetric padding changes the features: the equality
    check above can fail."""
    import jax

    from rp_jax import model as model_lib
    from rp_jax.configs import default
    from rp_jax.train import create_train_state

    params = create_train_state(default.get_config(), 5, 1, jax.random.key(0)).params
    x = np.random.default_rng(0).uniform(-0.5, 0.5, (4, 64, 64, 3)).astype(np.float32)
    ours = np.asarray(model_lib.PatchEncoder().apply({"params": params["patch_encoder"]}, x))
    good = tr.load_flax_params(tr.TorchRepeatabilityPredictor(5), params)
    with torch.no_grad():
        np.testing.assert_allclose(good.encode(torch.from_numpy(x)).numpy(), ours, atol=1e-5)
        wrong_kernel = tr.load_flax_params(tr.TorchRepeatabilityPredictor(5), params)
        wrong_kernel.conv1.weight.copy_(
            wrong_kernel.conv1.weight.transpose(2, 3).clone()
        )  # H and W swapped
        assert np.abs(wrong_kernel.encode(torch.from_numpy(x)).numpy() - ours).max() > 1e-3
        symmetric = tr.load_flax_params(tr.TorchRepeatabilityPredictor(5), params)
        symmetric.conv2.padding = (1, 1)
        feats = torch.nn.functional.relu(
            symmetric.conv1(tr.space_to_depth_nhwc(torch.from_numpy(x), 4).permute(0, 3, 1, 2))
        )
        sym = symmetric.conv2(feats)[:, :, :8, :8]
        same = good.conv2(torch.nn.functional.pad(feats, (0, 1, 0, 1)))
        assert (sym - same).abs().max() > 1e-3


@needs_torch
def test_load_flax_params_rejects_other_sizes():
    import jax

    from rp_jax.configs import default
    from rp_jax.train import create_train_state

    params = create_train_state(default.get_config(), 5, 1, jax.random.key(0)).params
    with pytest.raises(ValueError, match="fc6"):
        tr.load_flax_params(tr.TorchRepeatabilityPredictor(7), params)


def test_statistics_and_pairwise_ratio():
    s = summarize_samples([3.0, 1.0, 2.0])
    assert (s["median"], s["min"], s["max"]) == (2.0, 1.0, 3.0)
    # Pair by pair: round 1 is 2x, round 2 is 4x, round 3 is 1x -> median 2x (not 8/4).
    assert pairwise_ratio([2.0, 8.0, 1.0], [1.0, 2.0, 1.0]) == 2.0
    with pytest.raises(ValueError):
        pairwise_ratio([1.0, 2.0], [1.0])


def test_cpu_peak_from_cpuinfo():
    info = (
        "processor\t: 0\nmodel name\t: Test Xeon\ncpu MHz\t\t: 2000.000\n"
        "flags\t\t: fpu sse avx2 fma avx512f amx_bf16\n"
    )
    peak = cpu_peak(info, num_cores=2)
    assert peak["isa"] == "AVX-512" and peak["amx_bf16"]
    assert peak["fp32_peak_flops"] == pytest.approx(2 * 2 * 16 * 2 * 2.0e9)
    avx2 = cpu_peak(info.replace(" avx512f", ""), num_cores=4)
    assert avx2["fp32_peak_flops"] == pytest.approx(4 * 2 * 8 * 2 * 2.0e9)


def test_synthetic_descriptors_are_exact_sift_like():
    descs = synthetic_descriptors(3, 50, seed=2)
    assert len(descs) == 3 and all(d.shape == (50, 128) and d.dtype == np.float32 for d in descs)
    for d in descs:
        np.testing.assert_array_equal(d, np.round(d))
        assert d.min() >= 0 and d.max() <= 255


def test_cli_rejects_unknown_stage(tmp_path):
    with pytest.raises(SystemExit):
        main(["nonsense", "--out", str(tmp_path)])


@pytest.fixture(scope="module")
def tiny_report(tmp_path_factory):
    """One tiny run of every stage; the model stages with one JAX variant and the PyTorch
    peer, to keep the test short (the full run measures all variants)."""
    out = tmp_path_factory.mktemp("bench")
    variants = {"train": ["jax_1dev", "torch_eager"], "predict": ["jax_2dev_ynn", "torch_eager"]}
    js, md = run_benchmark(
        ["train", "predict", "match", "groundtruth"],
        out,
        size="tiny",
        repeats=2,
        progress=False,
        model_variants=variants,
    )
    return json.loads(js.read_text()), md.read_text(), out


@pytest.mark.slow
@needs_torch
def test_report_shape(tiny_report):
    results, md, _ = tiny_report
    assert list(results) == ["train", "predict", "match", "groundtruth"]
    for stage in ("train", "predict", "match"):
        e = results[stage]
        assert e["unit"] and e["ratio"] > 0
        for side in ("ours", "peer"):
            assert e[side]["min"] <= e[side]["median"] <= e[side]["max"]
            assert len(e[side]["samples"]) == 2
        # The top-level ratio is the pairwise median of the two sides' samples.
        assert e["ratio"] == pytest.approx(
            pairwise_ratio(e["ours"]["samples"], e["peer"]["samples"])
        )
    for stage in ("train", "predict"):
        e = results[stage]
        assert e["ours"]["flops_per_sample"] > 1e6  # tens of MFLOP per interest point
        assert 0 < e["ours"]["fraction_of_fp32_peak"]
        assert e["peer"]["equality"]["output_max_abs_diff"] <= 1e-5
        assert e["ours"]["best_variant"] in e["ours"]["variants"]
    assert (
        results["train"]["ours"]["flops_per_sample"]
        > results["predict"]["ours"]["flops_per_sample"]
    )
    assert results["match"]["identical"] is True
    gt = results["groundtruth"]
    assert gt["peer"] is None and gt["ratio"] is None
    assert list(gt["ours"]["per_num_images"]) == [str(n) for n in SIZES["tiny"]["gt_images"]]
    for v in gt["ours"]["per_num_images"].values():
        assert v["seconds"]["median"] > 0 and v["peak_rss_mb"] > 0 and v["interest_points"] > 0
    assert set(gt["quadratic_fit"]) >= {"a", "b", "c"}
    for heading in (
        "## train",
        "## predict",
        "## match",
        "## groundtruth",
        "| variant | median | min | max",
    ):
        assert heading in md


@pytest.mark.slow
@needs_torch
def test_rerun_of_one_stage_keeps_the_others(tiny_report):
    results, _, out = tiny_report
    run_benchmark(["match"], out, size="tiny", repeats=1, progress=False)
    again = json.loads((out / "benchmark.json").read_text())
    assert list(again) == list(results)
    assert again["train"] == results["train"]
    assert len(again["match"]["ours"]["samples"]) == 1


def test_synthetic_street_map_is_a_valid_map_for_both_methods():
    from experiments.benchmark import summarize_stage
    from rp_jax.mapsum import kcover_keep, keep_count, partition, repeatability_keep

    mp, rep = summarize_stage.synthetic_street_map(3000, num_timestamps=6, seed=3)
    assert mp.num_points == 3000 and rep.shape == (3000, 6) and rep.dtype == np.float32
    assert 0 <= rep.min() and rep.max() <= 1
    lengths = mp.track_length
    assert lengths.min() >= 2 and lengths.max() <= 5
    # Each track is distinct consecutive database images (ids 1..n_images).
    for i in (0, 1234, 2999):
        images, _ = mp.track(i)
        assert np.all(np.diff(images) == 1) and images.min() >= 1
        assert images.max() <= len(mp.image_names)
    parts = partition(mp.xyz, "grid", cell_size=10.0)
    ours = repeatability_keep(mp, 0.5, parts, repeatability=rep, timestamp=2)
    kcover = kcover_keep(mp, 0.5, parts)
    for p in range(parts.max() + 1):
        n = keep_count((parts == p).sum(), 0.5)
        assert ours[parts == p].sum() == kcover[parts == p].sum() == n


def _touch_fresh_pages(num_mb: int) -> None:
    """Make ``num_mb`` MB resident and release them. Fresh anonymous pages, not malloc's: in a
    long process (the whole test suite) malloc serves even 16 MB from freed, still-resident
    heap memory, which would raise no peak at all."""
    buf = mmap.mmap(-1, num_mb * 2**20)
    view = np.frombuffer(buf, np.uint8)
    view[::4096] = 1  # one write per page
    del view
    buf.close()


def test_memory_probe_sees_an_allocation_after_a_larger_one():
    from experiments.benchmark import summarize_stage

    _touch_fresh_pages(64)  # a 64 MB peak before the probe
    with summarize_stage.memory_probe() as mem:
        _touch_fresh_pages(16)
    assert mem.peak_mb > 0
    if mem.method.startswith("VmHWM"):
        assert 8 <= mem.extra_mb <= 48, mem.extra_mb  # its own 16 MB, not the earlier 64 MB


@pytest.fixture(scope="module")
def tiny_sum_loc_report(tmp_path_factory):
    """One tiny run of the map summarization and localization stages (Sec. V)."""
    out = tmp_path_factory.mktemp("bench_sumloc")
    js, md = run_benchmark(["summarize", "localize"], out, size="tiny", repeats=2, progress=False)
    return json.loads(js.read_text()), md.read_text()


@pytest.mark.slow
def test_summarize_report_shape(tiny_sum_loc_report):
    results, md = tiny_sum_loc_report
    assert list(results) == ["summarize", "localize"]
    e = results["summarize"]
    assert e["unit"] == "s" and e["prediction_cached"] is True and e["ratio"] > 0
    sizes = [str(n) for n in SIZES["tiny"]["sum_points"]]
    assert list(e["ours"]["per_num_points"]) == sizes == list(e["peer"]["per_num_points"])
    assert e["headline_points"] == SIZES["tiny"]["sum_headline_points"]
    for side in ("ours", "peer"):
        assert e[side]["min"] <= e[side]["median"] <= e[side]["max"]
        assert len(e[side]["samples"]) == 2
        for v in e[side]["per_num_points"].values():
            assert 0 < v["seconds"]["min"] <= v["seconds"]["median"] <= v["seconds"]["max"]
            assert v["peak_mb"] > 0 and v["extra_mb"] >= 0
            assert v["partition_seconds"] > 0 and v["select_seconds"] > 0
    # Equal size: both methods keep the same number of points.
    for n in sizes:
        assert e["ours"]["per_num_points"][n]["kept"] == e["peer"]["per_num_points"][n]["kept"]
        assert e["ratio_per_num_points"][n] > 0
        assert e["maps"][n]["points"] == int(n) and e["maps"][n]["observations"] > 2 * int(n)
    # The headline ratio is the pairwise median of the headline size's rounds.
    assert e["ratio"] == pytest.approx(
        pairwise_ratio(
            [1 / s for s in e["ours"]["samples"]], [1 / s for s in e["peer"]["samples"]]
        )
    )
    assert "## summarize" in md and "| points | method | median s" in md
    assert "| summarize | s (10,000 points) |" in md


@pytest.mark.slow
def test_localize_report_shape(tiny_sum_loc_report):
    results, md = tiny_sum_loc_report
    e = results["localize"]
    assert e["unit"] == "ms/query" and e["ratio"] > 0
    for side in ("ours", "peer"):
        assert 0 < e[side]["min"] <= e[side]["median"] <= e[side]["max"]
        assert len(e[side]["samples"]) == 2
        assert set(e[side]["steps"]) == {"retrieval", "matching", "pnp"}
        for s in e[side]["steps"].values():
            assert 0 < s["min"] <= s["median"] <= s["max"]
    assert set(e["step_ratios"]) == {"retrieval", "matching", "pnp"}
    assert all(r > 0 for r in e["step_ratios"].values())
    eq = e["equality"]
    assert eq["localized_ours"] == eq["localized_peer"] == eq["queries"] == e["num_queries"]
    assert eq["matches_agree_fraction"] >= 0.99
    assert eq["pose_max_position_diff_m"] < 0.05 and eq["pose_max_rotation_diff_deg"] < 0.5
    assert "## localize" in md and "| **whole query** |" in md and "PnP-RANSAC" in md
    sm = e["summaries"]  # matching on summaries, on their own and from the query's table
    for side in ("alone", "from_table", "table_ms_per_query"):
        assert 0 < sm[side]["min"] <= sm[side]["median"] <= sm[side]["max"]
        assert len(sm[side]["samples"]) == 2
    assert sm["ratio"] > 0 and sm["ratios"] == [0.5, 0.7, 0.9]
    assert "from the query's table of nearest full-map candidates" in md


def test_summarize_skips_kcover_past_its_budget(monkeypatch):
    """K-cover is not run at a size once the previous size took longer than the budget; the
    report says so with a projected time and never waits for it."""
    from experiments.benchmark import summarize_stage

    size = {**SIZES["tiny"], "sum_points": (100, 1000, 10_000), "kcover_budget_s": 1.0}
    monkeypatch.setitem(SIZES, "fake", size)
    calls = []

    def fake_worker(n, size_name, repeats, run_kcover, timeout_s):
        calls.append((n, run_kcover))
        ours = {"method": "ours", "seconds": 0.01, "partition_s": 0.005, "select_s": 0.005}
        kc = {**ours, "method": "kcover", "seconds": 2.0}
        common = {"kept": n // 2, "peak_mb": 100.0, "extra_mb": 1.0, "memory_method": "test"}
        runs = [{"measure": {**ours, **common}}]
        if run_kcover:
            runs.append({"measure": {**kc, **common}})
        return [{"map": {"points": n, "observations": 3 * n}}] + runs, None

    monkeypatch.setattr(summarize_stage, "_run_summarize_worker", fake_worker)
    e = summarize_stage.run_summarize_stage("fake", 1, progress=False)
    assert calls == [(100, True), (1000, False), (10_000, False)]
    skipped = e["peer"]["per_num_points"]["1000"]
    assert skipped["projected_seconds"] == pytest.approx(20.0)
    assert skipped["status"].startswith("not run: projected 20 s (at 100 points it took 2 s")
    chained = e["peer"]["per_num_points"]["10000"]
    assert chained["projected_seconds"] == pytest.approx(200.0)
    assert "was projected at 20 s" in chained["status"]
    assert e["ratio_per_num_points"] == {"100": pytest.approx(200.0), "1000": None, "10000": None}
    assert e["headline_points"] == 100  # the largest size both ran at
    from experiments.benchmark import report

    md = report.markdown({"summarize": {**e, "size": "fake"}})
    assert "not run: projected 20 s" in md


def test_match_stage_times_both_paths_and_the_scaling(tmp_path):
    """The match stage (no PyTorch needed): the bf16 and float32 paths in the same rounds,
    checked identical first, and the scaling table."""
    js, md = run_benchmark(["match"], tmp_path, size="tiny", repeats=1, progress=False)
    e = json.loads(js.read_text())["match"]
    md = md.read_text()
    assert e["identical"] is True and e["bf16_vs_float32"] > 0
    assert len(e["ours_float32"]["samples"]) == len(e["peer"]["samples"]) == 1
    scaling = e["scaling"]["per_num_images"]
    assert list(scaling) == [str(n) for n in SIZES["tiny"]["match_scaling_images"]]
    for n, row in scaling.items():
        assert row["measured"] == (int(n) <= SIZES["tiny"]["match_scaling_measured_max"])
        for method in ("bf16", "float32"):
            assert row[method]["seconds"] > 0 and row[method]["image_pairs"] > 0
        assert row["bf16"]["output_mb"] == pytest.approx(row["float32"]["output_mb"])
    assert scaling["3"]["bf16"]["peak_rss_mb"] > 0
    assert "Scaling with the images of a viewpoint" in md and "extrapolated" in md



@needs_torch
def test_torch_bf16_autocast_peer_trains_and_predicts():
    """The bfloat16-autocast peer row: the same module and step under torch.autocast; its
    predictions stay within bfloat16 rounding of the float32 ones, and a step updates the
    float32 parameters."""
    import jax

    from rp_jax.configs import default
    from rp_jax.train import create_train_state

    params = create_train_state(default.get_config(), 5, 1, jax.random.key(0)).params
    module = tr.load_flax_params(tr.TorchRepeatabilityPredictor(5, 2), params)
    rng = np.random.default_rng(0)
    batch = {
        "patch": torch.from_numpy(rng.integers(0, 256, (4, 64, 64, 3), dtype=np.uint8)),
        "xy_normalized": torch.rand(4, 2),
        "hour": torch.tensor([0, 6, 12, 18]),
        "minute": torch.tensor([0, 15, 30, 45]),
        "label": torch.rand(4, 5),
        "label_mask": torch.ones(4, 5, dtype=torch.bool),
        "mask": torch.ones(4, dtype=torch.bool),
    }
    inputs = (tr.preprocess_patches(batch["patch"]), batch["xy_normalized"],
              tr.encode_time_of_day(batch["hour"], batch["minute"]))
    with torch.no_grad():
        fp32 = module(*inputs)
        with tr.autocast_context(True):
            bf16 = module(*inputs).float()
    assert float((fp32 - bf16).abs().max()) < 2e-2
    before = module.fc6.weight.detach().clone()
    loss = tr.train_step(module, tr.make_optimizer(module, 1e-2, 0.0), batch, autocast=True)
    assert np.isfinite(float(loss)) and module.fc6.weight.dtype == torch.float32
    assert not torch.equal(before, module.fc6.weight)


@needs_torch
def test_layer_profile_benches_and_table():
    """Both sides of the per-layer profile build the same layer and time it (in this process
    here; the command runs each in its worker); the table has one row per (layer, pass)."""
    from experiments.benchmark import layer_profile
    from experiments.benchmark.config import VARIANTS

    for name in ("jax_2dev_ynn_image", "torch_eager"):
        bench = layer_profile.LayerBench(VARIANTS[name], SIZES["tiny"], inner=1,
                                         layers=["conv2"])
        assert bench.setup()["keys"] == ["conv2|fwd", "conv2|fwd+bwd"]
        assert bench.measure("conv2|fwd+bwd")["seconds"] > 0
    rows = [{"layer": "conv2", "pass": p, "description": "d", "jax_ms": 1.0, "torch_ms": 2.0,
             "jax_gflops": 3.0, "torch_gflops": 1.5, "ratio": 2.0} for p in ("fwd", "fwd+bwd")]
    table = layer_profile.format_table(rows, 16, 1)
    assert table.count("\n| conv2 |") == 2 and "JAX / PyTorch" in table
    from experiments.benchmark import report

    md = report.markdown({"layers": {"unit": "ms per batch", "batch": 16, "repeats": 1,
                                     "jax_variant": "j", "torch_variant": "t", "rows": rows}})
    assert "## layers" in md and table in md


def test_tune_malloc_in_a_fresh_process():
    """configure_cpu's allocator setting applies (glibc) and leaves results unchanged; in a
    subprocess started with glibc's defaults (without the suite's GLIBC_TUNABLES)."""
    import os
    import platform as host
    import subprocess
    import sys

    code = ("import numpy as np; from rp_jax import platform; "
            "a = np.arange(50_000_000, dtype=np.float32).sum(); ok = platform.tune_malloc(); "
            "b = np.arange(50_000_000, dtype=np.float32).sum(); print(ok, a == b)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env={**{k: v for k, v in os.environ.items()
                                             if k != "GLIBC_TUNABLES"}, "JAX_PLATFORMS": "cpu"})
    assert out.stdout.split() == [str(host.libc_ver()[0] == "glibc"), "True"]
