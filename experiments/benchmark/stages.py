"""What the benchmark measures, one stage at a time (the predictor of Sec. III-B/C, III-D).

Stages and their peers:

* ``train``: samples/s of one optimisation step of the repeatability predictor (masked MSE
  of Sec. III-C, global-norm clipping, AdamW), ours (``rp_jax.train``) against the same
  network in PyTorch (``torch_reference``).
* ``predict``: samples/s of batched prediction, numpy in and numpy out.
* ``match``: query x database descriptor pairs per second of the ground-truth matcher
  (``rp_jax.groundtruth.matching.match_all_pairs``, Sec. III-D steps 1-2) against
  ``cv2.BFMatcher(cv2.NORM_L2).knnMatch(k=2)`` + ratio test, results checked identical.
* ``groundtruth``: wall time and peak memory of labelling one viewpoint as its number of
  images grows (no peer).

Model stages run each configuration in its own *worker* process (``worker.py``): JAX's
device count and XLA flags are fixed when JAX initialises, so they cannot change within a
process. The workers are started together, compile and warm up, and then the orchestrator
asks them for one timed measurement each in turn, round after round (A B C A B C ...), so
that load from other users of the machine falls on all of them alike.

Everything here that touches JAX or PyTorch runs inside a worker; the orchestrator imports
neither.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "SIZES",
    "VARIANTS",
    "ModelBench",
    "Variant",
    "check_torch_equals_jax",
    "cpu_peak",
    "groundtruth_once",
    "make_bench",
    "pairwise_ratio",
    "run_groundtruth_stage",
    "run_match_stage",
    "run_model_stage",
    "summarize_samples",
    "synthetic_descriptors",
]

PROTOCOL_PREFIX = "@@BENCH "  # stdout lines of the worker protocol start with this

# Problem sizes. ``tiny`` is for tests (seconds); ``full`` is the real measurement.
SIZES: dict[str, dict[str, Any]] = {
    "tiny": {
        "train_batch": 16,
        "train_steps": 2,
        "predict_batch": 32,
        "predict_steps": 2,
        "num_records": 64,
        "schedule": "webcam_clipart",
        "match_images": 3,
        "match_keypoints": 120,
        "gt_images": (3, 4, 6),
        "gt_image_size": (200, 150),
        "gt_keypoints": 150,
        # Map summarization (Sec. V-A): map sizes, pruned fraction, grid cell, T.
        "sum_points": (1_000, 10_000),
        "sum_headline_points": 10_000,
        "sum_ratio": 0.5,
        "sum_cell_size_m": 10.0,
        "sum_timestamps": 24,
        "kcover_budget_s": 60.0,
        # Localization (Sec. V-B).
        "loc_points": 1_500,
        "loc_images": 8,
        "loc_street_m": 36.0,
        "loc_queries": 3,
        "loc_words": 16,
        "loc_retrieved": 3,
    },
    "full": {
        # The project's defaults: batch 256 for training, 512 for prediction.
        "train_batch": 256,
        "train_steps": 6,
        "predict_batch": 512,
        "predict_steps": 6,
        "num_records": 2048,
        "schedule": "webcam_clipart",
        # One viewpoint of 8 images at the ground truth's 1000 interest points per image.
        "match_images": 8,
        "match_keypoints": 1000,
        "gt_images": (21, 42, 84),
        "gt_image_size": (640, 480),
        "gt_keypoints": 1000,
        # Maps of 10^4 .. 10^7 points; the goal: 10^6 points in under a second.
        "sum_points": (10_000, 100_000, 1_000_000, 10_000_000),
        "sum_headline_points": 1_000_000,
        "sum_ratio": 0.5,
        "sum_cell_size_m": 10.0,  # experiments/map_summarization's config.map.cell_size_m
        "sum_timestamps": 24,  # hourly (Sec. V: T = 24 hours/day)
        "kcover_budget_s": 60.0,  # skip K-cover at a size once the previous took longer
        # A 200 m street, a database image every 5 m, ~3,000 keypoints per query.
        "loc_points": 20_000,
        "loc_images": 40,
        "loc_street_m": 200.0,
        "loc_queries": 20,
        "loc_words": 64,
        "loc_retrieved": 5,  # experiments/map_summarization's config.map.num_retrieved
    },
}


@dataclasses.dataclass(frozen=True)
class Variant:
    """One configuration measured in its own process.

    Attributes:
      name: its key in the report.
      impl: ``"jax"`` (ours) or ``"torch"`` (the peer).
      num_devices: forced XLA host devices (jax); the batch is sharded over them.
      ynn: XLA's YNNPACK fusion flag (``rp_jax.platform.YNN_FLAG``) set (jax).
      dtype: patch-encoder dtype (``config.model.dtype``, jax).
      compile: ``torch.compile`` the module (torch).
      predictor_api: predict through ``rp_jax.predict.Predictor`` as shipped (jax, predict).
      description: one line for the report.
    """

    name: str
    impl: str
    num_devices: int = 1
    ynn: bool = False
    dtype: str = "float32"
    compile: bool = False
    predictor_api: bool = False
    description: str = ""


VARIANTS: dict[str, Variant] = {
    v.name: v
    for v in (
        Variant("jax_1dev", "jax", 1, False, description="JAX, 1 CPU device (JAX's default)"),
        Variant(
            "jax_2dev", "jax", 2, False, description="JAX, 2 forced host devices, batch sharded"
        ),
        Variant(
            "jax_2dev_ynn",
            "jax",
            2,
            True,
            description="JAX, 2 devices + YNN fusion flag (rp_jax.platform.configure_cpu default)",
        ),
        Variant(
            "jax_2dev_ynn_bf16",
            "jax",
            2,
            True,
            "bfloat16",
            description="JAX, 2 devices + YNN, bfloat16 patch encoder",
        ),
        Variant(
            "jax_predictor_api",
            "jax",
            2,
            True,
            predictor_api=True,
            description="rp_jax.predict.Predictor as shipped, after configure_cpu()",
        ),
        Variant("torch_eager", "torch", description="PyTorch 2 threads, eager"),
        Variant(
            "torch_compile", "torch", compile=True, description="PyTorch 2 threads, torch.compile"
        ),
    )
}
# Which variant stands for "ours" and for "peer" in the top-level ratio: what a user gets
# by default from each (configure_cpu() on this project, eager mode in PyTorch).
OURS_DEFAULT = "jax_2dev_ynn"
PEER_DEFAULT = "torch_eager"
STAGE_VARIANTS = {
    "train": ["jax_1dev", "jax_2dev", "jax_2dev_ynn", "jax_2dev_ynn_bf16", "torch_eager"],
    "predict": [
        "jax_1dev",
        "jax_2dev",
        "jax_2dev_ynn",
        "jax_2dev_ynn_bf16",
        "jax_predictor_api",
        "torch_eager",
    ],
}


# ----------------------------------------------------------------------------- statistics


def summarize_samples(samples: list[float]) -> dict[str, Any]:
    """Median, min, max of repeated measurements (and the samples themselves)."""
    a = np.asarray(samples, np.float64)
    return {
        "median": float(np.median(a)),
        "min": float(a.min()),
        "max": float(a.max()),
        "samples": [float(x) for x in a],
    }


def pairwise_ratio(ours: list[float], peer: list[float]) -> float:
    """Median over rounds of ours[r] / peer[r] (speeds measured back to back in round r)."""
    a, b = np.asarray(ours, np.float64), np.asarray(peer, np.float64)
    if a.shape != b.shape or a.size == 0:
        raise ValueError(f"need one peer measurement per round: {a.shape} vs {b.shape}")
    return float(np.median(a / b))


def cpu_peak(cpuinfo: str | None = None, num_cores: int | None = None) -> dict[str, Any]:
    """The FP32 peak of this CPU from ``/proc/cpuinfo``, with the assumption spelled out.

    Peak = cores x FMA units x SIMD lanes x 2 (multiply + add) x clock. AVX-512 server cores
    (Skylake-SP and later Xeons) have 2 FMA units of 16 fp32 lanes; AVX2 cores 2 of 8. The
    clock is the ``cpu MHz`` line (on a VM the TSC/base clock; turbo may run higher, so the
    fraction of peak is an upper bound of the truth at base clock).
    """
    if cpuinfo is None:
        try:
            cpuinfo = Path("/proc/cpuinfo").read_text()
        except OSError:
            cpuinfo = ""
    flags = (
        set(re.search(r"^flags\s*:\s*(.*)$", cpuinfo, re.MULTILINE).group(1).split())
        if "flags" in cpuinfo
        else set()
    )
    mhz = [float(m) for m in re.findall(r"^cpu MHz\s*:\s*([\d.]+)", cpuinfo, re.MULTILINE)]
    model = re.search(r"^model name\s*:\s*(.*)$", cpuinfo, re.MULTILINE)
    cores = num_cores or len(os.sched_getaffinity(0))
    if "avx512f" in flags:
        lanes, isa = 16, "AVX-512"
    elif "avx2" in flags and "fma" in flags:
        lanes, isa = 8, "AVX2+FMA"
    else:
        lanes, isa = 4, "SSE"
    units = 2
    ghz = (max(mhz) / 1000.0) if mhz else float("nan")
    peak = cores * units * lanes * 2 * ghz * 1e9
    return {
        "model": model.group(1).strip() if model else "unknown",
        "cores": cores,
        "isa": isa,
        "fma_units_assumed": units,
        "fp32_lanes": lanes,
        "clock_ghz": ghz,
        "fp32_peak_flops": peak,
        "amx_bf16": "amx_bf16" in flags,
        "avx512_bf16": "avx512_bf16" in flags,
        "assumption": (
            f"{cores} cores x {units} FMA units x {lanes} fp32 lanes ({isa}) x 2 flop "
            f"x {ghz:.2f} GHz (cpu MHz of /proc/cpuinfo)"
        ),
    }


# ----------------------------------------------------------------------------- model benches
# Everything below until the orchestration runs inside a worker process.


class ModelBench:
    """A warmed-up train or predict loop of one variant; ``measure()`` times one run."""

    stage: str
    batch: int
    steps: int

    def setup(self) -> dict[str, Any]:  # pragma: no cover - interface
        raise NotImplementedError

    def run_steps(self) -> None:  # pragma: no cover - interface
        raise NotImplementedError

    def measure(self) -> dict[str, float]:
        """Time ``steps`` steps; returns seconds and samples/s."""
        t0 = time.perf_counter()
        self.run_steps()
        dt = time.perf_counter() - t0
        n = self.batch * self.steps
        return {"seconds": dt, "samples": n, "speed": n / dt}


def _model_config(size: dict, variant: Variant, batch: int):
    from rp_jax.configs import default

    config = default.get_config()
    config.batch_size = batch
    config.eval_batch_size = batch
    config.num_devices = variant.num_devices
    config.model.dtype = variant.dtype
    config.schedule = size["schedule"]
    return config


def _records(size: dict, config) -> dict[str, np.ndarray]:
    from rp_jax import schedule as schedule_lib
    from rp_jax.datasets.learnable_task import make_learnable_task

    sched = schedule_lib.preset(config.schedule)
    rec = make_learnable_task(size["num_records"], sched, seed=0)
    rec["mask"] = np.ones(len(rec["patch"]), bool)
    return rec


def _batches(records: dict, batch: int, count: int) -> list[dict[str, np.ndarray]]:
    from rp_jax.datasets.input_pipeline import MODEL_KEYS

    n = len(records["patch"])
    out = []
    for i in range(count):
        idx = (np.arange(batch) + i * batch) % n
        out.append({k: records[k][idx] for k in MODEL_KEYS + ("mask",)})
    return out


def _cost_flops(compiled) -> float:
    cost = compiled.cost_analysis()
    if isinstance(cost, (list, tuple)):
        cost = cost[0]
    return float(cost.get("flops", float("nan"))) if cost else float("nan")


class JaxTrainBench(ModelBench):
    """Ours: ``rp_jax.train``'s jitted, sharded ``train_step`` as the training loop runs it."""

    stage = "train"

    def __init__(self, variant: Variant, size: dict):
        self.variant, self.size = variant, size
        self.batch, self.steps = size["train_batch"], size["train_steps"]

    def setup(self) -> dict[str, Any]:
        import jax

        from rp_jax import platform, train

        config = _model_config(self.size, self.variant, self.batch)
        records = _records(self.size, config)
        T = records["label"].shape[1]
        state = train.create_train_state(config, T, 100, jax.random.key(0))
        mesh = platform.make_mesh(config.num_devices)
        # FLOPs of one step from XLA's cost analysis, on one device without sharding.
        lowered = jax.jit(lambda s, b: train.train_step(s, b, config)).lower(
            state, self._first(records)
        )
        flops = _cost_flops(lowered.compile())
        self.compiled = train._compile(config, mesh, state.apply_fn)
        self.state = jax.device_put(state, self.compiled.replicated)
        self.batches = _batches(records, self.batch, self.steps)
        self.run_steps()  # compile + warm-up
        return {
            "flops_per_sample": flops / self.batch,
            "devices": int(mesh.devices.size),
            "xla_flags": os.environ.get("XLA_FLAGS", ""),
        }

    def _first(self, records):
        return _batches(records, self.batch, 1)[0]

    def run_steps(self) -> None:
        import jax

        metrics = None
        for b in self.batches:
            self.state, metrics = self.compiled.train(
                self.state, jax.device_put(b, self.compiled.data)
            )
        float(metrics["loss"])  # wait for the last step


