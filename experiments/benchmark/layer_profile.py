"""Per-layer profile of the repeatability predictor (Sec. III-B): each layer of the patch
encoder and the fc head, forwards and forwards + backwards, JAX against PyTorch on the same
shapes and weights, in interleaved rounds.

    python -m experiments.benchmark.layer_profile [--size full|tiny] [--repeats 7] [--out FILE]

Also the ``layers`` stage of ``python -m experiments.benchmark`` (its section of
``benchmark.md``). Prints a markdown table (and writes it to ``--out``): milliseconds per
batch (the train batch of the size: 256 at full size; median over rounds), GFLOP/s and the
speed ratio JAX / PyTorch measured in the same rounds.

Each framework runs in its own worker process (``worker.py``), as the train stage runs them:
JAX with ``configure_cpu``'s defaults (the ``jax_2dev_ynn_image`` variant; a layer here is
jitted without sharding, so it runs on one device with the 2-thread pool), PyTorch eager with
2 threads (``torch_eager``). Two frameworks in one process would fight over the cores (one's
idle threads spinning while the other works). The whole batch goes through one JAX device
here, whereas the train stage shards it over 2, so the rows do not add up to the train
step's time; they say where each framework is fast. "fwd+bwd" is the forward pass and the
vector-Jacobian product for a given output cotangent: gradients of the layer's weights and
bias, and of its input except for the first layer (whose input is data).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

__all__ = ["LAYERS", "LayerBench", "format_table", "main", "profile_layers",
           "run_layers_stage"]

# (name, description, input shape without the batch, forward GFLOP per sample, input grad)
LAYERS = [
    ("input", "uint8 patch -> float, space-to-depth 64x64x3 -> 16x16x48", (64, 64, 3), 0.0,
     False),
    ("conv1 (s2d)", "3x3 conv 48->64 on the 16x16 space-to-depth map, bias, relu",
     (16, 16, 48), 2 * 16 * 16 * 9 * 48 * 64 / 1e9, False),
    ("conv1 (image)", "the same conv1 as a 12x12 stride-4 conv of the 64x64x3 patch",
     (64, 64, 3), 2 * 16 * 16 * 9 * 48 * 64 / 1e9, False),
    ("conv2", "3x3 stride-2 conv 64->64, 16x16 -> 8x8, bias, relu", (16, 16, 64),
     2 * 8 * 8 * 9 * 64 * 64 / 1e9, True),
    ("conv3", "3x3 stride-2 conv 64->128, 8x8 -> 4x4, bias, relu", (8, 8, 64),
     2 * 4 * 4 * 9 * 64 * 128 / 1e9, True),
    ("proj", "dense 2048->128, bias, relu", (2048,), 2 * 2048 * 128 / 1e9, True),
    ("head", "fc1..fc5, GeM, fc6, sigmoid on [features, xy, time]", (132,),
     2 * (132 * 64 + 64 * 32 + 32 * 64 + 64 * 32 + 32 * 64 + 64 * 21) / 1e9, True),
]


def _jax_layers(params, num_timestamps: int) -> dict[str, Callable]:
    """Each layer as a function of (weights, input) using rp_jax.model's own modules."""
    import flax.linen as nn
    import jax.numpy as jnp

    from rp_jax import model as model_lib

    enc = params["patch_encoder"]

    def conv1_image():
        mod = model_lib.Conv1(64, "image")
        return lambda w, x: nn.relu(mod.apply({"params": w}, x)), enc["conv1"]

    def conv1_s2d():  # what Conv1's "space_to_depth" path runs after the transpose
        mod = nn.Conv(64, (3, 3), padding="SAME")
        return lambda w, x: nn.relu(mod.apply({"params": w}, x)), enc["conv1"]

    def strided(name, ch):
        mod = nn.Conv(ch, (3, 3), strides=(2, 2), padding="SAME")
        return lambda w, x: nn.relu(mod.apply({"params": w}, x)), enc[name]

    proj = nn.Dense(128)

    def head(w, h):
        def dense(name, v):
            return v @ w[name]["kernel"] + w[name]["bias"]

        z1 = nn.relu(dense("fc1", h))
        z2 = nn.relu(dense("fc3", nn.relu(dense("fc2", z1))))
        z3 = nn.relu(dense("fc5", nn.relu(dense("fc4", z2))))
        p = model_lib.GeM.p_from(w["gem"]["rho"])
        return nn.sigmoid(dense("fc6", model_lib.gem_pool(jnp.stack([z1, z2, z3]), p)))

    head_w = {k: params[k] for k in ("fc1", "fc2", "fc3", "fc4", "fc5", "fc6", "gem")}
    return {
        "input": (lambda w, u: model_lib.space_to_depth(model_lib.preprocess_patches(u), 4),
                  {}),
        "conv1 (s2d)": conv1_s2d(),
        "conv1 (image)": conv1_image(),
        "conv2": strided("conv2", 64),
        "conv3": strided("conv3", 128),
        "proj": (lambda w, x: nn.relu(proj.apply({"params": w}, x)), enc["proj"]),
        "head": (head, head_w),
    }


