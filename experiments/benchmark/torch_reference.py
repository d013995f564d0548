"""The repeatability predictor of Sec. III-B written again in PyTorch: the benchmark's peer.

``TorchRepeatabilityPredictor`` is the SAME network as ``rp_jax.model.RepeatabilityPredictor``
(space-to-depth patch encoder, fc1..fc5, GeM over fc1/fc3/fc5, fc6 sigmoid), written the way
a PyTorch user would (NCHW convolutions), so that the benchmark compares frameworks, not
architectures. ``load_flax_params`` copies a Flax ``params`` tree into it; the layout
conversions are written here, once:

* Space-to-depth: the Flax model reshapes NHWC [B, 64, 64, 3] to [B, 16, 4, 16, 4, 3] and
  orders the 48 output channels as (row in block, column in block, colour). The same
  reshape is done here on NHWC input before moving channels first, so channel k means the
  same in both.
* Convolution kernels: Flax HWIO [3, 3, in, out] -> PyTorch OIHW [out, in, 3, 3].
* ``padding="SAME"`` with stride 2 on an even map pads 0 before and 1 after (XLA puts the
  odd pixel at the end); PyTorch's symmetric ``padding=1`` would shift the sampling grid,
  so strided layers pad explicitly with ``F.pad(x, (0, 1, 0, 1))``.
* Flatten: Flax flattens the NHWC 4x4x128 map in (h, w, c) order; the NCHW map is permuted
  back to NHWC before flattening so the ``proj`` kernel is used unchanged (transposed to
  PyTorch's [out, in]).
* Dense kernels: Flax [in, out] -> ``nn.Linear.weight`` [out, in].

``train_step`` is the peer of ``rp_jax.train.train_step``: the masked MSE of Sec. III-C,
global-norm gradient clipping and one AdamW step, with the patch preprocessing and the
cyclic time-of-day encoding (``rp_jax.time_encoding``) done inside the step as in ours.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Mapping

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

__all__ = [
    "GEM_EPS",
    "TorchRepeatabilityPredictor",
    "autocast_context",
    "encode_time_of_day",
    "load_flax_params",
    "make_optimizer",
    "masked_mse",
    "preprocess_patches",
    "train_step",
]

GEM_EPS = 1e-6  # rp_jax.model.GEM_EPS


def space_to_depth_nhwc(x: torch.Tensor, block: int) -> torch.Tensor:
    """[B, H, W, C] -> [B, H/b, W/b, b*b*C] in the channel order of ``rp_jax.model``."""
    b, h, w, c = x.shape
    x = x.reshape(b, h // block, block, w // block, block, c)
    return x.permute(0, 1, 3, 2, 4, 5).reshape(b, h // block, w // block, block * block * c)


def gem_pool(zs: torch.Tensor, p: torch.Tensor) -> torch.Tensor:
    """Generalized mean over the first axis, computed as ``rp_jax.model.gem_pool`` does."""
    zs = torch.clamp(zs, min=GEM_EPS)
    zmax = torch.amax(zs, dim=0, keepdim=True)
    mean = torch.mean((zs / zmax) ** p, dim=0)
    return zmax.squeeze(0) * mean ** (1.0 / p)


class TorchRepeatabilityPredictor(nn.Module):
    """RP of Sec. III-B in PyTorch; forward takes the inputs of the Flax model.

    Args:
      num_timestamps: T, the output size.
      time_features: d, the length of the time vector.
      encoder_channels: widths of the three convolutions.
      encoder_features: the patch-encoder output size.
      gem_init_p: initial GeM exponent.
    """

    def __init__(
        self,
        num_timestamps: int,
        time_features: int = 2,
        encoder_channels=(64, 64, 128),
        encoder_features: int = 128,
        gem_init_p: float = 3.0,
    ):
        super().__init__()
        c1, c2, c3 = encoder_channels
        self.conv1 = nn.Conv2d(48, c1, 3, stride=1, padding=1)
        self.conv2 = nn.Conv2d(c1, c2, 3, stride=2, padding=0)
        self.conv3 = nn.Conv2d(c2, c3, 3, stride=2, padding=0)
        self.proj = nn.Linear(4 * 4 * c3, encoder_features)
        self.fc1 = nn.Linear(encoder_features + 2 + time_features, 64)
        self.fc2 = nn.Linear(64, 32)
        self.fc3 = nn.Linear(32, 64)
        self.fc4 = nn.Linear(64, 32)
        self.fc5 = nn.Linear(32, 64)
        self.fc6 = nn.Linear(64, num_timestamps)
        self.rho = nn.Parameter(
            torch.tensor(math.log(math.expm1(gem_init_p - 1.0)), dtype=torch.float32)
        )

    def encode(self, patches: torch.Tensor) -> torch.Tensor:
        """The patch encoder: [B, 64, 64, 3] float (NHWC, centred) -> [B, encoder_features]."""
        x = space_to_depth_nhwc(patches, 4).permute(0, 3, 1, 2)  # NCHW [B, 48, 16, 16]
        x = F.relu(self.conv1(x))
        x = F.relu(self.conv2(F.pad(x, (0, 1, 0, 1))))  # XLA "SAME", stride 2: pad after only
        x = F.relu(self.conv3(F.pad(x, (0, 1, 0, 1))))
        x = x.permute(0, 2, 3, 1).reshape(x.shape[0], -1)  # flatten in Flax's (h, w, c) order
        return F.relu(self.proj(x))

    def forward(self, patches: torch.Tensor, xy: torch.Tensor, time: torch.Tensor) -> torch.Tensor:
        """patches [B, 64, 64, 3] float (NHWC, centred), xy [B, 2], time [B, d] -> [B, T]."""
        h = torch.cat([self.encode(patches), xy, time], dim=-1)
        z1 = F.relu(self.fc1(h))
        z2 = F.relu(self.fc3(F.relu(self.fc2(z1))))
        z3 = F.relu(self.fc5(F.relu(self.fc4(z2))))
        p = 1.0 + F.softplus(self.rho)
        z = gem_pool(torch.stack([z1, z2, z3], dim=0), p)
        return torch.sigmoid(self.fc6(z))


def load_flax_params(
    module: TorchRepeatabilityPredictor, params: Mapping
) -> TorchRepeatabilityPredictor:
    """Copy a Flax ``params`` tree of ``RepeatabilityPredictor`` into ``module`` (in place).

    Raises:
      ValueError: a parameter's shape does not fit (a model of another size).
    """
    enc = params["patch_encoder"]

    def put(target: torch.Tensor, value, name: str) -> None:
        value = torch.from_numpy(np.array(value, dtype=np.float32))
        if tuple(target.shape) != tuple(value.shape):
            raise ValueError(
                f"parameter {name}: PyTorch expects {tuple(target.shape)}, "
                f"the Flax tree gives {tuple(value.shape)}"
            )
        with torch.no_grad():
            target.copy_(value)

    for i, conv in enumerate((module.conv1, module.conv2, module.conv3), start=1):
        layer = enc[f"conv{i}"]
        put(conv.weight, np.transpose(np.asarray(layer["kernel"]), (3, 2, 0, 1)), f"conv{i}.kernel")
        put(conv.bias, layer["bias"], f"conv{i}.bias")
    put(module.proj.weight, np.asarray(enc["proj"]["kernel"]).T, "proj.kernel")
    put(module.proj.bias, enc["proj"]["bias"], "proj.bias")
    for name in ("fc1", "fc2", "fc3", "fc4", "fc5", "fc6"):
        lin = getattr(module, name)
        put(lin.weight, np.asarray(params[name]["kernel"]).T, f"{name}.kernel")
        put(lin.bias, params[name]["bias"], f"{name}.bias")
    put(module.rho, params["gem"]["rho"], "gem.rho")
    return module


def preprocess_patches(patches: torch.Tensor) -> torch.Tensor:
    """uint8 [0, 255] -> float32 centred at 0, as ``rp_jax.model.preprocess_patches``."""
    return patches.to(torch.float32) / 255.0 - 0.5


def encode_time_of_day(hour: torch.Tensor, minute: torch.Tensor) -> torch.Tensor:
    """The cyclic time-of-day encoding of ``rp_jax.time_encoding`` (sin, cos): [B, 2]."""
    angle = 2 * math.pi * (hour.to(torch.float32) * 60.0 + minute.to(torch.float32)) / 1440.0
    return torch.stack([torch.sin(angle), torch.cos(angle)], dim=-1)


def masked_mse(pred, label, label_mask, example_mask) -> torch.Tensor:
    """(1/N) sum_i sum_j m_ij (y_ij - y_hat_ij)^2 over valid examples (``rp_jax.losses.mse``)."""
    em = example_mask.to(torch.float32)
    m = label_mask.to(torch.float32) * em[:, None]
    return torch.sum(m * (pred - label) ** 2) / torch.clamp(torch.sum(em), min=1.0)


def make_optimizer(
    module: nn.Module, learning_rate: float, weight_decay: float
) -> torch.optim.Optimizer:
    """AdamW with optax's defaults (b1 0.9, b2 0.999, eps 1e-8) and decay on every parameter."""
    return torch.optim.AdamW(
        module.parameters(),
        lr=learning_rate,
        betas=(0.9, 0.999),
        eps=1e-8,
        weight_decay=weight_decay,
    )