class JaxPredictBench(ModelBench):
    """Ours: the pure ``rp_jax.predict.repeatability`` jitted with the batch sharded over the
    devices (or ``Predictor.__call__`` as shipped), numpy in and numpy out."""

    stage = "predict"

    def __init__(self, variant: Variant, size: dict):
        self.variant, self.size = variant, size
        self.batch, self.steps = size["predict_batch"], size["predict_steps"]

    def setup(self) -> dict[str, Any]:
        import jax
        from jax.sharding import NamedSharding
        from jax.sharding import PartitionSpec as P

        from rp_jax import platform, predict, time_encoding, train
        from rp_jax import schedule as schedule_lib

        config = _model_config(self.size, self.variant, self.batch)
        records = _records(self.size, config)
        T = records["label"].shape[1]
        params = train.create_train_state(config, T, 100, jax.random.key(0)).params
        tf = np.asarray(
            time_encoding.encode(
                records["hour"],
                records["minute"],
                records["day"],
                records["month"],
                fields=config.time_fields,
                encoding=config.time_encoding,
            ),
            np.float32,
        )
        self.inputs = []
        for b in _batches({**records, "time_features": tf}, self.batch, self.steps):
            self.inputs.append((b["patch"], b["xy_normalized"], tf[: self.batch]))

        def fn(p, x, xy, t):
            return predict.repeatability(p, x, xy, t, config=config)

        flops = _cost_flops(jax.jit(fn).lower(params, *self.inputs[0]).compile())
        if self.variant.predictor_api:
            self.predictor = predict.Predictor(
                params, config, schedule_lib.preset(config.schedule), batch_size=self.batch
            )
            self.call = lambda x, xy, t: self.predictor(x, xy, t)
        else:
            mesh = platform.make_mesh(config.num_devices)
            data, rep = NamedSharding(mesh, P("data")), NamedSharding(mesh, P())
            jitted = jax.jit(fn, in_shardings=(rep, data, data, data), out_shardings=data)
            self.params = jax.device_put(params, rep)
            self.call = lambda x, xy, t: np.asarray(jitted(self.params, x, xy, t))
        self.run_steps()
        return {
            "flops_per_sample": flops / self.batch,
            "devices": len(jax.devices()),
            "xla_flags": os.environ.get("XLA_FLAGS", ""),
        }

    def run_steps(self) -> None:
        for x, xy, t in self.inputs:
            self.last = self.call(x, xy, t)


