"""SIM, RND and ICM behind one small interface.

A model is a frozen dataclass with
    history                       frames/actions each environment keeps across rollouts (M)
    init(key, tl, x) -> params    tl: a Timeline, x: its frames normalised (``base``)
    apply(params, tl, x, hyper=None, targets=None) -> (error (T, N), scored (T, N) bool, loss, metrics)
``hyper`` (a ``NoveltyHyper``, traced when a sweep varies it) gives the values a model may run
with instead of its own: lambda, and SIM's H and L. ``targets`` (T, N) bool, if given, limits
the transitions ``loss`` averages over to those it marks (A3C's pieces of a rollout, cut at
episode ends: ``simjax.agents.a3c``); ``error``, ``scored`` and ``metrics`` do not change.
``error`` is the per-transition novelty before scaling (the bonus is beta * error where
``scored``, 0 elsewhere); ``loss`` is the model's share of eq. (8), lambda * L_F + (1 - lambda)
* L_I, already weighted; ``metrics`` holds ``forward_loss`` and ``inverse_loss``.
Target parameters are kept under ``params["target"]`` and only ever seen through
``stop_gradient``, so the optimiser never moves them.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import jax
import jax.numpy as jnp

from simjax.novelty.base import Timeline, in_episode, masked_mean, to_unit
from simjax.novelty.networks import ICMNet, RNDPredictor, RNDTarget, SIMNet


def half_squared_error(prediction, target):
    """eq. (5)/(6) without beta: 1/2 ||target - prediction||^2 over the last axis."""
    return 0.5 * jnp.sum(jnp.square(target - prediction), axis=-1)


@dataclasses.dataclass(frozen=True)
class RND:
    """Random network distillation (A.3): predict a fixed random network's output on o_{t+1}."""

    num_actions: int
    history: int = 1

    def init(self, key, tl: Timeline, x):
        k_t, k_p = jax.random.split(key)
        frames = x[tl.history + 1 :]
        return {"target": RNDTarget().init(k_t, frames), "predictor": RNDPredictor().init(k_p, frames)}

    def apply(self, params, tl: Timeline, x, hyper=None, targets=None):
        frames = x[tl.history + 1 :]  # the target frames o_1 ... o_T
        target = jax.lax.stop_gradient(RNDTarget().apply(params["target"], frames))
        error = half_squared_error(RNDPredictor().apply(params["predictor"], frames), target)
        scored = in_episode(tl, 1)
        forward = masked_mean(error, scored)
        loss = forward if targets is None else masked_mean(error, scored & targets)
        return error, scored, loss, {"forward_loss": forward, "inverse_loss": jnp.zeros(())}


class Windows(NamedTuple):
    """Where each window slot of each target reads the timeline. Windows are laid out for
    ``H_max`` frames and ``L_max`` actions, right-aligned: for lengths (H, L) the last H frame
    slots and the last L action slots are real, the others padding.

    frame_index  (T, H_max) int32    timeline index of frame slot j (oldest first)
    frame_mask   (T, H_max, N) bool  the slot is real and its frame is in the target's episode
    frame_start  (H_max,) bool       the LSTM starts afresh at this slot: every padding slot and
                                     the first real one, so padding never reaches the real steps
    action_index, action_mask, action_start: the same for the L_max action slots
    """

    frame_index: jnp.ndarray
    frame_mask: jnp.ndarray
    frame_start: jnp.ndarray
    action_index: jnp.ndarray
    action_mask: jnp.ndarray
    action_start: jnp.ndarray


def in_episode_at(tl: Timeline, index: jnp.ndarray) -> jnp.ndarray:
    """(T, S, N) bool: timeline entry index[t, s] is a real frame of target t's episode."""
    targets = tl.segment[tl.history + 1 :]  # (T, N)
    return tl.valid[index] & (tl.segment[index] == targets[:, None])


