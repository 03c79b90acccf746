"""The LSTM actor-critic of LSTM-A3C (paper appendix A.5).

obs uint8 (42, 42, 3) -> conv 16 (3x3, s2) -> conv 32 (3x3, s2) -> fc 256 -> LSTM 256 ->
{value (fc 1), policy logits (fc |A|)}. Any image size works (the encoder reads it from the
observation); a flat observation vector (a gymnax CartPole's (4,)) skips the convolutions. The module consumes whole time-major sequences
(T, N, ...): the encoder runs once over all T*N frames (one large batch is what a CPU does
well), then the LSTM is scanned over time, its carry zeroed wherever ``reset`` marks the first
step of an episode. Acting is the same call with T = 1, so acting and learning share one path.
"""

from __future__ import annotations

import chex
import flax.linen as nn
import jax
import jax.numpy as jnp
from flax.linen.recurrent import DenseParams

from simjax.networks.layers import Dense, conv_stack, matmul, orthogonal


class Encoder(nn.Module):
    """Frame embedding: conv 16 -> conv 32 (3x3, stride 2, ReLU) -> fc ``features`` (ReLU).

    ``image=False``: the observation is a vector, and only the fc layer is applied. uint8
    pixels are scaled by 1/255; float observations are taken as they are."""

    features: int = 256
    image: bool = True

    @nn.compact
    def __call__(self, obs: jnp.ndarray) -> jnp.ndarray:
        x = obs.astype(jnp.float32)
        if obs.dtype == jnp.uint8:
            x = x / 255.0
        if self.image:
            x = conv_stack(x, (16, 32))
            x = x.reshape(x.shape[:-3] + (-1,))
        return nn.relu(Dense(self.features)(x))


class OptimizedLSTMCell(nn.Module):
    """The parameters of flax's ``nn.OptimizedLSTMCell`` under its names (ii, if, ig, io: input
    kernels; hi, hf, hg, ho: recurrent kernels and the biases), with its initialisers, so
    checkpoints written with flax's cell load; returned concatenated in gate order i, f, g, o."""

    features: int

    @nn.compact
    def __call__(self, x: jnp.ndarray):
        gates = "ifgo"
        w_i = [DenseParams(self.features, use_bias=False, name=f"i{g}")(x)[0] for g in gates]
        h = jnp.zeros(x.shape[:-1] + (self.features,), x.dtype)
        recurrent = [DenseParams(self.features, kernel_init=orthogonal(), name=f"h{g}")(h) for g in gates]
        return (jnp.concatenate(w_i, axis=-1), jnp.concatenate([k for k, _ in recurrent], axis=-1),
                jnp.concatenate([b for _, b in recurrent], axis=-1))


class ResetLSTM(nn.Module):
    """An LSTM over time (axis 0) whose carry is zeroed where ``reset`` is true: flax's
    ``OptimizedLSTMCell`` (same gates, parameters and initialisers; tested) with the input
    projection x W_i taken once for all T*N inputs, one large product, and only h W_h + b in the
    scan over time."""

    features: int = 256

    @nn.compact
    def __call__(self, carry, inputs):
        x, reset = inputs
        w_i, w_h, bias = OptimizedLSTMCell(self.features)(x)
        projected = matmul(x, w_i)  # (T, N, 4 features)

        def step(carry, xs):
            p, fresh = xs
            c, h = jax.tree.map(lambda v: jnp.where(fresh[:, None], jnp.zeros_like(v), v), carry)
            i, f, g, o = jnp.split((matmul(h, w_h) + bias) + p, 4, axis=-1)  # flax's order of the sums
            c = nn.sigmoid(f) * c + nn.sigmoid(i) * jnp.tanh(g)
            h = nn.sigmoid(o) * jnp.tanh(c)
            return (c, h), h

        return jax.lax.scan(step, carry, (projected, reset))

    @staticmethod
    def initial_carry(batch: int, features: int = 256):
        zeros = jnp.zeros((batch, features), jnp.float32)
        return (zeros, zeros)


class ActorCritic(nn.Module):
    """``(carry, obs (T, N, H, W, C), reset (T, N)) -> (carry, logits (T, N, A), value (T, N))``;
    obs may also be vectors (T, N, D). With ``two_values`` the value is (T, N, 2): the task
    reward's and, from a head of its own (``IntrinsicValue``), the bonus's."""

    num_actions: int
    hidden: int = 256
    embed: int = 256
    two_values: bool = False

    @nn.compact
    def __call__(self, carry, obs: jnp.ndarray, reset: jnp.ndarray):
        chex.assert_rank(obs, {3, 5})
        chex.assert_equal_shape_prefix([obs, reset], 2)
        x = Encoder(self.embed, image=obs.ndim == 5)(obs)
        carry, h = ResetLSTM(self.hidden)(carry, (x, reset))
        logits = nn.Dense(self.num_actions, kernel_init=orthogonal(0.01))(h)
        value = nn.Dense(1, kernel_init=orthogonal(1.0))(h)[..., 0]
        if self.two_values:  # a separate head: one-value checkpoints keep their parameter names
            bonus_value = nn.Dense(1, kernel_init=orthogonal(1.0), name="IntrinsicValue")(h)
            value = jnp.stack([value, bonus_value[..., 0]], axis=-1)
        return carry, logits, value

    def initial_carry(self, batch: int):
        return ResetLSTM.initial_carry(batch, self.hidden)