def autocast_context(enabled: bool):
    """``torch.autocast("cpu", dtype=torch.bfloat16)`` when ``enabled`` (PyTorch's mixed
    precision on a CPU: convolutions and linear layers in bfloat16), else a no-op."""
    if enabled:
        return torch.autocast("cpu", dtype=torch.bfloat16)
    return contextlib.nullcontext()


def train_step(
    module: nn.Module,
    optimizer: torch.optim.Optimizer,
    batch: Mapping[str, torch.Tensor],
    grad_clip: float = 1.0,
    autocast: bool = False,
) -> torch.Tensor:
    """One AdamW step on the masked MSE; the peer of ``rp_jax.train.train_step``.

    Args:
      module: a ``TorchRepeatabilityPredictor`` (or its ``torch.compile`` wrapper).
      optimizer: from ``make_optimizer``.
      batch: tensors ``patch`` uint8 [B,64,64,3], ``xy_normalized``, ``hour``, ``minute``,
        ``label``, ``label_mask``, ``mask``.
      grad_clip: global-norm clipping threshold.
      autocast: forward and loss under bfloat16 autocast (``autocast_context``); the
        backward pass follows the forward's dtypes, the parameters stay float32.

    Returns:
      The loss before the step (a 0-d tensor).
    """
    optimizer.zero_grad(set_to_none=True)
    with autocast_context(autocast):
        pred = module(
            preprocess_patches(batch["patch"]),
            batch["xy_normalized"],
            encode_time_of_day(batch["hour"], batch["minute"]),
        )
        loss = masked_mse(pred.float(), batch["label"], batch["label_mask"], batch["mask"])
    loss.backward()
    torch.nn.utils.clip_grad_norm_(module.parameters(), grad_clip)
    optimizer.step()
    return loss.detach()
