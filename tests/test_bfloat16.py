"""``--precision bfloat16``: the networks' products with bfloat16 operands and float32 sums.

Tolerances come from bfloat16's 8-bit significand: rounding a float32 to bfloat16 changes it by
at most u = 2^-9 of itself, so a product of two rounded operands is within 2u + u^2 < 2^-8 of
the exact product, and a sum of K such products, accumulated in float32 (at most K * 2^-24 of
the sum of magnitudes more), within (2^-8 + K 2^-24) * sum |a_k b_k| of the float32 dot: a
bound that holds element by element on every machine. A network chains D such products; each
adds an error of at most about 2^-8 of its output's size (the rounding errors of a sum of
random-signed terms are themselves random-signed, so they grow with its norm, not its absolute
sum), ReLU, sigmoid and tanh do not amplify it, so a network's output is within about D 2^-8
of its norm; the tests allow twice that, D 2^-7, and check that the error is not zero (the
bfloat16 path ran).
"""

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import random_rollout

from simjax import runtime
from simjax.envs import make
from simjax.networks import ActorCritic
from simjax.networks.layers import matmul, matmul_operands, operand_dtype
from simjax.novelty import ICM, SIM, build_timeline, init_memory
from simjax.novelty.ec import ReachabilityNet
from simjax.novelty.networks import ICMNet, RNDPredictor, RNDTarget

A = 4
U8 = 2.0 ** -8  # 2u + u^2 rounded up: one product of two bfloat16-rounded operands


def test_matmul_and_its_gradient_products_are_within_the_bfloat16_bound():
    M, K, N = 37, 300, 21
    a = jax.random.normal(jax.random.PRNGKey(0), (M, K))
    b = jax.random.normal(jax.random.PRNGKey(1), (K, N))
    g = jax.random.normal(jax.random.PRNGKey(2), (M, N))

    def products(a, b):
        out, vjp = jax.vjp(matmul, a, b)
        return (out, *vjp(g))

    exact_abs = [np.abs(np.asarray(x, np.float64)) for x in (a, b, g)]
    bounds = [exact_abs[0] @ exact_abs[1], exact_abs[2] @ exact_abs[1].T, exact_abs[0].T @ exact_abs[2]]
    reference = [np.asarray(x, np.float64) for x in (a @ b, g @ b.T, a.T @ g)]
    contracted = [K, N, M]
    with matmul_operands(jnp.bfloat16):
        got = jax.jit(products)(a, b)
        hlo = jax.jit(products).lower(a, b).as_text()
    for x, ref, bound, k in zip(got, reference, bounds, contracted, strict=True):
        chex.assert_type(x, jnp.float32)
        err = np.abs(np.asarray(x, np.float64) - ref)
        assert np.all(err <= (U8 + k * 2.0 ** -24) * bound + 1e-30), float(np.max(err / bound))
        assert np.max(err) > 0  # rounded: the bfloat16 path ran
    assert hlo.count("bf16") >= 6, "the three products take bfloat16 operands"
    with matmul_operands(jnp.float32):  # float32 operands: the plain product
        np.testing.assert_array_equal(jax.jit(products)(a, b)[0], jax.jit(lambda a, b: a @ b)(a, b))


def test_products_of_operands_bfloat16_holds_exactly_are_summed_exactly_in_float32():
    """Integers 1-15 are bfloat16 numbers and their products float32 ones, and every partial sum
    here is an integer below 2^24: a float32 sum of them is exact, in any order. A sum kept in
    bfloat16 (8 significant bits: integers above 256 lose their last bits), or a float32 sum
    rounded to bfloat16 at the end, is not: these sums reach 10^4-10^5."""
    M, K, N = 400, 600, 300  # each of the three products contracts one of them
    a = jax.random.randint(jax.random.PRNGKey(0), (M, K), 1, 16).astype(jnp.float32)
    b = jax.random.randint(jax.random.PRNGKey(1), (K, N), 1, 16).astype(jnp.float32)
    g = jax.random.randint(jax.random.PRNGKey(2), (M, N), 1, 16).astype(jnp.float32)
    with matmul_operands(jnp.bfloat16):
        out, vjp = jax.jit(lambda a, b: jax.vjp(matmul, a, b))(a, b)
        da, db = jax.jit(vjp)(g)
    a64, b64, g64 = (np.asarray(x, np.int64) for x in (a, b, g))
    for got, want in ((out, a64 @ b64), (da, g64 @ b64.T), (db, a64.T @ g64)):
        assert want.max() > 2**13 and want.max() < 2**24
        np.testing.assert_array_equal(np.asarray(got, np.float64), want)


def test_the_operand_setting_is_scoped_and_checked():
    assert operand_dtype() == jnp.float32
    with runtime.matmul_precision("bfloat16"):
        assert operand_dtype() == jnp.bfloat16
        with runtime.matmul_precision("highest"):
            assert operand_dtype() == jnp.float32
        assert operand_dtype() == jnp.bfloat16
    assert operand_dtype() == jnp.float32
    with pytest.raises(ValueError, match="float32 or bfloat16"):
        with matmul_operands(jnp.float16):
            pass


@pytest.fixture(scope="module")
def batch():
    """Random-action frames of maze-dense, (T+1, N, 42, 42, 3) uint8, and their timeline."""
    return random_rollout(make("maze-dense"), jax.random.PRNGKey(0), T=6, N=2, num_actions=A)


def _timeline(batch, history):
    obs, reset, actions, last_obs, last_reset = batch
    tl, _ = build_timeline(init_memory(history, obs.shape[1], obs.shape[2:]), obs, reset, actions, last_obs, last_reset)
    return tl