def check_torch_equals_jax(size: dict, num_points: int = 16, seed: int = 0) -> dict[str, float]:
    """Copy fresh Flax weights into the PyTorch model and compare them on the same inputs.

    Returns max absolute differences of the patch-encoder features, the outputs, the
    masked-MSE loss, and the gradients relative to the largest gradient entry.
    """
    import jax
    import torch

    from experiments.benchmark import torch_reference as tr
    from rp_jax import losses, train
    from rp_jax import model as model_lib

    config = _model_config(size, Variant("ref", "jax"), num_points)
    records = _records({**size, "num_records": num_points}, config)
    T = records["label"].shape[1]
    params = train.create_train_state(config, T, 100, jax.random.key(seed)).params
    batch = _batches(records, num_points, 1)[0]
    x, xy, tf = (np.array(a) for a in train.model_inputs(batch, config))  # writable copies
    net = model_lib.create_model(config, T)
    out_j = np.asarray(net.apply({"params": params}, x, xy, tf))
    enc = model_lib.PatchEncoder(
        tuple(config.model.encoder_channels), config.model.encoder_features
    )
    feat_j = np.asarray(enc.apply({"params": params["patch_encoder"]}, x))

    def loss_fn(p):
        return losses.mse(
            net.apply({"params": p}, *train.model_inputs(batch, config)),
            batch["label"],
            batch["label_mask"],
            batch["mask"],
        )

    loss_j, grads_j = jax.value_and_grad(loss_fn)(params)

    module = tr.load_flax_params(tr.TorchRepeatabilityPredictor(T, tf.shape[1]), params)
    tb = {k: torch.from_numpy(np.asarray(v)) for k, v in batch.items()}
    with torch.no_grad():
        out_t = module(torch.from_numpy(x), torch.from_numpy(xy), torch.from_numpy(tf)).numpy()
        feat_t = module.encode(torch.from_numpy(x)).numpy()
        time_t = tr.encode_time_of_day(tb["hour"], tb["minute"]).numpy()
    pred = module(
        tr.preprocess_patches(tb["patch"]),
        tb["xy_normalized"],
        tr.encode_time_of_day(tb["hour"], tb["minute"]),
    )
    loss_t = tr.masked_mse(pred, tb["label"], tb["label_mask"], tb["mask"])
    loss_t.backward()
    # The same gradients in Flax layout, for a like-for-like comparison.
    grads_t = {
        "patch_encoder": {
            **{
                f"conv{i}": {
                    "kernel": np.transpose(c.weight.grad.numpy(), (2, 3, 1, 0)),
                    "bias": c.bias.grad.numpy(),
                }
                for i, c in enumerate((module.conv1, module.conv2, module.conv3), start=1)
            },
            "proj": {
                "kernel": module.proj.weight.grad.numpy().T,
                "bias": module.proj.bias.grad.numpy(),
            },
        },
        **{
            n: {
                "kernel": getattr(module, n).weight.grad.numpy().T,
                "bias": getattr(module, n).bias.grad.numpy(),
            }
            for n in ("fc1", "fc2", "fc3", "fc4", "fc5", "fc6")
        },
        "gem": {"rho": module.rho.grad.numpy()},
    }
    gj = jax.tree.map(np.asarray, grads_j)
    scale = max(float(np.max(np.abs(g))) for g in jax.tree.leaves(gj))
    diffs = jax.tree.map(
        lambda a, b: float(np.max(np.abs(np.asarray(a) - np.asarray(b)))), gj, grads_t
    )
    return {
        "feature_max_abs_diff": float(np.max(np.abs(feat_j - feat_t))),
        "feature_scale": float(np.max(np.abs(feat_j))),
        "output_max_abs_diff": float(np.max(np.abs(out_j - out_t))),
        "output_range": [float(out_j.min()), float(out_j.max())],
        "time_encoding_max_abs_diff": float(np.max(np.abs(tf - time_t))),
        "loss_abs_diff": float(abs(float(loss_j) - float(loss_t.detach()))),
        "grad_max_rel_diff": max(jax.tree.leaves(diffs)) / scale,
        "grad_scale": scale,
    }