def _torch_layers(module) -> dict[str, Callable]:
    """The same layers of ``torch_reference.TorchRepeatabilityPredictor`` (NCHW inside)."""
    import torch
    import torch.nn.functional as F

    from experiments.benchmark import torch_reference as tr

    def image_kernel():
        from rp_jax.model import conv1_kernel_on_image

        k = module.conv1.weight.detach().numpy().transpose(2, 3, 1, 0)  # OIHW -> HWIO
        k = np.asarray(conv1_kernel_on_image(k)).transpose(3, 2, 0, 1)
        return torch.nn.Parameter(torch.from_numpy(np.ascontiguousarray(k)))

    w_image = image_kernel()

    def head(h):
        z1 = F.relu(module.fc1(h))
        z2 = F.relu(module.fc3(F.relu(module.fc2(z1))))
        z3 = F.relu(module.fc5(F.relu(module.fc4(z2))))
        p = 1.0 + F.softplus(module.rho)
        return torch.sigmoid(module.fc6(tr.gem_pool(torch.stack([z1, z2, z3]), p)))

    return {
        # NHWC in, NCHW out: what the encoder's first layer consumes.
        "input": lambda u: tr.space_to_depth_nhwc(tr.preprocess_patches(u), 4).permute(
            0, 3, 1, 2).contiguous(),
        "conv1 (s2d)": lambda x: F.relu(module.conv1(x)),
        "conv1 (image)": lambda x: F.relu(
            F.conv2d(F.pad(x, (4, 4, 4, 4)), w_image, module.conv1.bias, stride=4)),
        "conv2": lambda x: F.relu(module.conv2(F.pad(x, (0, 1, 0, 1)))),
        "conv3": lambda x: F.relu(module.conv3(F.pad(x, (0, 1, 0, 1)))),
        "proj": lambda x: F.relu(module.proj(x)),
        "head": head,
    }


def _timed(fn: Callable, sync: Callable, inner: int) -> float:
    t0 = time.perf_counter()
    for _ in range(inner):
        out = fn()
    sync(out)
    return (time.perf_counter() - t0) / inner