@dataclasses.dataclass(frozen=True)
class SIM:
    """The sequence-level novelty model (section 2, A.1) and its ablations (section 3.5).

    target "rnd": f*(o_t) is the fixed RND target; "embed" (SIM-no-RND): stop_gradient f_e(o_t).
    sequence "lstm" / "ff" (SIM-no-Seq); combine "full" / "itr" / "concat"; inverse on/off.
    ``obs_len`` and ``act_len`` are the window sizes the model is laid out for; ``apply`` takes
    the H and L it runs with (at most those; traced, so one compiled program serves a sweep
    over them) from ``hyper``, and by default the full sizes. The settings are checked where
    they are given (``NoveltySettings``), not here.
    """

    num_actions: int
    obs_len: int = 10  # H (the largest H when H is swept)
    act_len: int = 3  # L (the largest L when L is swept)
    combine: str = "full"
    sequence: str = "lstm"
    target: str = "rnd"
    inverse: bool = True
    forward_weight: float = 0.2  # lambda

    @property
    def history(self) -> int:
        return self.obs_len + self.act_len - 2

    def net(self) -> SIMNet:
        return SIMNet(
            num_actions=self.num_actions, obs_len=self.obs_len, act_len=self.act_len,
            combine=self.combine, sequence=self.sequence, inverse=self.inverse,
            target_dim=64 if self.target == "rnd" else 256,
        )

    def windows(self, tl: Timeline, obs_len=None, act_len=None) -> Windows:
        """The windows of the rollout's targets for H = ``obs_len``, L = ``act_len`` (int or
        traced int32; default the full sizes). Target e's frame slot j holds frame
        e - L - (H_max - 1 - j), its action slot i action e - (L_max - i)."""
        h_max, l_max = self.obs_len, self.act_len
        H = h_max if obs_len is None else obs_len
        L = l_max if act_len is None else act_len
        e = tl.history + 1 + jnp.arange(tl.num_targets)[:, None]  # (T, 1)
        j, i = jnp.arange(h_max), jnp.arange(l_max)
        frame_index = e - L - (h_max - 1 - j)  # >= L_max - L >= 0: the timeline holds H_max + L_max - 2 old frames
        action_index = e - (l_max - i)
        frame_real, action_real = j >= h_max - H, i >= l_max - L
        return Windows(
            frame_index=frame_index, frame_mask=in_episode_at(tl, frame_index) & frame_real[:, None],
            frame_start=j <= h_max - H,
            action_index=action_index, action_mask=in_episode_at(tl, action_index) & action_real[:, None],
            action_start=i <= l_max - L,
        )

    def init(self, key, tl: Timeline, x):
        k_t, k_s = jax.random.split(key)
        params = {"sim": self.net().init(k_s, x, tl.actions, self.windows(tl))}
        if self.target == "rnd":
            params["target"] = RNDTarget().init(k_t, x[tl.history + 1 :])
        return params

    def apply(self, params, tl: Timeline, x, hyper=None, targets=None):
        """``hyper`` (optional): ``obs_len``, ``act_len`` and ``forward_weight`` to run with."""
        w = self.windows(tl, *((hyper.obs_len, hyper.act_len) if hyper is not None else (None, None)))
        lam = self.forward_weight if hyper is None else hyper.forward_weight
        emb, prediction, logits = self.net().apply(params["sim"], x, tl.actions, w)
        if self.target == "rnd":
            target = RNDTarget().apply(params["target"], x[tl.history + 1 :])
        else:
            target = emb[tl.history + 1 :]
        error = half_squared_error(prediction, jax.lax.stop_gradient(target))
        # scored: the window's newest frame, o_{t-L}, is in o_t's episode (so o_t is no reset frame)
        scored = w.frame_mask[:, -1]
        forward = masked_mean(error, scored)
        counted = scored if targets is None else scored & targets  # the transitions the loss averages over
        if self.inverse:
            # the actions taken at the window's frames but the last: (T, N, H_max - 1)
            labels = jnp.moveaxis(tl.actions[w.frame_index[:, :-1]], 1, 2)
            log_p = jax.nn.log_softmax(logits)
            ce = -jnp.take_along_axis(log_p, labels[..., None], axis=-1)[..., 0]
            inverse_mask = jnp.moveaxis(w.frame_mask[:, :-1], 1, 2)
            inverse = masked_mean(ce, inverse_mask & scored[..., None])
            if targets is None:
                loss = lam * forward + (1.0 - lam) * inverse
            else:
                loss = (lam * masked_mean(error, counted)
                        + (1.0 - lam) * masked_mean(ce, inverse_mask & counted[..., None]))
        else:
            inverse = jnp.zeros(())
            loss = lam * (forward if targets is None else masked_mean(error, counted))
        return error, scored, loss, {"forward_loss": forward, "inverse_loss": inverse}