class TorchBench(ModelBench):
    """The peer: ``torch_reference`` with the same weights, 2 threads, eager or compiled."""

    def __init__(self, stage: str, variant: Variant, size: dict):
        self.stage, self.variant, self.size = stage, variant, size
        key = "train" if stage == "train" else "predict"
        self.batch, self.steps = size[f"{key}_batch"], size[f"{key}_steps"]

    def setup(self) -> dict[str, Any]:
        import jax
        import torch

        from experiments.benchmark import torch_reference as tr
        from rp_jax import train

        torch.set_num_threads(2)
        check = check_torch_equals_jax(self.size)
        if check["output_max_abs_diff"] > 1e-5 or check["feature_max_abs_diff"] > 1e-5 * max(
            1.0, check["feature_scale"]
        ):
            raise RuntimeError(f"the PyTorch reference is not the same network as ours: {check}")
        config = _model_config(self.size, Variant("ref", "jax"), self.batch)
        records = _records(self.size, config)
        T = records["label"].shape[1]
        params = train.create_train_state(config, T, 100, jax.random.key(0)).params
        self.module = tr.load_flax_params(tr.TorchRepeatabilityPredictor(T, 2), params)
        self.net = torch.compile(self.module) if self.variant.compile else self.module
        self.batches = _batches(records, self.batch, self.steps)
        if self.stage == "train":
            self.optimizer = tr.make_optimizer(
                self.module, config.learning_rate, config.weight_decay
            )
        else:
            self.module.eval()
        self.tr, self.torch = tr, torch
        self.run_steps()
        return {"equality": check, "threads": torch.get_num_threads(), "torch": torch.__version__}

    def run_steps(self) -> None:
        tr, torch = self.tr, self.torch
        if self.stage == "train":
            for b in self.batches:
                loss = tr.train_step(
                    self.net, self.optimizer, {k: torch.from_numpy(v) for k, v in b.items()}
                )
            float(loss)
            return
        with torch.inference_mode():
            for b in self.batches:
                t = tr.encode_time_of_day(
                    torch.from_numpy(b["hour"]), torch.from_numpy(b["minute"])
                )
                self.last = self.net(
                    tr.preprocess_patches(torch.from_numpy(b["patch"])),
                    torch.from_numpy(b["xy_normalized"]),
                    t,
                ).numpy()


