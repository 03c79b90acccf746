"""Flax modules: shapes, the im2col convolution, the LSTM reset."""

import functools
import re

import chex
import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import flat_draw

from simjax.networks import ActorCritic, Encoder
from simjax.networks.layers import (
    PatchConv,
    conv_stack,
    drawn_as_matrix,
    extract_patches,
    from_chwn,
    max_pool,
    orthogonal,
    to_chwn,
)


@pytest.mark.parametrize("layout", ["NHWC", "CHWN"])
@pytest.mark.parametrize("kernel,stride,padding,size", [(3, 2, "SAME", 42), (3, 2, "SAME", 21), (8, 4, "VALID", 42),
                                                        (4, 2, "VALID", 10), (3, 1, "VALID", 4), (3, 1, "SAME", 7),
                                                        (3, 1, "SAME", 2), (3, 2, "SAME", 2)])
def test_patch_conv_matches_flax_conv(kernel, stride, padding, size, layout):
    # maps smaller than the kernel (size 2) take the dense form in NHWC, EC's 2x2 stage
    x = flat_draw(jax.random.normal, jax.random.PRNGKey(0), (2, 3, size, size, 5))
    ref = nn.Conv(7, (kernel, kernel), strides=(stride, stride), padding=padding)
    params = ref.init(jax.random.PRNGKey(1), x)
    mine = PatchConv(7, kernel, stride, padding, layout=layout)
    mine_x = to_chwn(x) if layout == "CHWN" else x
    chex.assert_trees_all_equal(mine.init(jax.random.PRNGKey(1), mine_x), params)  # flax's values too
    out = mine.apply(params, mine_x)
    np.testing.assert_allclose(from_chwn(out) if layout == "CHWN" else out, ref.apply(params, x), atol=1e-5, rtol=1e-5)


def test_patches_and_max_pool_are_exactly_the_one_pass_forms():
    """extract_patches gathers along W, then H: the very array of one concatenation of the
    k*k windows in (ki, kj, c) order; max_pool is lax.reduce_window's max (inputs >= 0)."""
    x = flat_draw(jax.random.uniform, jax.random.PRNGKey(2), (2, 12, 9, 3))

    @functools.partial(jax.jit, static_argnums=(1, 2, 3, 4, 5))
    def both(x, k, s, pad_h, pad_w, out):
        padded = jnp.pad(x, [(0, 0), pad_h, pad_w, (0, 0)])
        views = [padded[:, i:i + s * (out[0] - 1) + 1:s, j:j + s * (out[1] - 1) + 1:s] for i in range(k) for j in range(k)]
        return jnp.concatenate(views, axis=-1), extract_patches(x, k, s, "SAME" if pad_h != (0, 0) else "VALID")

    for k, s, pad_h, pad_w, out in [(7, 2, (2, 3), (3, 3), (6, 5)), (3, 1, (1, 1), (1, 1), (12, 9)),
                                    (3, 2, (0, 0), (0, 0), (5, 4))]:
        one_pass, patches = both(x, k, s, pad_h, pad_w, out)
        chex.assert_shape(patches, (2, *out, k * k * 3))
        np.testing.assert_array_equal(patches, one_pass)
    relu = jnp.maximum(x - 0.5, 0.0)  # zeros and ties, as after a ReLU
    pooled = jax.jit(max_pool)(relu)
    ref = jax.lax.reduce_window(relu, -jnp.inf, jax.lax.max, (1, 3, 3, 1), (1, 2, 2, 1), [(0, 0), (0, 1), (1, 1), (0, 0)])
    chex.assert_shape(pooled, (2, 6, 5, 3))
    np.testing.assert_array_equal(pooled, ref)


def test_conv_kernels_drawn_as_a_matrix_are_the_initialisers_own_values():
    # PatchConv draws its kernel as the (k*k*c_in, features) matrix (XLA:CPU compiles that draw
    # faster): the same values for every initialiser the networks give it
    key = jax.random.PRNGKey(4)
    for init in (nn.initializers.lecun_normal(), nn.initializers.he_normal(), orthogonal(2**0.5),
                 nn.initializers.zeros_init()):
        for shape in ((3, 3, 2, 4), (1, 1, 4, 8)):
            np.testing.assert_array_equal(drawn_as_matrix(init)(key, shape), init(key, shape))
    glorot = nn.initializers.glorot_normal()  # fan-out is the matrix's: the one kind that differs
    assert not np.array_equal(drawn_as_matrix(glorot)(key, (3, 3, 2, 4)), glorot(key, (3, 3, 2, 4)))