def _from_timeline(batch, history, read):
    """``read(timeline)`` of the batch's timeline, in one compiled program (op by op, each
    slice of the timeline would compile a program of its own)."""
    return jax.jit(lambda *b: read(_timeline(b, history)))(*batch)


def _policy(batch):
    obs, reset = batch[0], batch[1]
    net = ActorCritic(num_actions=A)
    carry = net.initial_carry(obs.shape[1])
    params = jax.jit(net.init)(jax.random.PRNGKey(0), carry, obs, reset)
    return params, lambda p: net.apply(p, carry, obs, reset)[1:]  # logits, value


def _rnd(module):
    def build(batch):
        frames = batch[0].astype(jnp.float32) / 255.0
        net = module()
        return jax.jit(net.init)(jax.random.PRNGKey(0), frames), lambda p: net.apply(p, frames)
    return build


def _sim(batch):
    model = SIM(A, obs_len=3, act_len=2)
    x, actions, windows = _from_timeline(batch, model.history,
                                         lambda tl: (tl.frames.astype(jnp.float32) / 255.0, tl.actions, model.windows(tl)))
    net = model.net()
    return jax.jit(net.init)(jax.random.PRNGKey(0), x, actions, windows), lambda p: net.apply(p, x, actions, windows)


def _icm(batch):
    stacks = _from_timeline(batch, ICM(A).history, ICM(A).stacks)
    net = ICMNet(A)
    actions = batch[2]
    return jax.jit(net.init)(jax.random.PRNGKey(0), stacks, actions), lambda p: net.apply(p, stacks, actions)


def _ec(batch):
    frames = batch[0][:2].astype(jnp.float32) / 255.0
    net = ReachabilityNet(width=8, features=32, hidden=32)

    def run(p):
        e = net.apply(p, frames, method=ReachabilityNet.embed)
        a, b = net.apply(p, e, method=ReachabilityNet.halves)
        return e, net.apply(p, a[0], b[1], method=ReachabilityNet.head)

    return jax.jit(net.init)(jax.random.PRNGKey(0), frames[0], frames[0]), run


# name: (builder, D: the most bfloat16 products chained on a path to an output)
NETWORKS = {
    "policy": (_policy, 3 + 1 + 6),  # conv, conv, fc; the LSTM's input projection and its 6 recurrent steps
    "rnd-target": (_rnd(RNDTarget), 4),
    "rnd-predictor": (_rnd(RNDPredictor), 5),
    "sim": (_sim, 3 + 1 + 3 + 1),  # embedding; the LSTM's projection and H = 3 steps; forward (or inverse) fc
    "icm": (_icm, 4 + 2),
    "ec": (_ec, 1 + 16 + 1 + 2),  # ResNet-18: stem, 16 block convs (shortcuts run beside), fc; the head's 2 fc
}


@pytest.mark.parametrize("name", sorted(NETWORKS))
def test_each_network_in_bfloat16_agrees_with_float32_and_keeps_float32_at_its_boundaries(name, batch):
    build, depth = NETWORKS[name]
    params, apply = build(batch)
    chex.assert_tree_all_finite(params)
    def grad_of(p):  # of the outputs' sum, as a loss that weighs every output entry alike
        return jax.grad(lambda p: sum(jnp.sum(x) for x in jax.tree.leaves(apply(p))))(p)

    f32, f32_grads = jax.jit(apply)(params), jax.jit(grad_of)(params)
    with runtime.matmul_precision("bfloat16"):
        bf16 = jax.jit(apply)(params)
        grads = jax.jit(grad_of)(params)
    chex.assert_trees_all_equal_shapes_and_dtypes(bf16, f32)
    chex.assert_type(jax.tree.leaves(bf16), jnp.float32)
    chex.assert_trees_all_equal_shapes_and_dtypes(grads, params)  # params and their gradients: float32
    chex.assert_tree_all_finite((bf16, grads))
    for x16, x32 in zip(jax.tree.leaves(bf16), jax.tree.leaves(f32), strict=True):
        x16, x32 = np.asarray(x16, np.float64), np.asarray(x32, np.float64)
        rel = np.linalg.norm(x16 - x32) / np.linalg.norm(x32)
        assert 0 < rel <= depth * 2.0 ** -7, (name, rel, depth * 2.0 ** -7)
    # a parameter's gradient runs the forward's D products to the output and back through at most
    # D transposed ones: 2 D chained products, so 2 D 2^-7 normwise over all the parameters (one
    # small parameter alone can be off by more where a ReLU flips under the rounding)
    g16, g32 = (np.concatenate([np.asarray(x, np.float64).ravel() for x in jax.tree.leaves(g)]) for g in (grads, f32_grads))
    rel = np.linalg.norm(g16 - g32) / np.linalg.norm(g32)
    assert 0 < rel <= 2 * depth * 2.0 ** -7, (name, rel, 2 * depth * 2.0 ** -7)


def test_a_jitted_function_is_traced_again_when_the_operands_change():
    """jit's cache keys on JAX's matmul precision, which ``matmul_operands`` sets with the
    operand dtype: one jitted function called under both never reuses the other's program."""
    from simjax.networks.layers import BFLOAT16_JAX_PRECISION

    assert runtime.MATMUL_PRECISIONS["bfloat16"] == BFLOAT16_JAX_PRECISION
    a = jax.random.normal(jax.random.PRNGKey(0), (8, 16))
    f = jax.jit(lambda a: matmul(a, a.T))
    with matmul_operands(jnp.bfloat16):
        rounded = f(a)
    with matmul_operands(jnp.float32):
        plain = f(a)
    with runtime.matmul_precision("bfloat16"):
        again = f(a)
    np.testing.assert_array_equal(plain, a @ a.T)
    np.testing.assert_array_equal(again, rounded)
    assert not np.array_equal(rounded, plain)