def make_bench(stage: str, variant: Variant, size: dict) -> ModelBench:
    """The bench of a (stage, variant) pair (called inside a worker)."""
    if variant.impl == "torch":
        return TorchBench(stage, variant, size)
    if stage == "train":
        return JaxTrainBench(variant, size)
    if stage == "predict":
        return JaxPredictBench(variant, size)
    raise ValueError(f"no model bench for stage {stage!r}")


# ----------------------------------------------------------------------------- orchestration


def worker_env(variant: Variant) -> dict[str, str]:
    """Environment of a worker: JAX settings fixed before JAX starts, threads for PyTorch."""
    env = dict(os.environ)
    flags = [
        f
        for f in env.get("XLA_FLAGS", "").split()
        if "ynn_fusion_type" not in f and "xla_force_host_platform_device_count" not in f
    ]
    if variant.impl == "jax" and variant.ynn:
        from rp_jax.platform import YNN_FLAG

        flags.append(YNN_FLAG)
    env["XLA_FLAGS"] = " ".join(flags)
    env["RP_JAX_NO_CPU_SETUP"] = "1"  # the worker sets the device count itself
    env["RP_BENCH_NUM_DEVICES"] = str(variant.num_devices)
    env["JAX_PLATFORMS"] = "cpu"
    root = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env


class Worker:
    """A worker process speaking the line protocol of ``worker.py``."""

    def __init__(self, stage: str, variant: Variant, size_name: str):
        self.variant = variant
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "experiments.benchmark.worker", stage, variant.name, size_name],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=worker_env(variant),
            cwd=str(Path(__file__).resolve().parents[2]),
        )

    def read(self) -> dict[str, Any]:
        while True:
            line = self.proc.stdout.readline()
            if not line:
                err = self.proc.stderr.read()[-3000:]
                raise RuntimeError(
                    f"worker {self.variant.name} exited (rc={self.proc.wait()}):\n{err}"
                )
            if line.startswith(PROTOCOL_PREFIX):
                msg = json.loads(line[len(PROTOCOL_PREFIX) :])
                if "error" in msg:
                    raise RuntimeError(f"worker {self.variant.name} failed: {msg['error']}")
                return msg

    def request(self, command: str) -> dict[str, Any]:
        self.proc.stdin.write(command + "\n")
        self.proc.stdin.flush()
        return self.read()

    def close(self) -> None:
        if self.proc.poll() is None:
            try:
                self.proc.stdin.write("quit\n")
                self.proc.stdin.flush()
                self.proc.wait(timeout=30)
            except (OSError, subprocess.TimeoutExpired):
                self.proc.kill()
                self.proc.wait()