class LayerBench:
    """Inside a worker: every (layer, pass) of one framework, warmed up;
    ``measure("LAYER|PASS")`` times ``inner`` calls of it. Both sides build the same weights
    and inputs from ``seed``."""

    def __init__(self, variant, size: dict, seed: int = 0, inner: int = 3,
                 layers: list[str] | None = None):
        self.impl, self.batch = variant.impl, size["train_batch"]
        self.seed, self.inner, self.layers = seed, inner, layers

    def setup(self) -> dict:
        import jax

        from rp_jax import model as model_lib

        T = 21
        net = model_lib.RepeatabilityPredictor(num_timestamps=T)
        params = model_lib.init_params(net, jax.random.key(self.seed), 2)
        self.calls = {}
        if self.impl == "jax":
            self._build_jax(params)
        else:
            from experiments.benchmark import torch_reference as tr

            self._build_torch(tr.load_flax_params(tr.TorchRepeatabilityPredictor(T, 2), params))
        for fn, sync in self.calls.values():  # compile and warm up
            sync(fn())
        return {"keys": list(self.calls)}

    def _inputs(self):
        """Per layer: input x (NHWC / flat, numpy) and output cotangent dy, the same on both
        sides (drawn in LAYERS order from one generator)."""
        rng = np.random.default_rng(self.seed)
        out_shapes = {"input": (16, 16, 48), "conv1 (s2d)": (16, 16, 64),
                      "conv1 (image)": (16, 16, 64), "conv2": (8, 8, 64), "conv3": (4, 4, 128),
                      "proj": (128,), "head": (21,)}
        for name, _, shape, _, _ in LAYERS:
            if name == "input":
                x = rng.integers(0, 256, (self.batch, *shape), dtype=np.uint8)
            else:
                x = (rng.standard_normal((self.batch, *shape)) * 0.5).astype(np.float32)
            dy = rng.standard_normal((self.batch, *out_shapes[name])).astype(np.float32)
            if self.layers is None or name in self.layers:
                yield name, x, dy

    def _build_jax(self, params) -> None:
        import jax
        import jax.numpy as jnp

        layers = _jax_layers(params, 21)
        flags = {name: (gflop, input_grad) for name, _, _, gflop, input_grad in LAYERS}
        for name, x, dy in self._inputs():
            f, w = layers[name]
            gflop, input_grad = flags[name]
            xj, dyj = jnp.asarray(x), jnp.asarray(dy)
            jf = jax.jit(f)
            self.calls[f"{name}|fwd"] = (lambda jf=jf, w=w, xj=xj: jf(w, xj),
                                         jax.block_until_ready)
            if not gflop:
                continue

            def vjp(w, x, dy, f=f, input_grad=input_grad):
                if input_grad:
                    return jax.vjp(f, w, x)[1](dy)
                return jax.vjp(lambda w: f(w, x), w)[1](dy)

            jb = jax.jit(vjp)
            self.calls[f"{name}|fwd+bwd"] = (lambda jb=jb, w=w, xj=xj, d=dyj: jb(w, xj, d),
                                             jax.block_until_ready)

    def _build_torch(self, module) -> None:
        import torch

        torch.set_num_threads(2)
        layers = _torch_layers(module)
        params_t = list(module.parameters())
        flags = {name: (gflop, input_grad) for name, _, _, gflop, input_grad in LAYERS}
        for name, x, dy in self._inputs():
            gflop, input_grad = flags[name]
            f = layers[name]
            # PyTorch takes NCHW maps: the same numbers, moved channels-first once, outside.
            xt, dyt = torch.from_numpy(x), torch.from_numpy(dy)
            if xt.ndim == 4 and name != "input":
                xt = xt.permute(0, 3, 1, 2).contiguous()
            if dyt.ndim == 4 and name != "input":
                dyt = dyt.permute(0, 3, 1, 2).contiguous()

            def fwd(f=f, xt=xt):
                with torch.no_grad():
                    return f(xt)

            self.calls[f"{name}|fwd"] = (fwd, lambda out: None)
            if not gflop:
                continue

            def bwd(f=f, xt=xt, dyt=dyt, input_grad=input_grad):
                xin = xt.detach().requires_grad_(input_grad)
                for q in params_t:
                    q.grad = None
                f(xin).backward(dyt)
                return xin.grad

            self.calls[f"{name}|fwd+bwd"] = (bwd, lambda out: None)

    def measure(self, key: str) -> dict:
        fn, sync = self.calls[key]
        return {"seconds": _timed(fn, sync, self.inner)}


