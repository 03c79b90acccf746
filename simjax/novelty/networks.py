"""The novelty models' networks: the RND target and predictor, SIM, and ICM (paper appendix A).

Every convolution is a ``PatchConv`` (im2col + matmul): its gradient stays fast inside the
learner's ``lax.scan`` on XLA:CPU, where ``lax.conv``'s does not (see ``networks/layers.py``).
"""

from __future__ import annotations

from functools import partial

import chex
import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np

from simjax.networks.layers import Dense, conv_stack, matmul, orthogonal

SQRT2 = float(np.sqrt(np.float32(2.0)))  # float32's sqrt(2), in numpy: no computation on import


def _flatten(x: jnp.ndarray) -> jnp.ndarray:
    return x.reshape(x.shape[:-3] + (-1,))


class RNDTarget(nn.Module):
    """The fixed random target f*: conv 32 8x8 s4 -> conv 32 4x4 s2 -> conv 32 3x3 s1 -> fc 64,
    orthogonal init scale sqrt(2), zero biases (VALID padding, leaky ReLU as in RND's code).

    ``leaky_slope`` is the leaky ReLU's slope below zero: flax's default 0.01 in the runs; RND's
    code calls TensorFlow's ``leaky_relu``, whose default is 0.2, and the paper does not say
    (``experiments/spot_loudness.py --slopes`` measures what it changes)."""

    features: int = 64
    leaky_slope: float = 0.01

    @nn.compact
    def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
        init = orthogonal(SQRT2)
        activation = partial(nn.leaky_relu, negative_slope=self.leaky_slope)
        x = conv_stack(x, (32, 32, 32), (8, 4, 3), (4, 2, 1), "VALID", activation, init)
        return Dense(self.features, kernel_init=init)(_flatten(x))


class RNDPredictor(nn.Module):
    """RND's trained predictor: 4 conv 32 (3x3, s2, ReLU) -> fc 64."""

    features: int = 64

    @nn.compact
    def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
        return Dense(self.features)(_flatten(conv_stack(x, (32, 32, 32, 32))))


class FrameEmbedding(nn.Module):
    """SIM's f_e: conv 16 -> conv 32 (3x3, s2, ReLU) -> fc 256 (ReLU)."""

    features: int = 256

    @nn.compact
    def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
        return nn.relu(Dense(self.features)(_flatten(conv_stack(x, (16, 32)))))


class WindowLSTM(nn.Module):
    """An LSTM over short windows whose inputs are projected once per timeline entry.

    Windows overlap (H windows share a frame), so ``project`` (x W_ih, no bias) runs once per
    frame or action and ``__call__`` gathers the projections into windows and scans only
    h W_hh + b over them. Gates i, f, g, o as in flax's ``OptimizedLSTMCell``, with the same
    initialisers (lecun-normal input kernels, one orthogonal block per recurrent gate kernel).
    """

    hidden: int = 256

    def setup(self):
        self.input = Dense(4 * self.hidden, use_bias=False, name="input")

        def gate_blocks(key, shape, dtype=jnp.float32):
            # the four blocks drawn by one mapped draw (orthogonal's vmap maps member by member):
            # the values of four calls, compiled once
            blocks = jax.vmap(lambda k: orthogonal()(k, (shape[0], self.hidden), dtype))(jax.random.split(key, 4))
            return jnp.moveaxis(blocks, 0, 1).reshape(shape[0], 4 * self.hidden)

        self.recurrent = self.param("recurrent", gate_blocks, (self.hidden, 4 * self.hidden))
        self.bias = self.param("bias", nn.initializers.zeros, (4 * self.hidden,))

    def project(self, x: jnp.ndarray) -> jnp.ndarray:
        return self.input(x)

    def __call__(self, proj: jnp.ndarray, start: jnp.ndarray) -> jnp.ndarray:
        """Final hidden state (B, hidden) after the S steps of ``proj`` (S, B, 4 hidden); the
        carry is zeroed before step s where ``start[s]``."""

        def step(carry, xs):
            p, fresh = xs
            c, h = jax.tree.map(lambda v: jnp.where(fresh, jnp.zeros_like(v), v), carry)
            i, f, g, o = jnp.split(p + matmul(h, self.recurrent) + self.bias, 4, axis=-1)
            c = nn.sigmoid(f) * c + nn.sigmoid(i) * jnp.tanh(g)
            return (c, nn.sigmoid(o) * jnp.tanh(c)), None

        zeros = jnp.zeros(proj.shape[1:-1] + (self.hidden,), proj.dtype)
        (_, h), _ = jax.lax.scan(step, (zeros, zeros), (proj, start))
        return h


def gather_windows(values: jnp.ndarray, index: jnp.ndarray, mask: jnp.ndarray) -> jnp.ndarray:
    """values (M+T+1 or M+T, N, D) at index (T, S) -> (T, S, N, D), zero where not ``mask`` (T, S, N)."""
    return values[index] * mask[..., None].astype(values.dtype)