def run_model_stage(
    stage: str,
    size_name: str,
    repeats: int,
    variants: list[str] | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    """Measure a model stage (``train`` or ``predict``): all variants, interleaved rounds.

    Args:
      stage: ``"train"`` or ``"predict"``.
      size_name: a key of ``SIZES``.
      repeats: timed rounds per variant (after each worker's warm-up).
      variants: names from ``VARIANTS`` (default ``STAGE_VARIANTS[stage]``); must include
        ``PEER_DEFAULT``.
      progress: tqdm bar over rounds.

    Returns:
      The stage's report entry (see ``report.py``).
    """
    from tqdm.auto import tqdm

    names = list(variants or STAGE_VARIANTS[stage])
    if PEER_DEFAULT not in names:
        raise ValueError(f"the variants of stage {stage} must include the peer {PEER_DEFAULT!r}")
    unavailable: dict[str, str] = {}
    workers: dict[str, Worker] = {}
    info: dict[str, Any] = {}
    try:
        for n in names:
            workers[n] = Worker(stage, VARIANTS[n], size_name)
        for n in list(workers):  # all compile at once; none is timed yet
            try:
                info[n] = workers[n].read()["ready"]
            except RuntimeError as e:
                if n in (PEER_DEFAULT, OURS_DEFAULT):
                    raise
                unavailable[n] = str(e).splitlines()[-1][:300]
                workers.pop(n).close()
        samples: dict[str, list[float]] = {n: [] for n in workers}
        order = list(workers)
        for r in tqdm(range(repeats), desc=f"{stage} rounds", disable=not progress, leave=False):
            # Alternate the direction of each round so a slow drift hits both ends alike.
            for n in order if r % 2 == 0 else order[::-1]:
                samples[n].append(workers[n].request("measure")["speed"])
    finally:
        for w in workers.values():
            w.close()

    peak = cpu_peak()
    # The peer runs the same float32 network: its FLOPs are ours' float32 count.
    f32 = [
        info[n]["flops_per_sample"]
        for n in samples
        if VARIANTS[n].impl == "jax"
        and VARIANTS[n].dtype == "float32"
        and "flops_per_sample" in info[n]
    ]
    entries = {}
    for n, s in samples.items():
        e = {**summarize_samples(s), "description": VARIANTS[n].description, **info.get(n, {})}
        if n != PEER_DEFAULT:
            e["ratio_to_peer"] = pairwise_ratio(s, samples[PEER_DEFAULT])
        if VARIANTS[n].impl == "torch" and f32:
            e["flops_per_sample"] = f32[0]
        fps = e.get("flops_per_sample")
        if fps:
            e["fraction_of_fp32_peak"] = e["median"] * fps / peak["fp32_peak_flops"]
        entries[n] = e
    ours_names = [n for n in entries if VARIANTS[n].impl == "jax"]
    best = max(ours_names, key=lambda n: entries[n]["median"])
    ours_key = OURS_DEFAULT if OURS_DEFAULT in entries else best
    return {
        "unit": "samples/s",
        "ours": {
            **entries[ours_key],
            "variant": ours_key,
            "variants": {n: entries[n] for n in ours_names},
            "best_variant": best,
        },
        "peer": {
            **entries[PEER_DEFAULT],
            "variant": PEER_DEFAULT,
            "variants": {n: entries[n] for n in entries if VARIANTS[n].impl == "torch"},
        },
        "ratio": pairwise_ratio(samples[ours_key], samples[PEER_DEFAULT]),
        "unavailable": unavailable,
        "cpu": peak,
        "batch": SIZES[size_name]["train_batch" if stage == "train" else "predict_batch"],
        "steps_per_measurement": SIZES[size_name][
            "train_steps" if stage == "train" else "predict_steps"
        ],
        "repeats": repeats,
    }


# ----------------------------------------------------------------------------- match stage


def synthetic_descriptors(num_images: int, num_keypoints: int, seed: int = 0) -> list[np.ndarray]:
    """SIFT-like descriptors of one viewpoint: integer-valued float32 in [0, 255], norm ~512.

    Each image sees the same scene points with noise, plus points of its own, so nearest
    neighbours and ratio tests behave like real ones (many pass, many fail).
    """
    rng = np.random.default_rng(seed)

    def sift_like(shape):
        d = rng.gamma(0.6, 1.0, shape)
        d = np.minimum(d / np.linalg.norm(d, axis=-1, keepdims=True), 0.2)
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        return d

    scene = sift_like((num_keypoints, 128))
    out = []
    for _ in range(num_images):
        shared = scene + rng.normal(0, 0.04, scene.shape)
        own = sift_like((num_keypoints, 128))
        keep = rng.random(num_keypoints) < 0.5
        d = np.where(keep[:, None], np.abs(shared), own)
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        out.append(np.minimum(np.round(d * 512), 255).astype(np.float32))
    return out


def _match_ours(descs, ratio):
    from rp_jax.groundtruth import matching

    return matching.match_all_pairs(descs, ratio=ratio, norm="l2", threads=2)


def _match_cv2(descs, ratio):
    import cv2

    bf = cv2.BFMatcher(cv2.NORM_L2)
    n = len(descs)
    nn = [np.full((len(d), n), -1, np.int32) for d in descs]
    ok = [np.zeros((len(d), n), bool) for d in descs]
    for a in range(n):
        for b in range(n):
            if a == b:
                continue
            for i, m in enumerate(bf.knnMatch(descs[a], descs[b], k=2)):
                if len(m) < 2:
                    continue
                nn[a][i, b] = m[0].trainIdx
                ok[a][i, b] = m[0].distance < ratio * m[1].distance
    return nn, ok


def run_match_stage(
    size_name: str, repeats: int, ratio: float = 0.8, progress: bool = True
) -> dict[str, Any]:
    """Descriptor matching of all ordered image pairs of a viewpoint: ours vs cv2.BFMatcher.

    Speed is query x database descriptor pairs per second, summed over ordered pairs (a, b),
    a != b. Results (nearest neighbour index and ratio-test verdict) are checked identical
    first.
    """
    import cv2
    from tqdm.auto import tqdm

    cv2.setNumThreads(2)
    size = SIZES[size_name]
    descs = synthetic_descriptors(size["match_images"], size["match_keypoints"])
    counts = np.array([len(d) for d in descs])
    pairs = float(counts.sum() ** 2 - np.sum(counts**2))
    ours = _match_ours(descs, ratio)  # warm-up, and the results to check
    nn_cv, ok_cv = _match_cv2(descs, ratio)
    mismatched_nn = sum(int(np.sum(o != c)) for o, c in zip(ours.nn, nn_cv))
    mismatched_ok = sum(int(np.sum(o != c)) for o, c in zip(ours.ratio_ok, ok_cv))
    if mismatched_nn or mismatched_ok:
        raise RuntimeError(
            f"ours and cv2.BFMatcher disagree: {mismatched_nn} nearest neighbours, "
            f"{mismatched_ok} ratio-test verdicts"
        )
    speeds: dict[str, list[float]] = {"ours": [], "peer": []}
    runs = {"ours": lambda: _match_ours(descs, ratio), "peer": lambda: _match_cv2(descs, ratio)}
    for r in tqdm(range(repeats), desc="match rounds", disable=not progress, leave=False):
        for k in ("ours", "peer") if r % 2 == 0 else ("peer", "ours"):
            t0 = time.perf_counter()
            runs[k]()
            speeds[k].append(pairs / (time.perf_counter() - t0))
    passed = sum(int(o.sum()) for o in ours.ratio_ok)
    return {
        "unit": "descriptor pairs/s",
        "ours": {
            **summarize_samples(speeds["ours"]),
            "variant": "rp_jax.groundtruth.matching.match_all_pairs",
            "description": "augmented float32 matrix product, 2 threads",
        },
        "peer": {
            **summarize_samples(speeds["peer"]),
            "variant": "cv2.BFMatcher(NORM_L2).knnMatch(k=2)",
            "description": (
                f"OpenCV {cv2.__version__}, cv2.setNumThreads(2), one call per ordered pair"
            ),
        },
        "ratio": pairwise_ratio(speeds["ours"], speeds["peer"]),
        "identical": True,
        "num_images": len(descs),
        "keypoints_per_image": int(counts[0]),
        "descriptor_pairs_per_run": pairs,
        "ratio_test_passed": passed,
        "repeats": repeats,
    }


# ----------------------------------------------------------------------------- groundtruth stage


def run_groundtruth_stage(size_name: str, repeats: int, progress: bool = True) -> dict[str, Any]:
    """Wall time and peak memory of labelling one viewpoint vs its number of images.

    Each (number of images, repeat) runs in a fresh process (``worker.py groundtruth``) so
    that its peak resident memory is its own. A quadratic ``a + b n + c n^2`` is fitted to the
    median times (matching is over all image pairs).
    """
    from tqdm.auto import tqdm

    size = SIZES[size_name]
    try:
        import rp_jax.groundtruth as gt

        gt.label_viewpoint  # noqa: B018 - the API this stage needs
    except (ImportError, AttributeError) as e:
        return {"unit": "s", "status": f"not yet available: {e}"}
    counts = list(size["gt_images"])
    rows: dict[int, dict[str, list[float]]] = {
        n: {"seconds": [], "peak_rss_mb": [], "delta_rss_mb": [], "interest_points": []}
        for n in counts
    }
    jobs = [(r, n) for r in range(repeats) for n in counts]
    for _, n in tqdm(jobs, desc="groundtruth", disable=not progress, leave=False):
        proc = subprocess.run(
            [
                sys.executable,
                "-m",
                "experiments.benchmark.worker",
                "groundtruth",
                str(n),
                size_name,
            ],
            check=False,  # a failure is reported below with the worker's stderr
            capture_output=True,
            text=True,
            env=worker_env(VARIANTS["jax_1dev"]),
            cwd=str(Path(__file__).resolve().parents[2]),
        )
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(PROTOCOL_PREFIX)]
        if proc.returncode or not lines:
            raise RuntimeError(
                f"groundtruth worker for {n} images failed (rc={proc.returncode}):\n"
                f"{proc.stderr[-3000:]}"
            )
        msg = json.loads(lines[-1][len(PROTOCOL_PREFIX) :])
        if "error" in msg:
            raise RuntimeError(f"groundtruth worker for {n} images failed: {msg['error']}")
        for k in rows[n]:
            rows[n][k].append(msg[k])
    per_size = {
        str(n): {
            "seconds": summarize_samples(rows[n]["seconds"]),
            "peak_rss_mb": float(np.max(rows[n]["peak_rss_mb"])),
            "delta_rss_mb": float(np.max(rows[n]["delta_rss_mb"])),
            "interest_points": int(np.median(rows[n]["interest_points"])),
        }
        for n in counts
    }
    med = np.array([per_size[str(n)]["seconds"]["median"] for n in counts])
    c2, c1, c0 = np.polyfit(np.asarray(counts, float), med, 2)
    slope = float(np.polyfit(np.log(counts), np.log(med), 1)[0])
    return {
        "unit": "s",
        "ours": {
            "variant": "rp_jax.groundtruth.label_viewpoint (static verification)",
            "per_num_images": per_size,
        },
        "peer": None,
        "ratio": None,
        "quadratic_fit": {
            "a": float(c0),
            "b": float(c1),
            "c": float(c2),
            "formula": "seconds ~ a + b n + c n^2",
        },
        "log_log_exponent": slope,
        "image_size": list(size["gt_image_size"]),
        "max_keypoints": size["gt_keypoints"],
        "repeats": repeats,
    }