def grey(frames: jnp.ndarray) -> jnp.ndarray:
    """Frames (..., h, w, c) -> grey (..., h, w) in [0, 1]: the channels' mean."""
    # added channel by channel: XLA:CPU ran jnp.mean over the 3-wide minor axis as a library
    # reduction, 10% of an ICM update
    x = to_unit(frames)
    return sum((x[..., c] for c in range(1, x.shape[-1])), x[..., 0]) / x.shape[-1]


def grey_stacks(tl: Timeline, stack: int) -> jnp.ndarray:
    """(T+1, N, h, w, stack) stacks of the last ``stack`` grey frames ending at each of frames
    M ... M+T (o_0 ... o_T), oldest first; frames before the episode's first are zero. Needs
    ``tl.history >= stack - 1``."""
    g = grey(tl.frames)  # (M+T+1, N, h, w)
    m, t = tl.history, tl.num_targets
    ends_seg = tl.segment[m:]
    layers = []
    for k in range(stack - 1, -1, -1):  # oldest first
        same = tl.valid[m - k : m - k + t + 1] & (tl.segment[m - k : m - k + t + 1] == ends_seg)
        layers.append(g[m - k : m - k + t + 1] * same[..., None, None])
    return jnp.stack(layers, axis=-1)


@dataclasses.dataclass(frozen=True)
class ICM:
    """The intrinsic curiosity module (A.2) on 4 stacked 42x42 grey frames.

    Frames before the episode's first are zero in the stack. As in ICM's code, the forward loss
    trains the features too (no stop-gradient on phi_{t+1}); the inverse loss keeps them from
    collapsing. ICM reads raw grey frames / 255 (its own preprocessing), not normalised ones;
    stacks are of whatever frame size the environment gives.
    """

    num_actions: int
    forward_weight: float = 0.2  # ICM's forward-inverse ratio
    stack: int = 4

    @property
    def history(self) -> int:
        return self.stack - 1

    def stacks(self, tl: Timeline) -> jnp.ndarray:
        """(T+1, N, 42, 42, stack) grey stacks ending at frames M ... M+T (o_0 ... o_T)."""
        return grey_stacks(tl, self.stack)

    def init(self, key, tl: Timeline, x):
        return {"icm": ICMNet(self.num_actions).init(key, self.stacks(tl), tl.actions[tl.history :])}

    def apply(self, params, tl: Timeline, x, hyper=None, targets=None):
        """``hyper`` (optional): the ``forward_weight`` to run with."""
        lam = self.forward_weight if hyper is None else hyper.forward_weight
        actions = tl.actions[tl.history :]  # a_0 ... a_{T-1}
        phi, prediction, logits = ICMNet(self.num_actions).apply(params["icm"], self.stacks(tl), actions)
        error = half_squared_error(prediction, phi[1:])
        scored = in_episode(tl, 1)
        forward = masked_mean(error, scored)
        ce = -jnp.take_along_axis(jax.nn.log_softmax(logits), actions[..., None], axis=-1)[..., 0]
        inverse = masked_mean(ce, scored)
        if targets is None:
            loss = lam * forward + (1.0 - lam) * inverse
        else:
            counted = scored & targets
            loss = lam * masked_mean(error, counted) + (1.0 - lam) * masked_mean(ce, counted)
        return error, scored, loss, {"forward_loss": forward, "inverse_loss": inverse}
