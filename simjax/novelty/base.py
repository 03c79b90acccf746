"""What every novelty model shares: per-environment memory, the sequence timeline, normalisation.

A novelty model sees the rollout as a *timeline* per environment: the last ``M`` frames and
actions it kept from earlier rollouts, then the rollout's T frames and actions, then the frame
after the rollout. Along the timeline's first axis (length ``M + T + 1``)::

    index      0 ... M-1 | M ...... M+T-1 | M+T
    frame      o_{-M} ... | o_0 .... o_{T-1} | o_T      (o_T is the next rollout's o_0)
    action     a_{-M} ... | a_0 .... a_{T-1} |          (a_i is taken at frame i)

The transition of rollout step t (frame t, action a_t, next frame t+1) is scored by its *target
frame* e = M + 1 + t, so there are T targets, e = M+1 ... M+T. A window of a target reaches
back to frame e - k for an offset k <= M + 1. ``in_episode(tl, k)`` says, per target, whether
frame e - k belongs to the target's episode: frames from an earlier episode (or from before
the first reset, which memory marks invalid) are masked, the same mask in bonus and loss.
A target that is an episode's first frame (its transition crossed an auto-reset, so the frame
the action led to was never seen) gets no bonus and no loss.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np


class Memory(NamedTuple):
    """The last ``M`` frames and actions of each environment, kept across rollouts."""

    frames: jnp.ndarray  # (M, N, H, W, C), the observations' dtype (uint8 for our tasks)
    actions: jnp.ndarray  # (M, N) int32
    reset: jnp.ndarray  # (M, N) bool, frame starts an episode
    valid: jnp.ndarray  # (M, N) bool, false until a real frame has filled the slot


class Timeline(NamedTuple):
    frames: jnp.ndarray  # (M+T+1, N, H, W, C), the observations' dtype
    actions: jnp.ndarray  # (M+T, N) int32
    segment: jnp.ndarray  # (M+T+1, N) int32, episode number along the timeline
    valid: jnp.ndarray  # (M+T+1, N) bool
    history: int  # M

    @property
    def num_targets(self) -> int:
        return self.frames.shape[0] - self.history - 1


def init_memory(history: int, num_envs: int, obs_shape, dtype=jnp.uint8) -> Memory:
    m, n = history, num_envs
    return Memory(
        frames=jnp.zeros((m, n) + tuple(obs_shape), dtype),
        actions=jnp.zeros((m, n), jnp.int32),
        reset=jnp.ones((m, n), bool),
        valid=jnp.zeros((m, n), bool),
    )


def build_timeline(memory: Memory, obs, reset, actions, last_obs, last_reset) -> tuple[Timeline, Memory]:
    """The timeline of one rollout (obs/reset/actions (T, N, ...), last_obs the frame after it)
    and the memory the next rollout starts from (the M frames before ``last_obs``)."""
    m = memory.frames.shape[0]
    t = obs.shape[0]
    frames = jnp.concatenate([memory.frames, obs, last_obs[None]], axis=0)
    acts = jnp.concatenate([memory.actions, actions.astype(jnp.int32)], axis=0)
    resets = jnp.concatenate([memory.reset, reset, last_reset[None]], axis=0)
    valid = jnp.concatenate([memory.valid, jnp.ones((t + 1,) + reset.shape[1:], bool)], axis=0)
    segment = jnp.cumsum(resets.astype(jnp.int32), axis=0)
    pad = jnp.zeros((1,) + acts.shape[1:], jnp.int32)  # o_T's action is not yet taken
    new_memory = Memory(
        frames=frames[t : t + m],
        actions=jnp.concatenate([acts, pad], axis=0)[t : t + m],
        reset=resets[t : t + m],
        valid=valid[t : t + m],
    )
    return Timeline(frames, acts, segment, valid, m), new_memory


def shifted(x: jnp.ndarray, history: int, num_targets: int, k: int) -> jnp.ndarray:
    """``x`` at index e - k for every target e = M+1 ... M+T: (T, ...)."""
    start = history + 1 - k
    if start < 0:
        raise ValueError(f"offset {k} reaches before the timeline (history {history})")
    return x[start : start + num_targets]


def in_episode(tl: Timeline, k: int) -> jnp.ndarray:
    """(T, N) bool: frame e - k is a real frame of target e's episode."""
    m, t = tl.history, tl.num_targets
    return shifted(tl.valid, m, t, k) & (shifted(tl.segment, m, t, k) == shifted(tl.segment, m, t, 0))


