"""Per-layer profile of the repeatability predictor (Sec. III-B): each layer of the patch
encoder and the fc head, forwards and forwards + backwards, JAX against PyTorch on the same
shapes and weights, in one process and in interleaved rounds.

    python -m experiments.benchmark.layer_profile [--batch 256] [--repeats 7] [--out FILE]

Prints a markdown table (and writes it to ``--out``): milliseconds per batch (median over
rounds), GFLOP/s and the speed ratio JAX / PyTorch measured in the same rounds.

Both frameworks run in this one process on the same cores: JAX as one XLA device with
``rp_jax.platform.configure_cpu``'s XLA flag and ``tune_malloc`` (which the PyTorch side then
shares), PyTorch eager with 2 threads. The whole batch goes through one JAX device here,
whereas the train stage shards it over 2 devices, so the sum of the rows is not the train
step's time; the rows say where each framework is fast. "fwd+bwd" is the forward pass and
the vector-Jacobian product for a given output cotangent: gradients of the layer's weights
and bias, and of its input except for the first layer (whose input is data).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

__all__ = ["LAYERS", "profile_layers", "format_table", "main"]

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


def profile_layers(batch: int = 256, repeats: int = 7, inner: int = 3, seed: int = 0,
                   layers: list[str] | None = None) -> list[dict]:
    """Time every layer of ``LAYERS`` (or the named ``layers``) in both frameworks; see the
    module docstring.

    Returns:
      One dict per (layer, pass): layer, pass ("fwd" / "fwd+bwd"), jax_ms, torch_ms
      (medians), jax_gflops, torch_gflops, ratio (median over rounds of torch time / JAX
      time: above 1 JAX is faster), description.
    """
    import jax
    import jax.numpy as jnp
    import torch

    from experiments.benchmark import torch_reference as tr
    from rp_jax import model as model_lib

    torch.set_num_threads(2)
    T = 21
    net = model_lib.RepeatabilityPredictor(num_timestamps=T)
    params = model_lib.init_params(net, jax.random.key(seed), 2)
    module = tr.load_flax_params(tr.TorchRepeatabilityPredictor(T, 2), params)
    jl, tl = _jax_layers(params, T), _torch_layers(module)
    rng = np.random.default_rng(seed)
    params_t = list(module.parameters())
    rows = []
    for name, desc, shape, gflop, input_grad in LAYERS:
        if layers is not None and name not in layers:
            continue
        if name == "input":
            x = rng.integers(0, 256, (batch, *shape), dtype=np.uint8)
        else:
            x = rng.standard_normal((batch, *shape)).astype(np.float32) * 0.5
        f, w = jl[name]
        xj = jnp.asarray(x)
        y = jax.jit(f)(w, xj)
        dy = jnp.asarray(rng.standard_normal(y.shape).astype(np.float32))
        jf = jax.jit(f)

        def vjp(w, x, dy, f=f, input_grad=input_grad):
            if input_grad:
                return jax.vjp(f, w, x)[1](dy)
            return jax.vjp(lambda w: f(w, x), w)[1](dy)

        jb = jax.jit(vjp)
        # PyTorch takes NCHW maps; the same numbers, moved channels-first once, outside.
        xt = torch.from_numpy(np.array(xj))
        if xt.ndim == 4 and name != "input":
            xt = xt.permute(0, 3, 1, 2).contiguous()
        tf = tl[name]
        yt = tf(xt)
        dyt = torch.from_numpy(np.asarray(rng.standard_normal(tuple(yt.shape)), np.float32))
        def torch_fwd(tf=tf, xt=xt):
            with torch.no_grad():
                return tf(xt)

        def torch_bwd(tf=tf, xt=xt, dyt=dyt, input_grad=input_grad):
            xin = xt.detach().requires_grad_(input_grad)
            for p in params_t:
                p.grad = None
            tf(xin).backward(dyt)
            return xin.grad

        passes = [("fwd", lambda jf=jf, w=w, xj=xj: jf(w, xj), torch_fwd)]
        if gflop:
            passes.append(("fwd+bwd", lambda jb=jb, w=w, xj=xj, dy=dy: jb(w, xj, dy),
                           torch_bwd))
        for pname, jcall, tcall in passes:
            jax.block_until_ready(jcall())  # compile and warm up
            tcall()
            jt, tt = [], []
            for r in range(repeats):
                order = ("jax", "torch") if r % 2 == 0 else ("torch", "jax")
                for side in order:
                    if side == "jax":
                        jt.append(_timed(jcall, jax.block_until_ready, inner))
                    else:
                        tt.append(_timed(tcall, lambda out: None, inner))
            jt, tt = np.asarray(jt), np.asarray(tt)
            flop = gflop * batch * (1 if pname == "fwd" else (3 if input_grad else 2))
            rows.append({
                "layer": name, "pass": pname, "description": desc,
                "jax_ms": float(np.median(jt) * 1e3), "torch_ms": float(np.median(tt) * 1e3),
                "jax_gflops": flop / float(np.median(jt)) if flop else float("nan"),
                "torch_gflops": flop / float(np.median(tt)) if flop else float("nan"),
                "ratio": float(np.median(tt / jt)),
            })
    return rows


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
    parser.add_argument("--batch", type=int, default=256, help="batch size (default 256)")
    parser.add_argument("--repeats", type=int, default=7, help="interleaved rounds")
    parser.add_argument("--out", default=None, help="also write the table to this file")
    args = parser.parse_args(argv)
    if args.batch < 1 or args.repeats < 1:
        parser.error("--batch and --repeats must be >= 1")
    from rp_jax import platform

    # configure_cpu's XLA flag and allocator, on one device (set before JAX starts).
    flags = os.environ.get("XLA_FLAGS", "")
    if "ynn_fusion_type" not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} {platform.YNN_FLAG}".strip()
    platform.tune_malloc()
    load = os.getloadavg()[0]
    rows = profile_layers(args.batch, args.repeats)
    table = format_table(rows, args.batch, args.repeats)
    table += f"\n\nLoad average (1 min) before -> after: {load:.1f} -> {os.getloadavg()[0]:.1f}."
    print(table)
    if args.out:
        Path(args.out).write_text(table + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