def groundtruth_once(num_images: int, size: dict, seed: int = 0) -> dict[str, float]:
    """Label one synthetic static viewpoint of ``num_images`` images (inside a worker)."""
    from rp_jax.groundtruth import GroundTruthConfig, label_viewpoint

    images = _viewpoint_images(num_images, size["gt_image_size"], seed)
    config = GroundTruthConfig(
        detector="sift", max_keypoints=size["gt_keypoints"], verification="static"
    )
    captures = _captures(num_images, size["gt_image_size"])
    loader = _ImageLoader(images)
    # Warm-up on two tiny images (imports, OpenCV's first-call set-up) before measuring.
    small = _viewpoint_images(2, (96, 72), seed + 1)
    label_viewpoint(
        _captures(2, (96, 72), "warm"),
        load_image=_ImageLoader(small),
        num_timestamps=4,
        config=config,
    )
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    t0 = time.perf_counter()
    rec = label_viewpoint(captures, load_image=loader, num_timestamps=4, config=config)
    seconds = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return {
        "seconds": seconds,
        "peak_rss_mb": peak,
        "delta_rss_mb": peak - base,
        "interest_points": len(rec["xy"]),
    }


class _ImageLoader:
    def __init__(self, images: list[np.ndarray]):
        self.images = images

    def __call__(self, capture) -> np.ndarray:
        return self.images[int(capture.image_id.split("_")[-1])]