def spread(targets) -> float:
    """Half the summed variance of prediction targets (B, D) over their B samples: the error of
    a model that predicts their mean, the scale a prediction-error bonus has among them."""
    return float(0.5 * np.var(np.asarray(targets), axis=0).sum())


def masked_mean(x: jnp.ndarray, mask: jnp.ndarray) -> jnp.ndarray:
    mask = mask.astype(x.dtype)
    return jnp.sum(x * mask) / jnp.maximum(jnp.sum(mask), 1.0)


class RunningMeanStd(NamedTuple):
    """Running mean and variance (Chan et al.'s parallel update), elementwise over ``shape``."""

    mean: jnp.ndarray
    var: jnp.ndarray
    count: jnp.ndarray

    @staticmethod
    def create(shape=()) -> RunningMeanStd:
        return RunningMeanStd(jnp.zeros(shape, jnp.float32), jnp.ones(shape, jnp.float32), jnp.zeros((), jnp.float32))

    def update(self, batch: jnp.ndarray, mask: jnp.ndarray | None = None) -> RunningMeanStd:
        """Fold in ``batch`` (..., *shape): every leading axis is a sample axis. With ``mask`` (the
        leading axes' shape), only the samples where it is true; a batch with none changes nothing."""
        x = batch.astype(jnp.float32).reshape((-1,) + self.mean.shape)
        if mask is None:
            n = jnp.float32(x.shape[0])
            b_mean, b_var = jnp.mean(x, axis=0), jnp.var(x, axis=0)
        else:
            w = mask.astype(jnp.float32).reshape((-1,) + (1,) * self.mean.ndim)
            n = jnp.sum(w)
            b_mean = jnp.sum(x * w, axis=0) / jnp.maximum(n, 1.0)
            b_var = jnp.sum(w * (x - b_mean) ** 2, axis=0) / jnp.maximum(n, 1.0)
        total = self.count + n
        safe = jnp.maximum(total, 1.0)  # total itself whenever a sample has been folded in
        delta = b_mean - self.mean
        mean = self.mean + delta * n / safe
        m2 = self.var * self.count + b_var * n + delta**2 * self.count * n / safe
        return RunningMeanStd(mean, jnp.where(total > 0, m2 / safe, self.var), total)


def normalize_frames(frames: jnp.ndarray, stats: RunningMeanStd | None) -> jnp.ndarray:
    """Frames -> float: per-pixel (x - mean) / std clipped to [-5, 5] (RND), or else ``to_unit``."""
    x = frames.astype(jnp.float32)
    if stats is None:
        return to_unit(frames)
    return jnp.clip((x - stats.mean) / jnp.sqrt(stats.var + 1e-8), -5.0, 5.0)


def to_unit(frames: jnp.ndarray) -> jnp.ndarray:
    """uint8 pixels / 255; observations of any other dtype (gymnax's floats) as they are."""
    x = frames.astype(jnp.float32)
    return x / 255.0 if frames.dtype == jnp.uint8 else x


def discounted_filter(running: jnp.ndarray, rewards: jnp.ndarray, gamma: float):
    """RND's running discounted sum of intrinsic rewards per env (never reset): (N,), (T, N)."""

    def step(acc, r):
        acc = gamma * acc + r
        return acc, acc

    return jax.lax.scan(step, running, rewards)