def profile_layers(size_name: str = "full", repeats: int = 7,
                   layers: list[str] | None = None) -> list[dict]:
    """Time every layer of ``LAYERS`` (or the named ``layers``) in both frameworks, each in
    its worker process, alternating JAX and PyTorch round by round; see the module docstring.

    Returns:
      One dict per (layer, pass): layer, pass ("fwd" / "fwd+bwd"), jax_ms, torch_ms
      (medians), jax_gflops, torch_gflops, ratio (median over rounds of torch time / JAX
      time: above 1 JAX is faster), description.
    """
    from experiments.benchmark.config import OURS_DEFAULT, PEER_DEFAULT, SIZES, VARIANTS
    from experiments.benchmark.orchestration import Worker

    batch = SIZES[size_name]["train_batch"]
    workers = {}
    try:
        for side, name in (("jax", OURS_DEFAULT), ("torch", PEER_DEFAULT)):
            workers[side] = Worker("layers", VARIANTS[name], size_name)
        keys = [workers[side].read()["ready"]["keys"] for side in workers][0]
        rows = []
        for name, desc, _, gflop, input_grad in LAYERS:
            if layers is not None and name not in layers:
                continue
            for pname in ("fwd", "fwd+bwd"):
                key = f"{name}|{pname}"
                if key not in keys:
                    continue
                times: dict[str, list[float]] = {"jax": [], "torch": []}
                for r in range(repeats):
                    for side in ("jax", "torch") if r % 2 == 0 else ("torch", "jax"):
                        times[side].append(workers[side].request(f"measure {key}")["seconds"])
                jt, tt = np.asarray(times["jax"]), np.asarray(times["torch"])
                flop = gflop * batch * (1 if pname == "fwd" else (3 if input_grad else 2))
                rows.append({
                    "layer": name, "pass": pname, "description": desc,
                    "jax_ms": float(np.median(jt) * 1e3),
                    "torch_ms": float(np.median(tt) * 1e3),
                    "jax_gflops": flop / float(np.median(jt)) if flop else float("nan"),
                    "torch_gflops": flop / float(np.median(tt)) if flop else float("nan"),
                    "ratio": float(np.median(tt / jt)),
                })
    finally:
        for w in workers.values():
            w.close()
    return rows


def run_layers_stage(size_name: str, repeats: int, progress: bool = True) -> dict:
    """The ``layers`` stage of ``python -m experiments.benchmark``: ``profile_layers`` as a
    report entry (``report.py`` renders it with ``format_table``)."""
    from experiments.benchmark.config import OURS_DEFAULT, PEER_DEFAULT, SIZES

    del progress  # one short pass; no bar
    return {
        "unit": "ms per batch",
        "batch": SIZES[size_name]["train_batch"],
        "repeats": repeats,
        "jax_variant": OURS_DEFAULT,
        "torch_variant": PEER_DEFAULT,
        "rows": profile_layers(size_name, repeats),
    }


def format_table(rows: list[dict], batch: int, repeats: int) -> str:
    """The rows of ``profile_layers`` as a markdown table with its caption."""
    lines = [
        f"ms per batch of {batch} (median of {repeats} interleaved rounds), GFLOP/s, and "
        "JAX's speed relative to PyTorch eager (torch ms / JAX ms, same rounds; above 1 JAX "
        "is faster). fwd+bwd = forward + gradients of weights, bias and (except conv1) input.",
        "",
        "| layer | pass | JAX ms | PyTorch ms | JAX GFLOP/s | PyTorch GFLOP/s | JAX / PyTorch | "
        "what |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        g = (f"{r['jax_gflops']:.0f} | {r['torch_gflops']:.0f}"
             if r["jax_gflops"] == r["jax_gflops"] else "- | -")
        lines.append(f"| {r['layer']} | {r['pass']} | {r['jax_ms']:.2f} | {r['torch_ms']:.2f} "
                     f"| {g} | {r['ratio']:.2f} | {r['description']} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m experiments.benchmark.layer_profile",
                                     description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--size", choices=("tiny", "full"), default="full",
                        help="tiny (batch 16, tests) or full (batch 256, default)")
    parser.add_argument("--repeats", type=int, default=7, help="interleaved rounds")
    parser.add_argument("--out", default=None, help="also write the table to this file")
    args = parser.parse_args(argv)
    if args.repeats < 1:
        parser.error("--repeats must be >= 1")
    from experiments.benchmark.config import SIZES

    load = os.getloadavg()[0]
    rows = profile_layers(args.size, args.repeats)
    table = format_table(rows, SIZES[args.size]["train_batch"], args.repeats)
    table += f"\n\nLoad average (1 min) before -> after: {load:.1f} -> {os.getloadavg()[0]:.1f}."
    print(table)
    if args.out:
        Path(args.out).write_text(table + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
