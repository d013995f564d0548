"""The model benches of the ``train`` and ``predict`` stages (Sec. III-B/C): ours
(``rp_jax.train``'s sharded step, ``rp_jax.predict``) and the PyTorch peer
(``torch_reference``) with the same weights, checked equal first.

Everything here runs inside a worker process (``worker.py``): JAX's device count and XLA
flags are fixed when JAX initialises; the orchestrator (``model_stage``) imports neither JAX
nor PyTorch.
"""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np

from experiments.benchmark.config import Variant

__all__ = [
    "JaxPredictBench",
    "JaxTrainBench",
    "ModelBench",
    "TorchBench",
    "check_torch_equals_jax",
    "make_bench",
]

class ModelBench:
    """A warmed-up train or predict loop of one variant; ``measure()`` times one run."""

    stage: str  # "train" or "predict": the SIZES keys of its batch and steps

    def __init__(self, variant: Variant, size: dict):
        self.variant, self.size = variant, size
        self.batch, self.steps = size[f"{self.stage}_batch"], size[f"{self.stage}_steps"]

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
    config.input.batch_size = batch
    config.eval.batch_size = batch
    config.train.num_devices = variant.num_devices
    config.model.dtype = variant.dtype
    config.input.schedule = size["schedule"]
    return config


def _records(size: dict, config) -> dict[str, np.ndarray]:
    from rp_jax import schedule as schedule_lib
    from rp_jax.datasets.learnable_task import make_learnable_task

    sched = schedule_lib.preset(config.input.schedule)
    rec = make_learnable_task(size["num_records"], sched, seed=0)
    rec["mask"] = np.ones(len(rec["patch"]), bool)
    return rec


def _fresh_model(size: dict, variant: Variant, batch: int, seed: int = 0):
    """(config, records, freshly initialised train state) of a bench: ours and the peer
    start from the same weights."""
    import jax

    from rp_jax import train

    config = _model_config(size, variant, batch)
    records = _records(size, config)
    T = records["label"].shape[1]
    return config, records, train.create_train_state(config, T, 100, jax.random.key(seed))


def _variant_net(config, variant: Variant, num_timestamps: int):
    """The Flax module a variant runs: the model of ``config`` with ``variant.conv1`` (the
    same parameters, another way to compute conv1), or None for the model's default."""
    if not variant.conv1:
        return None
    from rp_jax import model as model_lib

    return model_lib.create_model(config, num_timestamps).clone(conv1_path=variant.conv1)


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

    def setup(self) -> dict[str, Any]:
        import jax

        from rp_jax import platform, train

        config, records, state = _fresh_model(self.size, self.variant, self.batch)
        net = _variant_net(config, self.variant, records["label"].shape[1])
        if net is not None:
            state = state.replace(apply_fn=net.apply)
        mesh = platform.make_mesh(config.train.num_devices)
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

    def setup(self) -> dict[str, Any]:
        import jax
        from jax.sharding import NamedSharding
        from jax.sharding import PartitionSpec as P

        from rp_jax import model as model_lib
        from rp_jax import platform, predict, time_encoding
        from rp_jax import schedule as schedule_lib

        config, records, state = _fresh_model(self.size, self.variant, self.batch)
        params = state.params
        tf = np.asarray(
            time_encoding.encode(
                records["hour"],
                records["minute"],
                records["day"],
                records["month"],
                fields=config.model.time_fields,
                encoding=config.model.time_encoding,
            ),
            np.float32,
        )
        self.inputs = []
        for b in _batches({**records, "time_features": tf}, self.batch, self.steps):
            self.inputs.append((b["patch"], b["xy_normalized"], tf[: self.batch]))

        net = _variant_net(config, self.variant, records["label"].shape[1])

        def fn(p, x, xy, t):
            if net is not None:  # what predict.repeatability does, with the variant's module
                return net.apply({"params": p}, model_lib.preprocess_patches(x), xy, t)
            return predict.repeatability(p, x, xy, t, config=config)

        flops = _cost_flops(jax.jit(fn).lower(params, *self.inputs[0]).compile())
        if self.variant.predictor_api:
            self.predictor = predict.Predictor(
                params, config, schedule_lib.preset(config.input.schedule), batch_size=self.batch
            )
            self.call = lambda x, xy, t: self.predictor(x, xy, t)
        else:
            mesh = platform.make_mesh(config.train.num_devices)
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

    config, records, state = _fresh_model(
        {**size, "num_records": num_points}, Variant("ref", "jax"), num_points, seed
    )
    params = state.params
    T = records["label"].shape[1]
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
        self.stage = stage
        super().__init__(variant, size)

    def setup(self) -> dict[str, Any]:
        import torch

        from experiments.benchmark import torch_reference as tr

        torch.set_num_threads(2)
        check = check_torch_equals_jax(self.size)
        if check["output_max_abs_diff"] > 1e-5 or check["feature_max_abs_diff"] > 1e-5 * max(
            1.0, check["feature_scale"]
        ):
            raise RuntimeError(f"the PyTorch reference is not the same network as ours: {check}")
        config, records, state = _fresh_model(self.size, Variant("ref", "jax"), self.batch)
        T = records["label"].shape[1]
        params = state.params
        self.module = tr.load_flax_params(tr.TorchRepeatabilityPredictor(T, 2), params)
        self.net = torch.compile(self.module) if self.variant.compile else self.module
        self.batches = _batches(records, self.batch, self.steps)
        if self.stage == "train":
            self.optimizer = tr.make_optimizer(
                self.module, config.train.learning_rate, config.train.weight_decay
            )
        else:
            self.module.eval()
        self.tr, self.torch = tr, torch
        self.run_steps()
        return {"equality": check, "threads": torch.get_num_threads(), "torch": torch.__version__}

    def run_steps(self) -> None:
        tr, torch = self.tr, self.torch
        autocast = self.variant.autocast
        if self.stage == "train":
            for b in self.batches:
                loss = tr.train_step(
                    self.net,
                    self.optimizer,
                    {k: torch.from_numpy(v) for k, v in b.items()},
                    autocast=autocast,
                )
            float(loss)
            return
        with torch.inference_mode(), tr.autocast_context(autocast):
            for b in self.batches:
                t = tr.encode_time_of_day(
                    torch.from_numpy(b["hour"]), torch.from_numpy(b["minute"])
                )
                self.last = (
                    self.net(
                        tr.preprocess_patches(torch.from_numpy(b["patch"])),
                        torch.from_numpy(b["xy_normalized"]),
                        t,
                    )
                    .float()
                    .numpy()
                )


def make_bench(stage: str, variant: Variant, size: dict) -> ModelBench:
    """The bench of a (stage, variant) pair (called inside a worker)."""
    if stage == "layers":  # experiments.benchmark.layer_profile, either framework
        from experiments.benchmark.layer_profile import LayerBench

        return LayerBench(variant, size)
    if variant.impl == "torch":
        return TorchBench(stage, variant, size)
    if stage == "train":
        return JaxTrainBench(variant, size)
    if stage == "predict":
        return JaxPredictBench(variant, size)
    raise ValueError(f"no model bench for stage {stage!r}")