def test_conv_stack_names_its_layers_and_matches_flax_convs_written_out():
    class Stack(nn.Module):
        @nn.compact
        def __call__(self, x):
            return conv_stack(x, (6, 4), kernel=(4, 3), stride=(2, 1), padding="VALID", activation=nn.elu)

    class Written(nn.Module):
        @nn.compact
        def __call__(self, x):
            x = nn.elu(nn.Conv(6, (4, 4), strides=(2, 2), padding="VALID", name="PatchConv_0")(x))
            return nn.elu(nn.Conv(4, (3, 3), padding="VALID", name="PatchConv_1")(x))

    x = flat_draw(jax.random.normal, jax.random.PRNGKey(0), (3, 2, 12, 12, 2))
    params = Written().init(jax.random.PRNGKey(1), x)
    chex.assert_trees_all_equal(Stack().init(jax.random.PRNGKey(1), x), params)
    out = Stack().apply(params, x)
    chex.assert_shape(out, (3, 2, 3, 3, 4))
    np.testing.assert_allclose(out, Written().apply(params, x), atol=1e-5, rtol=1e-5)


def test_encoder_and_actor_critic_shapes():
    T, N, A = 5, 3, 4
    obs = flat_draw(jax.random.randint, jax.random.PRNGKey(0), (T, N, 42, 42, 3), 0, 256).astype(jnp.uint8)
    reset = jnp.zeros((T, N), bool)
    enc = Encoder()
    emb = enc.apply(enc.init(jax.random.PRNGKey(0), obs), obs)
    chex.assert_shape(emb, (T, N, 256))
    net = ActorCritic(num_actions=A)
    carry = net.initial_carry(N)
    params = net.init(jax.random.PRNGKey(0), carry, obs, reset)
    kernels = jax.tree.map(jnp.shape, params["params"])
    assert kernels["Encoder_0"]["PatchConv_0"]["kernel"] == (3, 3, 3, 16)
    assert kernels["Encoder_0"]["PatchConv_1"]["kernel"] == (3, 3, 16, 32)
    assert kernels["Encoder_0"]["Dense_0"]["kernel"] == (11 * 11 * 32, 256)
    carry2, logits, value = net.apply(params, carry, obs, reset)
    chex.assert_shape(logits, (T, N, A))
    chex.assert_shape(value, (T, N))
    chex.assert_shape(carry2, ((N, 256), (N, 256)))
    chex.assert_tree_all_finite((carry2, logits, value))


def test_lstm_carry_is_reset_where_an_episode_starts():
    T, N = 6, 2
    obs = flat_draw(jax.random.randint, jax.random.PRNGKey(0), (T, N, 42, 42, 3), 0, 256).astype(jnp.uint8)
    net = ActorCritic(num_actions=4)
    params = net.init(jax.random.PRNGKey(0), net.initial_carry(N), obs, jnp.zeros((T, N), bool))
    noisy = jax.tree.map(lambda c: jax.random.normal(jax.random.PRNGKey(2), c.shape), net.initial_carry(N))
    reset = jnp.zeros((T, N), bool).at[3, 0].set(True)  # env 0 starts a new episode at t=3
    _, logits, _ = net.apply(params, noisy, obs, reset)
    # env 0 from t=3 on must equal a run that starts fresh at t=3; env 1 must not
    _, fresh, _ = net.apply(params, net.initial_carry(N), obs[3:], jnp.zeros((T - 3, N), bool))
    np.testing.assert_allclose(logits[3:, 0], fresh[:, 0], atol=1e-6)
    assert not np.allclose(logits[3:, 1], fresh[:, 1], atol=1e-6)
    # and before the reset, env 0 still carried its (noisy) memory
    _, from_zero, _ = net.apply(params, net.initial_carry(N), obs[:3], jnp.zeros((3, N), bool))
    assert not np.allclose(logits[:3, 0], from_zero[:, 0], atol=1e-6)