def _viewpoint_images(num_images: int, wh: tuple[int, int], seed: int) -> list[np.ndarray]:
    """A static webcam: one textured scene, each image with a sub-pixel jitter, gain and noise."""
    import cv2

    w, h = wh
    rng = np.random.default_rng(seed)
    img = np.zeros((h, w, 3), np.float32)
    for sigma, amp in ((6.0, 120.0), (2.5, 80.0), (1.2, 40.0)):
        noise = rng.normal(0, 1, (h, w, 1)) + 0.3 * rng.normal(0, 1, (h, w, 3))
        blurred = cv2.GaussianBlur(noise.astype(np.float32), (0, 0), sigma)
        img += amp * blurred / (blurred.std() + 1e-6)
    img = (img - img.min()) / (img.max() - img.min()) * 255.0
    out = []
    for _ in range(num_images):
        dx, dy = rng.uniform(-0.5, 0.5, 2)
        M = np.float32([[1, 0, dx], [0, 1, dy]])
        moved = cv2.warpAffine(img, M, (w, h), borderMode=cv2.BORDER_REFLECT_101)
        moved = moved * rng.uniform(0.6, 1.1) + rng.normal(0, 4.0, moved.shape)
        out.append(np.clip(moved, 0, 255).astype(np.uint8))
    return out


def _captures(num_images: int, wh: tuple[int, int], viewpoint: str = "bench"):
    import datetime as dt

    from rp_jax.sources.capture import Camera, Capture

    w, h = wh
    cam = Camera("PINHOLE", w, h, np.array([[w, 0, w / 2], [0, w, h / 2], [0, 0, 1.0]]))
    tz = dt.UTC
    caps = []
    for i in range(num_images):
        slot, cycle = i % 4, i // 4
        when = dt.datetime(2021, 6, 1, 8 + 2 * slot, 0, tzinfo=tz) + dt.timedelta(days=cycle)
        caps.append(
            Capture(
                Path(f"/synthetic/{viewpoint}/img_{i}.png"),
                when,
                cam,
                viewpoint,
                cycle=cycle,
                slot=slot,
                image_id=f"img_{i}",
            )
        )
    return caps
