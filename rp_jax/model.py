"""The repeatability predictor (RP) network of Sec. III-B, as pure Flax Linen modules.

Input per interest point: its 64x64x3 patch, its normalised image coordinates (R^2) and the
encoded capture time (R^d, see ``time_encoding``). The paper gives the fully connected part
exactly: fc1 (64, relu), fc2 (32, relu), fc3 (64, relu), fc4 (32, relu), fc5 (64, relu),
generalized-mean (GeM) pooling of the outputs z1, z2, z3 of fc1, fc3, fc5

    z = [ (z1^p + z2^p + z3^p) / 3 ]^(1/p),  p learnable,

then fc6 (D, sigmoid) with D = T, the number of timestamps. The paper does not give the
patch encoder; ours is designed for a CPU (see ``PatchEncoder``).

``params`` is a plain pytree and ``RepeatabilityPredictor.apply`` a pure function, so the
model composes with ``jax.jit``, ``jax.vmap`` and ``jax.grad`` in users' own code.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp

__all__ = ["gem_pool", "GeM", "Conv1", "CONV1_PATHS", "PatchEncoder", "RepeatabilityPredictor",
           "space_to_depth", "conv1_kernel_on_image", "create_model", "init_params",
           "preprocess_patches"]

GEM_EPS = 1e-6


def gem_pool(zs: jnp.ndarray, p: jnp.ndarray | float, axis: int = 0) -> jnp.ndarray:
    """Generalized mean over ``axis``: (mean z^p)^(1/p) (Radenovic et al.; Sec. III-B).

    p = 1 is the arithmetic mean; p -> inf tends to the maximum. Inputs are clamped at a
    small epsilon because z^p needs z > 0 (the pooled layers are ReLU outputs).
    """
    zs = jnp.maximum(zs, GEM_EPS)
    # Computed relative to the max for numerical range at large p: max * (mean (z/max)^p)^(1/p).
    zmax = jnp.max(zs, axis=axis, keepdims=True)
    mean = jnp.mean((zs / zmax) ** p, axis=axis)
    return jnp.squeeze(zmax, axis) * mean ** (1.0 / p)


class GeM(nn.Module):
    """GeM pooling over a stack of feature vectors with a learnable exponent p >= 1.

    p is kept valid during training by construction: p = 1 + softplus(rho), rho free.
    """

    init_p: float = 3.0

    @nn.compact
    def __call__(self, zs: jnp.ndarray) -> jnp.ndarray:
        if self.init_p <= 1.0:
            raise ValueError(f"GeM init_p must be > 1, got {self.init_p}")
        rho0 = jnp.log(jnp.expm1(self.init_p - 1.0))  # softplus^-1(init_p - 1)
        rho = self.param("rho", lambda _: jnp.asarray(rho0, jnp.float32))
        return gem_pool(zs, self.p_from(rho), axis=0)

    @staticmethod
    def p_from(rho: jnp.ndarray) -> jnp.ndarray:
        return 1.0 + jax.nn.softplus(rho)


def space_to_depth(x: jnp.ndarray, block: int) -> jnp.ndarray:
    """[B, H, W, C] -> [B, H/b, W/b, b*b*C], a reshape (no arithmetic)."""
    b, h, w, c = x.shape
    x = x.reshape(b, h // block, block, w // block, block, c)
    return x.transpose(0, 1, 3, 2, 4, 5).reshape(b, h // block, w // block, block * block * c)


CONV1_PATHS = ("image", "space_to_depth")


def conv1_kernel_on_image(kernel: jnp.ndarray, block: int = 4) -> jnp.ndarray:
    """conv1's [3, 3, b*b*C, O] kernel over the space-to-depth map as the equivalent
    [3b, 3b, C, O] kernel over the image (stride b): channel (r, s, c) of block (i, j)
    is pixel (b*i + r, b*j + s), colour c (the channel order of ``space_to_depth``)."""
    kh, kw, cin, cout = kernel.shape
    c = cin // (block * block)
    k = kernel.reshape(kh, kw, block, block, c, cout).transpose(0, 2, 1, 3, 4, 5)
    return k.reshape(kh * block, kw * block, c, cout)


class Conv1(nn.Module):
    """The encoder's first layer: a 3x3 "SAME" convolution over the 4x4 space-to-depth map
    of the patch, with ``nn.Conv``'s parameters (``kernel`` [3, 3, 48, O], ``bias`` [O]).

    ``path`` chooses how it is computed; both give the same function of the same
    parameters (up to float rounding):

    * ``"image"``: one 12x12, stride-4 convolution over the 64x64x3 patch itself, with the
      kernel rearranged (``conv1_kernel_on_image``) and 4 pixels (one block) of zero padding
      on each side. XLA:CPU then never materialises the space-to-depth transpose (a slow
      copy with a 3-float inner dimension), forwards or in the weight gradient.
    * ``"space_to_depth"``: the reshape-transpose to 16x16x48, then ``nn.Conv``'s 3x3
      convolution (the original formulation).
    """

    features: int
    path: str = "image"
    block: int = 4
    dtype: jnp.dtype = jnp.float32

    @nn.compact
    def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
        if self.path not in CONV1_PATHS:
            raise ValueError(f"conv1 path must be one of {CONV1_PATHS}, got {self.path!r}")
        cin = self.block * self.block * x.shape[-1]
        kernel = self.param("kernel", nn.initializers.lecun_normal(),
                            (3, 3, cin, self.features), jnp.float32)
        bias = self.param("bias", nn.initializers.zeros_init(), (self.features,), jnp.float32)
        x, kernel, bias = nn.dtypes.promote_dtype(x, kernel, bias, dtype=self.dtype)
        dn = ("NHWC", "HWIO", "NHWC")
        if self.path == "image":
            pad = (self.block, self.block)
            y = jax.lax.conv_general_dilated(
                x, conv1_kernel_on_image(kernel, self.block), (self.block, self.block),
                (pad, pad), dimension_numbers=dn)
        else:
            y = jax.lax.conv_general_dilated(
                space_to_depth(x, self.block), kernel, (1, 1), "SAME", dimension_numbers=dn)
        return y + bias


class PatchEncoder(nn.Module):
    """A small CNN for the 64x64x3 patch, shaped for CPU throughput.

    The strided first layer of a usual CNN is replaced by a 4x4 space-to-depth (a free
    reshape to 16x16x48), so every convolution runs on small spatial maps with channel
    counts that are multiples of 16 (vector-friendly); the last map (4x4) is flattened, not
    averaged, so the encoder keeps *where* in the patch a structure lies (the keypoint is at
    the centre). ``conv1_path`` picks how the first layer is computed (see ``Conv1``; same
    function, same parameters).
    """

    channels: Sequence[int] = (64, 64, 128)
    features: int = 128
    dtype: jnp.dtype = jnp.float32
    conv1_path: str = "image"

    @nn.compact
    def __call__(self, patches: jnp.ndarray) -> jnp.ndarray:
        x = patches.astype(self.dtype)
        for i, ch in enumerate(self.channels):
            if i == 0:  # 64x64x3 -> 16x16xch, through the 16x16x48 space-to-depth map
                x = Conv1(ch, self.conv1_path, 4, self.dtype, name="conv1")(x)
            else:
                x = nn.Conv(ch, (3, 3), strides=(2, 2), padding="SAME", dtype=self.dtype,
                            name=f"conv{i + 1}")(x)
            x = nn.relu(x)
        x = x.reshape(x.shape[0], -1)
        return nn.relu(nn.Dense(self.features, dtype=self.dtype, name="proj")(x))


class RepeatabilityPredictor(nn.Module):
    """RP of Sec. III-B: patch, coordinates and time -> T repeatability scores in (0, 1).

    Attributes:
      num_timestamps: D = T, the length of the repeatability vector.
      encoder_channels, encoder_features: the patch encoder's size.
      gem_init_p: initial GeM exponent.
      dtype: computation dtype of the patch encoder (float32 or bfloat16); the fc layers and
        the output are float32.
      conv1_path: how the encoder's first layer is computed, ``"image"`` (default) or
        ``"space_to_depth"``: the same function of the same parameters (see ``Conv1``).
    """

    num_timestamps: int
    encoder_channels: Sequence[int] = (64, 64, 128)
    encoder_features: int = 128
    gem_init_p: float = 3.0
    dtype: jnp.dtype = jnp.float32
    conv1_path: str = "image"

    @nn.compact
    def __call__(self, patches: jnp.ndarray, xy: jnp.ndarray, time: jnp.ndarray) -> jnp.ndarray:
        """Args: patches [B,64,64,3] float in [0,1] (or centred), xy [B,2] in [0,1], time [B,d].

        Returns: [B, T] float32 repeatability scores.
        """
        feat = PatchEncoder(self.encoder_channels, self.encoder_features, self.dtype,
                            self.conv1_path, name="patch_encoder")(patches).astype(jnp.float32)
        h = jnp.concatenate([feat, xy.astype(jnp.float32), time.astype(jnp.float32)], axis=-1)
        z1 = nn.relu(nn.Dense(64, name="fc1")(h))
        h = nn.relu(nn.Dense(32, name="fc2")(z1))
        z2 = nn.relu(nn.Dense(64, name="fc3")(h))
        h = nn.relu(nn.Dense(32, name="fc4")(z2))
        z3 = nn.relu(nn.Dense(64, name="fc5")(h))
        z = GeM(self.gem_init_p, name="gem")(jnp.stack([z1, z2, z3], axis=0))
        return nn.sigmoid(nn.Dense(self.num_timestamps, name="fc6")(z))


DTYPES = {"float32": jnp.float32, "bfloat16": jnp.bfloat16}


def create_model(config, num_timestamps: int) -> RepeatabilityPredictor:
    """The RP network of Sec. III-B sized by ``config.model`` (the run's config).

    Args:
      config: a config with a ``model`` group (``rp_jax/configs/default.py``):
        ``encoder_channels``, ``encoder_features``, ``gem_init_p``, ``dtype``.
      num_timestamps: T, the length of the output.
    """
    if config.model.dtype not in DTYPES:
        raise ValueError(f"config.model.dtype must be one of {sorted(DTYPES)}, "
                         f"got {config.model.dtype!r}")
    return RepeatabilityPredictor(
        num_timestamps=num_timestamps,
        encoder_channels=tuple(config.model.encoder_channels),
        encoder_features=config.model.encoder_features,
        gem_init_p=config.model.gem_init_p,
        dtype=DTYPES[config.model.dtype],
    )


def init_params(net: RepeatabilityPredictor, rng, num_time_features: int) -> dict:
    """Initial ``params`` of ``net`` for a time input of ``num_time_features`` (d) values.

    Under ``jax.eval_shape`` it gives the params' shapes without computing anything (what a
    checkpoint is restored into). Compiled as one program (the same parameters, bit for
    bit): run op by op, ``init``'s forward pass compiles every operation of every layer on
    its own; a process's first initialisation of the default model took 5.9-7.6 s of CPU
    that way against 3.2-3.8 s, backend start included (2-core AMD EPYC). One program per
    network and ``d`` in a process: a second initialisation of an equal network (a resumed
    or repeated run, another seed) reuses it instead of tracing, lowering and compiling
    again (1.3-1.5 s of CPU each time for a small network without a compilation cache, 2-core
    AMD EPYC; 0.01 s reused). A network that cannot be hashed (an attribute given as a
    list) is compiled for the call alone.
    """
    try:
        hash(net)
    except TypeError:
        return jax.jit(functools.partial(_init_fn, net, num_time_features=num_time_features))(rng)
    return _init(net, rng, num_time_features)


def _init_fn(net: RepeatabilityPredictor, rng, num_time_features: int) -> dict:
    return net.init(rng, jnp.zeros((1, 64, 64, 3)), jnp.zeros((1, 2)),
                    jnp.zeros((1, num_time_features)))["params"]


_init = jax.jit(_init_fn, static_argnums=(0, 2))


def preprocess_patches(patches: jnp.ndarray) -> jnp.ndarray:
    """uint8 [0, 255] patches -> float32 centred at 0 (what the network sees)."""
    return patches.astype(jnp.float32) / 255.0 - 0.5