def test_orthogonal_draws_flax_values_member_by_member_under_vmap():
    # the XLA:CPU hang: flax's initialiser, vmapped over seeds, is one batched LAPACK QR per
    # matrix, and two of those side by side deadlocked jaxlib 0.10.2's thread pool
    keys = jax.random.split(jax.random.PRNGKey(3), 3)
    for shape, scale in (((256, 64), 1.0), ((8, 32), 0.01)):
        vmapped = jax.jit(jax.vmap(functools.partial(orthogonal(scale), shape=shape)))
        one_by_one = np.stack([nn.initializers.orthogonal(scale)(k, shape) for k in keys])
        np.testing.assert_array_equal(vmapped(keys), one_by_one)
        qr_batch_dims = [re.search(r'num_batch_dims = "(\d+)"', line).group(1)
                         for line in vmapped.lower(keys).as_text().splitlines() if "lapack_sgeqrf" in line]
        assert qr_batch_dims == ["0"], qr_batch_dims  # one QR, of one matrix at a time


def test_on_a_cpu_highest_high_and_default_precision_compute_what_jax_default_does():
    """--precision's default (highest) keeps the numbers a CPU computed before there was the
    setting (JAX's default): the policy's gradient is the same to the bit at each."""
    from simjax import runtime

    if jax.default_backend() != "cpu":
        pytest.skip("a GPU computes float32 matmuls in TF32 at high and default")
    T, N = 3, 2
    obs = flat_draw(jax.random.randint, jax.random.PRNGKey(0), (T, N, 42, 42, 3), 0, 256).astype(jnp.uint8)
    reset = jnp.zeros((T, N), bool)
    net = ActorCritic(num_actions=4)
    params = net.init(jax.random.PRNGKey(0), net.initial_carry(N), obs, reset)

    def loss(p):
        _, logits, value = net.apply(p, net.initial_carry(N), obs, reset)
        return jnp.sum(jax.nn.log_softmax(logits) * jnp.arange(4)) + jnp.sum(value ** 2)

    grad = jax.jit(jax.grad(loss))  # the precision is part of jit's key: traced again under each
    assert jax.config.jax_default_matmul_precision is None
    base = grad(params)
    for name in ("highest", "high", "default"):
        with runtime.matmul_precision(name):
            chex.assert_trees_all_equal(grad(params), base)


def test_reset_lstm_is_flax_optimized_lstm_cell_with_its_parameters():
    """``ResetLSTM`` takes the input projection out of the scan; its parameters are flax's
    ``OptimizedLSTMCell``'s (names, shapes, initial values) and its outputs that cell's, step
    by step, with the carry zeroed at resets."""
    from simjax.networks.actor_critic import ResetLSTM

    T, N, D, H = 4, 3, 5, 8
    x = jax.random.normal(jax.random.PRNGKey(0), (T, N, D))
    reset = jnp.array([[1, 0, 0], [0, 1, 0], [0, 0, 0], [1, 0, 1]], bool)
    carry = ResetLSTM.initial_carry(N, H)
    lstm = ResetLSTM(H)
    params = lstm.init(jax.random.PRNGKey(1), carry, (x, reset))
    cell = nn.OptimizedLSTMCell(H, recurrent_kernel_init=orthogonal())
    flax_params = cell.init(jax.random.PRNGKey(1), carry, x[0])
    chex.assert_trees_all_equal_shapes_and_dtypes(params["params"]["OptimizedLSTMCell_0"], flax_params["params"])
    cell_params = {"params": params["params"]["OptimizedLSTMCell_0"]}
    (c, h), out = jax.jit(lstm.apply)(params, carry, (x, reset))
    want_c, want_h = carry
    for t in range(T):
        want_c, want_h = (jnp.where(reset[t][:, None], 0.0, v) for v in (want_c, want_h))
        (want_c, want_h), y = cell.apply(cell_params, (want_c, want_h), x[t])
        np.testing.assert_allclose(out[t], y, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(c, want_c, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(h, want_h, rtol=1e-5, atol=1e-6)
