"""The LSTM actor-critic of LSTM-A3C (paper appendix A.5).

obs uint8 (42, 42, 3) -> conv 16 (3x3, s2) -> conv 32 (3x3, s2) -> fc 256 -> LSTM 256 ->
{value (fc 1), policy logits (fc |A|)}. Any image size works (the encoder reads it from the
observation); a flat observation vector (a gymnax CartPole's (4,)) skips the convolutions. The module consumes whole time-major sequences
(T, N, ...): the encoder runs once over all T*N frames (one large batch is what a CPU does
well), then the LSTM is scanned over time, its carry zeroed wherever ``reset`` marks the first
step of an episode. Acting is the same call with T = 1, so acting and learning share one path.
"""

from __future__ import annotations

import functools

import chex
import flax.linen as nn
import jax
import jax.numpy as jnp

from simjax.networks.layers import conv_stack, orthogonal


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
        return nn.relu(nn.Dense(self.features)(x))


class ResetLSTM(nn.Module):
    """An LSTM scanned over time (axis 0) whose carry is zeroed where ``reset`` is true."""

    features: int = 256

    @functools.partial(
        nn.scan, variable_broadcast="params", split_rngs={"params": False}, in_axes=0, out_axes=0
    )
    @nn.compact
    def __call__(self, carry, inputs):
        x, reset = inputs
        carry = jax.tree.map(lambda c: jnp.where(reset[:, None], jnp.zeros_like(c), c), carry)
        carry, h = nn.OptimizedLSTMCell(self.features, recurrent_kernel_init=orthogonal())(carry, x)
        return carry, h

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
