"""The novelty models' networks: the RND target and predictor, SIM, and ICM (paper appendix A).

Every convolution is a ``PatchConv`` (im2col + matmul): its gradient stays fast inside the
learner's ``lax.scan`` on XLA:CPU, where ``lax.conv``'s does not (see ``networks/layers.py``).
"""

from __future__ import annotations

import chex
import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np

from simjax.networks.actor_critic import ResetLSTM
from simjax.networks.layers import PatchConv, conv_stack

SQRT2 = float(np.sqrt(np.float32(2.0)))  # float32's sqrt(2), in numpy: no computation on import


def _flatten(x: jnp.ndarray) -> jnp.ndarray:
    return x.reshape(x.shape[:-3] + (-1,))


class RNDTarget(nn.Module):
    """The fixed random target f*: conv 32 8x8 s4 -> conv 32 4x4 s2 -> conv 32 3x3 s1 -> fc 64,
    orthogonal init scale sqrt(2), zero biases (VALID padding, leaky ReLU as in RND's code)."""

    features: int = 64

    @nn.compact
    def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
        init = nn.initializers.orthogonal(SQRT2)
        for kernel, stride in ((8, 4), (4, 2), (3, 1)):
            x = nn.leaky_relu(PatchConv(32, kernel, stride, "VALID", kernel_init=init)(x))
        return nn.Dense(self.features, kernel_init=init)(_flatten(x))


class RNDPredictor(nn.Module):
    """RND's trained predictor: 4 conv 32 (3x3, s2, ReLU) -> fc 64."""

    features: int = 64

    @nn.compact
    def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
        return nn.Dense(self.features)(_flatten(conv_stack(x, (32, 32, 32, 32))))


class FrameEmbedding(nn.Module):
    """SIM's f_e: conv 16 -> conv 32 (3x3, s2, ReLU) -> fc 256 (ReLU)."""

    features: int = 256

    @nn.compact
    def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
        return nn.relu(nn.Dense(self.features)(_flatten(conv_stack(x, (16, 32)))))


class SIMNet(nn.Module):
    """SIM's trained part (section 2, A.1) on a timeline of embedded-once frames.

    ``__call__(x (M+T+1, N, h, w, c), actions (M+T, N), frame_mask (T, H, N), action_mask
    (T, L, N))`` returns the frame embeddings (M+T+1, N, 256), the forward prediction (T, N,
    target_dim) and the inverse logits (T, N, H-1, |A|) (None when the inverse head is off).
    Target e's window is frames e-L-H+1 ... e-L (oldest first) and actions e-L ... e-1;
    masked slots are zeroed after embedding.
    """

    num_actions: int
    obs_len: int  # H
    act_len: int  # L
    combine: str = "full"  # full: [h^o, h^a, h^o*h^a]; itr: h^o*h^a; concat: [h^o, h^a]
    sequence: str = "lstm"  # lstm: two LSTMs over the windows; ff: fc 256 over the stacked window
    inverse: bool = True
    target_dim: int = 64
    hidden: int = 256

    @nn.compact
    def __call__(self, x, actions, frame_mask, action_mask):
        H, L, A = self.obs_len, self.act_len, self.num_actions
        M = H + L - 2
        T = x.shape[0] - M - 1
        chex.assert_shape(actions, (M + T,) + x.shape[1:2])
        chex.assert_shape([frame_mask], (T, H, x.shape[1]))
        chex.assert_shape([action_mask], (T, L, x.shape[1]))
        emb = FrameEmbedding(self.hidden)(x)  # every frame embedded once
        # windows of embeddings, gathered with static slices: (T, H, N, 256) and (T, L, N, A)
        frames = jnp.stack([emb[M + 1 - k : M + 1 - k + T] for k in range(L + H - 1, L - 1, -1)], axis=1)
        acts = jnp.stack([actions[M + 1 - k : M + 1 - k + T] for k in range(L, 0, -1)], axis=1)
        frames = frames * frame_mask[..., None]
        a_emb = nn.relu(nn.Dense(128, name="ActionEmbedding")(jax.nn.one_hot(acts, A))) * action_mask[..., None]
        n = x.shape[1]
        if self.sequence == "lstm":
            h_o = self._last_lstm(frames, "FrameLSTM")
            h_a = self._last_lstm(a_emb, "ActionLSTM")
        elif self.sequence == "ff":
            h_o = nn.relu(nn.Dense(self.hidden, name="FrameFF")(jnp.moveaxis(frames, 1, 2).reshape(T, n, -1)))
            h_a = nn.relu(nn.Dense(self.hidden, name="ActionFF")(jnp.moveaxis(a_emb, 1, 2).reshape(T, n, -1)))
        else:
            raise ValueError(f"unknown sequence model {self.sequence!r}")
        if self.combine == "full":
            h = jnp.concatenate([h_o, h_a, h_o * h_a], axis=-1)
        elif self.combine == "itr":
            h = h_o * h_a
        elif self.combine == "concat":
            h = jnp.concatenate([h_o, h_a], axis=-1)
        else:
            raise ValueError(f"unknown combination {self.combine!r}")
        prediction = nn.Dense(self.target_dim, name="Forward")(h)
        logits = None
        if self.inverse:
            logits = nn.Dense((H - 1) * A, name="Inverse")(h).reshape(T, n, H - 1, A)
        return emb, prediction, logits

    def _last_lstm(self, seq: jnp.ndarray, name: str) -> jnp.ndarray:
        """Final hidden state of an LSTM run over axis 1 of (T, S, N, D), batched over T*N."""
        T, S, N, D = seq.shape
        xs = jnp.moveaxis(seq, 1, 0).reshape(S, T * N, D)
        carry = ResetLSTM.initial_carry(T * N, self.hidden)
        (_, h), _ = ResetLSTM(self.hidden, name=name)(carry, (xs, jnp.zeros((S, T * N), bool)))
        return h.reshape(T, N, self.hidden)


class ICMNet(nn.Module):
    """ICM (A.2): phi = 4 conv 32 (3x3, s2, ELU) on 4 stacked grey frames -> 288; forward fc 256
    -> fc 288 on [phi_t, one-hot a_t]; inverse fc 256 -> |A| on [phi_t, phi_{t+1}].

    ``__call__(stacks (T+1, N, 42, 42, 4), actions (T, N))`` -> (phi (T+1, N, 288), forward
    prediction of phi_{t+1} (T, N, 288), inverse logits (T, N, |A|)).
    """

    num_actions: int

    @nn.compact
    def __call__(self, stacks, actions):
        x = stacks
        for _ in range(4):
            x = nn.elu(PatchConv(32, 3, 2)(x))
        phi = _flatten(x)
        phi_t, phi_next = phi[:-1], phi[1:]
        a = jax.nn.one_hot(actions, self.num_actions)
        f = nn.relu(nn.Dense(256, name="Forward_0")(jnp.concatenate([phi_t, a], axis=-1)))
        prediction = nn.Dense(phi.shape[-1], name="Forward_1")(f)
        g = nn.relu(nn.Dense(256, name="Inverse_0")(jnp.concatenate([phi_t, phi_next], axis=-1)))
        logits = nn.Dense(self.num_actions, name="Inverse_1")(g)
        return phi, prediction, logits
