"""``Novelty``: the one object the learner is handed. It knows nothing of the learner either.

    params, state = novelty.init(key, obs)                      obs: (N, h, w, c), the first frames
    loss, (bonus, metrics, state) = novelty.loss_and_bonus(params, state, obs, reset, actions,
                                                           last_obs, last_reset, hyper=None)
``bonus`` (T, N) is r+ for each rollout transition, already scaled by beta and free of
gradients; ``loss`` is lambda * L_F + (1 - lambda) * L_I of eq. (8), to be added to eta times
the RL loss. ``state`` carries each environment's last frames and actions across rollouts and
the running statistics of the two normalisations, and a stateful model's own state (EC's
episodic memories, E3B's inverse covariances: ``model``; empty for the others):

* ``obs_norm`` (default on): the novelty networks see frames normalised per pixel by a running
  mean and std, clipped to [-5, 5], as in RND. A random target on raw pixels mostly encodes
  brightness, which barely changes in a maze; normalised, its features differ between places.
  ICM ignores it (its own preprocessing is grey / 255).
* ``bonus_norm`` (default off): divide the error by a running std of its discounted sum per
  environment, as in RND. Off by default because the paper's beta (0.001 for SIM, 0.01 for
  ICM and RND) scales unnormalised errors; with it on, beta is the scale of a unit-std bonus.
With no model (``algo=a2c``) the bonus is zero, the loss is zero and the params are empty.
``hyper`` (a ``NoveltyHyper``; by default this object's own values) supplies beta, the
normaliser's discount, lambda and SIM's H and L as arrays, so that a sweep's points share one
compiled program.
"""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from simjax.novelty.base import (
    Memory,
    RunningMeanStd,
    Timeline,
    build_timeline,
    discounted_filter,
    init_memory,
    normalize_frames,
)

METRICS = ("bonus_mean", "forward_loss", "inverse_loss")


class NoveltyState(NamedTuple):
    memory: Memory
    obs_stats: RunningMeanStd  # per pixel, (h, w, c)
    ret_stats: RunningMeanStd  # scalar, of the discounted error sums
    ret_running: jnp.ndarray  # (N,) discounted error sum per environment
    model: Any = ()  # a stateful model's own per-environment state (EC's memories, E3B's C^-1), leading axis N


class Prepared(NamedTuple):
    """A rollout as every novelty model reads it (``Novelty.prepare``): no params involved."""

    timeline: Timeline
    memory: Memory  # the memory the next rollout starts from
    obs_stats: RunningMeanStd  # with the rollout's frames folded in (if ``obs_norm``)


@dataclasses.dataclass(frozen=True)
class Novelty:
    model: Any = None  # SIM, RND, ICM (``models``), EC, E3B or None for no bonus
    bonus_scale: float = 0.0  # beta
    gamma: float = 0.99  # discount of the bonus normaliser's running return
    obs_norm: bool = True
    bonus_norm: bool = False

    @property
    def trainable(self) -> bool:
        """Whether the learner's gradient steps change the model's params (not EC's, fixed after
        its pretraining; nothing to change without a model)."""
        return self.model is not None and getattr(self.model, "trainable", True)

    def init(self, key, obs: jnp.ndarray):
        n = obs.shape[0]
        state = NoveltyState(
            memory=init_memory(self.model.history if self.model else 0, n, obs.shape[1:], obs.dtype),
            obs_stats=RunningMeanStd.create(obs.shape[1:]),
            ret_stats=RunningMeanStd.create(()),
            ret_running=jnp.zeros((n,), jnp.float32),
        )
        if self.model is None:
            return {}, state
        zeros = jnp.zeros((n,), bool)
        tl, _ = build_timeline(state.memory, obs[None], zeros[None], jnp.zeros((1, n), jnp.int32), obs, zeros)
        params = self.model.init(key, tl, self._frames(tl, state.obs_stats.update(obs)))
        if getattr(self.model, "stateful", False):
            state = state._replace(model=self.model.init_state(params, obs, jax.random.fold_in(key, 1)))
        return params, state

    def _frames(self, tl, obs_stats):
        return normalize_frames(tl.frames, obs_stats if self.obs_norm else None)

    def loss_and_bonus(self, params, state: NoveltyState, obs, reset, actions, last_obs, last_reset, hyper=None):
        if self.model is None:
            zero = jnp.zeros(())
            return zero, (jnp.zeros(actions.shape, jnp.float32), {k: zero for k in METRICS}, state)
        prepared = self.prepare(state, obs, reset, actions, last_obs, last_reset)
        loss, (error, scored, metrics, model_state) = self.model_loss(params, state.model, prepared, hyper)
        return loss, self.bonus_and_state(state, prepared, error, scored, metrics, model_state, hyper)

    # ``loss_and_bonus`` in its three parts, for a learner that needs each environment's loss on
    # its own (A3C's actors, ``simjax.agents.a3c``): only ``model_loss`` reads the params, and in
    # it each environment's numbers come from its own column alone, so it can be ``vmap``ped over
    # environments (one column each, the model's state split along its leading axis) with the
    # normalisation the whole batch gives

    def prepare(self, state: NoveltyState, obs, reset, actions, last_obs, last_reset) -> Prepared:
        """The rollout's timeline, the memory the next rollout starts from, and the frame
        statistics with the rollout's frames folded in (before any params are read)."""
        timeline, memory = build_timeline(state.memory, obs, reset, actions, last_obs, last_reset)
        obs_stats = state.obs_stats.update(obs) if self.obs_norm else state.obs_stats
        return Prepared(timeline, memory, obs_stats)

    def model_loss(self, params, model_state, prepared: Prepared, hyper=None, targets=None):
        """``(loss, (error, scored, metrics, model_state))``: the model on ``prepared``'s
        timeline, its frames normalised by ``prepared.obs_stats``; ``model_state`` is a stateful
        model's own state (``NoveltyState.model``, leading axis: environment). ``targets`` (T, N)
        bool: the loss of those transitions alone (``models``); of the stateful models E3B takes them,
        EC none."""
        tl, x = prepared.timeline, self._frames(prepared.timeline, prepared.obs_stats)
        extra = {} if targets is None else {"targets": targets}
        if getattr(self.model, "stateful", False):
            if targets is not None and not getattr(self.model, "per_transition_loss", False):
                raise ValueError(f"{type(self.model).__name__}'s loss is not one of transitions: it takes no targets")
            error, scored, loss, metrics, model_state = self.model.apply_with_state(params, model_state, tl, x, hyper,
                                                                                    **extra)
        else:
            error, scored, loss, metrics = self.model.apply(params, tl, x, hyper, **extra)
        return loss, (error, scored, metrics, model_state)

    def bonus_and_state(self, state: NoveltyState, prepared: Prepared, error, scored, metrics, model_state,
                        hyper=None):
        """``(bonus, metrics, state)`` from the model's ``error`` and ``scored`` (T, N)."""
        error = jax.lax.stop_gradient(error) * scored
        ret_stats, ret_running = state.ret_stats, state.ret_running
        if self.bonus_norm:
            gamma = self.gamma if hyper is None else hyper.gamma
            ret_running, returns = discounted_filter(ret_running, error, gamma)
            ret_stats = ret_stats.update(returns)
            error = error / jnp.sqrt(ret_stats.var + 1e-8)
        bonus = (self.bonus_scale if hyper is None else hyper.bonus_scale) * error
        metrics = {**metrics, "bonus_mean": jnp.mean(bonus)}
        return bonus, metrics, NoveltyState(prepared.memory, prepared.obs_stats, ret_stats, ret_running, model_state)