class SIMNet(nn.Module):
    """SIM's trained part (section 2, A.1) on a timeline of embedded-once frames.

    ``__call__(x (M+T+1, N, h, w, c), actions (M+T, N), windows)`` returns the frame embeddings
    (M+T+1, N, 256), the forward prediction (T, N, target_dim) and the inverse logits
    (T, N, H_max-1, |A|) (None when the inverse head is off). ``windows`` (``models.Windows``)
    says which frames and actions each target's window holds: for target e, frames
    e-L-H+1 ... e-L and actions e-L ... e-1, right-aligned in H_max and L_max slots; masked
    slots enter as zeros, and the LSTMs start at the first real slot, so a window laid out for
    larger H_max, L_max gives exactly what a model built for (H, L) gives.
    """

    num_actions: int
    obs_len: int  # H_max: frame slots per window
    act_len: int  # L_max: action slots per window
    combine: str = "full"  # full: [h^o, h^a, h^o*h^a]; itr: h^o*h^a; concat: [h^o, h^a]
    sequence: str = "lstm"  # lstm: two LSTMs over the windows; ff: fc 256 over the stacked window
    inverse: bool = True
    target_dim: int = 64
    hidden: int = 256

    @nn.compact
    def __call__(self, x, actions, windows):
        H, L, A = self.obs_len, self.act_len, self.num_actions
        M = H + L - 2
        T, n = x.shape[0] - M - 1, x.shape[1]
        chex.assert_shape(actions, (M + T, n))
        chex.assert_shape([windows.frame_index], (T, H))
        chex.assert_shape([windows.frame_mask], (T, H, n))
        chex.assert_shape([windows.action_index], (T, L))
        chex.assert_shape([windows.action_mask], (T, L, n))
        emb = FrameEmbedding(self.hidden)(x)  # every frame embedded once
        # one action embedding per action value: a table (A, 128), looked up per timeline step
        table = nn.relu(Dense(128, name="ActionEmbedding")(jnp.eye(A, dtype=jnp.float32)))
        if self.sequence == "lstm":
            frame_lstm, action_lstm = WindowLSTM(self.hidden, name="FrameLSTM"), WindowLSTM(self.hidden, name="ActionLSTM")
            h_o = self._last(frame_lstm, frame_lstm.project(emb), windows.frame_index, windows.frame_mask,
                             windows.frame_start)
            h_a = self._last(action_lstm, action_lstm.project(table)[actions], windows.action_index,
                             windows.action_mask, windows.action_start)
        elif self.sequence == "ff":
            frames = gather_windows(emb, windows.frame_index, windows.frame_mask)  # (T, H, N, 256)
            acts = gather_windows(table[actions], windows.action_index, windows.action_mask)
            h_o = nn.relu(Dense(self.hidden, name="FrameFF")(jnp.moveaxis(frames, 1, 2).reshape(T, n, -1)))
            h_a = nn.relu(Dense(self.hidden, name="ActionFF")(jnp.moveaxis(acts, 1, 2).reshape(T, n, -1)))
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
        prediction = Dense(self.target_dim, name="Forward")(h)
        logits = None
        if self.inverse:
            logits = Dense((H - 1) * A, name="Inverse")(h).reshape(T, n, H - 1, A)
        return emb, prediction, logits

    def _last(self, lstm: WindowLSTM, proj, index, mask, start) -> jnp.ndarray:
        """The LSTM's final hidden state over each target's window: (T, N, hidden)."""
        seq = gather_windows(proj, index, mask)  # (T, S, N, 4 hidden)
        T, S, N, D = seq.shape
        h = lstm(jnp.moveaxis(seq, 1, 0).reshape(S, T * N, D), start)
        return h.reshape(T, N, self.hidden)


def icm_features(stacks: jnp.ndarray) -> jnp.ndarray:
    """ICM's encoder phi, called inside a compact module: 4 conv 32 (3x3, s2, ELU) on 4 stacked
    grey frames, flattened (288 features from 42x42)."""
    return _flatten(conv_stack(stacks, (32, 32, 32, 32), activation=nn.elu))


class ICMEncoder(nn.Module):
    """``icm_features`` as a module of its own (E3B's phi)."""

    @nn.compact
    def __call__(self, stacks: jnp.ndarray) -> jnp.ndarray:
        return icm_features(stacks)


class InverseHead(nn.Module):
    """An inverse-dynamics head: fc 256 (ReLU) -> |A| logits on [phi_t, phi_{t+1}]."""

    num_actions: int

    @nn.compact
    def __call__(self, phi_t: jnp.ndarray, phi_next: jnp.ndarray) -> jnp.ndarray:
        g = nn.relu(Dense(256)(jnp.concatenate([phi_t, phi_next], axis=-1)))
        return Dense(self.num_actions)(g)


class ICMNet(nn.Module):
    """ICM (A.2): phi = 4 conv 32 (3x3, s2, ELU) on 4 stacked grey frames -> 288; forward fc 256
    -> fc 288 on [phi_t, one-hot a_t]; inverse fc 256 -> |A| on [phi_t, phi_{t+1}].

    ``__call__(stacks (T+1, N, 42, 42, 4), actions (T, N))`` -> (phi (T+1, N, 288), forward
    prediction of phi_{t+1} (T, N, 288), inverse logits (T, N, |A|)).
    """

    num_actions: int

    @nn.compact
    def __call__(self, stacks, actions):
        phi = icm_features(stacks)
        phi_t, phi_next = phi[:-1], phi[1:]
        a = jax.nn.one_hot(actions, self.num_actions)
        f = nn.relu(Dense(256, name="Forward_0")(jnp.concatenate([phi_t, a], axis=-1)))
        prediction = Dense(phi.shape[-1], name="Forward_1")(f)
        g = nn.relu(Dense(256, name="Inverse_0")(jnp.concatenate([phi_t, phi_next], axis=-1)))
        logits = Dense(self.num_actions, name="Inverse_1")(g)
        return phi, prediction, logits
