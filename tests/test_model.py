"""Tests of rp_jax.model: GeM pooling and the predictor of Sec. III-B."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from rp_jax import model


def test_gem_is_mean_at_p1_and_tends_to_max():
    zs = jnp.asarray(np.random.default_rng(0).uniform(0.1, 2.0, (3, 64)), jnp.float32)
    np.testing.assert_allclose(model.gem_pool(zs, 1.0), zs.mean(0), rtol=1e-5)
    gaps = [float(jnp.abs(model.gem_pool(zs, p) - zs.max(0)).max())
            for p in (2.0, 10.0, 100.0, 1000.0)]
    assert all(b < a for a, b in zip(gaps, gaps[1:]))
    assert gaps[-1] < 0.01


def test_gem_exponent_stays_valid():
    assert float(model.GeM.p_from(jnp.asarray(-1e4))) >= 1.0
    gem = model.GeM(init_p=3.0)
    params = gem.init(jax.random.key(0), jnp.ones((3, 4)))
    np.testing.assert_allclose(model.GeM.p_from(params["params"]["rho"]), 3.0, rtol=1e-5)
    with pytest.raises(ValueError, match="init_p"):
        model.GeM(init_p=0.5).init(jax.random.key(0), jnp.ones((3, 4)))


def test_space_to_depth_is_a_reshape():
    x = jnp.arange(2 * 8 * 8 * 3, dtype=jnp.float32).reshape(2, 8, 8, 3)
    y = model.space_to_depth(x, 4)
    assert y.shape == (2, 2, 2, 48)
    np.testing.assert_array_equal(y[0, 1, 0].reshape(4, 4, 3), x[0, 4:8, 0:4])


def test_predictor_shapes_range_and_parameter_count():
    net = model.RepeatabilityPredictor(num_timestamps=21)
    x = jnp.zeros((5, 64, 64, 3))
    params = net.init(jax.random.key(0), x, jnp.zeros((5, 2)), jnp.zeros((5, 2)))["params"]
    y = net.apply({"params": params}, x, jnp.full((5, 2), 0.5), jnp.ones((5, 2)))
    assert y.shape == (5, 21)
    assert bool(jnp.all((y > 0) & (y < 1)))
    # The paper's fully connected sizes.
    sizes = {k: params[k]["kernel"].shape[1] for k in ("fc1", "fc2", "fc3", "fc4", "fc5", "fc6")}
    assert sizes == {"fc1": 64, "fc2": 32, "fc3": 64, "fc4": 32, "fc5": 64, "fc6": 21}
    count = sum(p.size for p in jax.tree.leaves(params))
    # By hand, default sizes, T = 21, d = 2 (weights + biases):
    # patch encoder (ours; the paper gives none), on the 16x16x48 space-to-depth input:
    #   conv1 3x3x48->64   27,648 + 64  =  27,712
    #   conv2 3x3x64->64   36,864 + 64  =  36,928  (stride 2: 8x8)
    #   conv3 3x3x64->128  73,728 + 128 =  73,856  (stride 2: 4x4)
    #   proj  4*4*128=2048->128  262,144 + 128 = 262,272        encoder 400,768
    # the paper's layers, on [128 patch features, 2 xy, 2 time] = 132 inputs:
    #   fc1 132->64 8,512; fc2 64->32 2,080; fc3 32->64 2,112; fc4 64->32 2,080;
    #   fc5 32->64 2,112; GeM p (rho) 1; fc6 64->21 1,365                 head 18,262
    # total 400,768 + 18,262 = 419,030
    assert count == 419_030


def test_bfloat16_encoder_keeps_float32_output():
    net = model.RepeatabilityPredictor(num_timestamps=4, dtype=jnp.bfloat16)
    x = jnp.zeros((2, 64, 64, 3))
    params = net.init(jax.random.key(0), x, jnp.zeros((2, 2)), jnp.zeros((2, 2)))
    assert net.apply(params, x, jnp.zeros((2, 2)), jnp.zeros((2, 2))).dtype == jnp.float32


def _both_conv1_paths(dtype=jnp.float32):
    kw = dict(num_timestamps=5, dtype=dtype)
    return (model.RepeatabilityPredictor(**kw),
            model.RepeatabilityPredictor(conv1_path="space_to_depth", **kw))


def test_conv1_on_the_image_is_the_space_to_depth_network():
    """The default conv1 (a 12x12 stride-4 convolution of the patch) computes the function
    of the original lax.conv path (space-to-depth, then a 3x3 convolution) with the same
    parameter tree and initial values: outputs and gradients agree to float rounding."""
    image, s2d = _both_conv1_paths()
    rng = np.random.default_rng(3)
    x = jnp.asarray(rng.uniform(-0.5, 0.5, (4, 64, 64, 3)), jnp.float32)
    xy, t = jnp.asarray(rng.uniform(0, 1, (4, 2)), jnp.float32), jnp.ones((4, 2))
    params = image.init(jax.random.key(0), x, xy, t)["params"]
    shapes = jax.eval_shape(s2d.init, jax.random.key(0), x, xy, t)["params"]
    assert jax.tree.map(jnp.shape, params) == jax.tree.map(jnp.shape, shapes)
    jax.tree.map(np.testing.assert_array_equal,  # conv1 starts from the same values
                 *(model.Conv1(8, path).init(jax.random.key(2), x[:1])
                   for path in model.CONV1_PATHS))
    np.testing.assert_allclose(image.apply({"params": params}, x, xy, t),
                               s2d.apply({"params": params}, x, xy, t), atol=1e-6)

    def grads(net):
        return jax.jit(jax.grad(lambda p: jnp.sum(net.apply({"params": p}, x, xy, t) ** 2)))(
            params)

    g_image, g_s2d = grads(image), grads(s2d)
    scale = max(float(jnp.max(jnp.abs(g))) for g in jax.tree.leaves(g_s2d))
    jax.tree.map(lambda a, b: np.testing.assert_allclose(a, b, atol=1e-5 * scale),
                 g_image, g_s2d)
    # The kernel rearrangement alone: one block's channel (r, s, c) is pixel (r, s), colour c.
    k = jnp.arange(3 * 3 * 48 * 2, dtype=jnp.float32).reshape(3, 3, 48, 2)
    k12 = model.conv1_kernel_on_image(k)
    assert k12.shape == (12, 12, 3, 2)
    np.testing.assert_array_equal(k12[4 * 2 + 1, 4 * 0 + 3, 2], k[2, 0, (1 * 4 + 3) * 3 + 2])


def test_conv1_paths_agree_in_bfloat16_and_reject_unknown_paths():
    image, s2d = _both_conv1_paths(jnp.bfloat16)
    x = jnp.asarray(np.random.default_rng(4).uniform(-0.5, 0.5, (3, 64, 64, 3)), jnp.float32)
    params = image.init(jax.random.key(1), x, jnp.zeros((3, 2)), jnp.ones((3, 2)))
    a = image.apply(params, x, jnp.zeros((3, 2)), jnp.ones((3, 2)))
    b = s2d.apply(params, x, jnp.zeros((3, 2)), jnp.ones((3, 2)))
    assert a.dtype == b.dtype == jnp.float32
    np.testing.assert_allclose(a, b, atol=2e-2)
    with pytest.raises(ValueError, match="conv1 path"):
        model.RepeatabilityPredictor(num_timestamps=2, conv1_path="im2col").init(
            jax.random.key(0), x, jnp.zeros((3, 2)), jnp.ones((3, 2)))


def test_init_params_compiles_once_per_network_and_time_size():
    def net(**kw):
        return model.RepeatabilityPredictor(num_timestamps=5, encoder_channels=(4, 4, 8),
                                            encoder_features=8, **kw)

    first = model.init_params(net(), jax.random.key(0), 3)
    programs = model._init._cache_size()
    # An equal network (a new object: a resumed or repeated run) and another key: no new program.
    again = model.init_params(net(), jax.random.key(0), 3)
    other = model.init_params(net(), jax.random.key(1), 3)
    assert model._init._cache_size() == programs
    jax.tree_util.tree_map(np.testing.assert_array_equal, first, again)
    assert not np.array_equal(first["fc6"]["kernel"], other["fc6"]["kernel"])
    # Another network or another time size is another program, with its own shapes.
    p = model.init_params(net(gem_init_p=2.0), jax.random.key(0), 3)["gem"]["rho"]
    np.testing.assert_allclose(model.GeM.p_from(p), 2.0, rtol=1e-6)
    assert model.init_params(net(), jax.random.key(0), 4)["fc1"]["kernel"].shape[0] == 8 + 2 + 4
    assert model._init._cache_size() == programs + 2
    # A network that cannot be hashed (channels as a list) still initialises, the same.
    listed = model.RepeatabilityPredictor(num_timestamps=5, encoder_channels=[4, 4, 8],
                                          encoder_features=8)
    jax.tree_util.tree_map(np.testing.assert_array_equal,
                           model.init_params(listed, jax.random.key(0), 3), first)
