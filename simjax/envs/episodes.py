"""Episodes as every simjax env reports them, and one way to step a batch of envs through them.

The envs auto-reset inside ``step``: the state after the step that ended an episode holds the
next episode's first frame, and that step's ``reward``, ``done`` and ``metrics`` still describe
the episode that ended. So
- ``starts_episode(state)``: the state's frame is an episode's first (a recurrent policy
  resets its memory there);
- ``metrics`` (``episode_metrics``) carry the ended episode's success, length and return
  wherever ``metrics['episode_done'] == 1``.

``rollout`` is the loop the learner and the diagnostics share: a ``lax.scan`` of a batch of
envs (``jax.vmap`` of ``env.step``) driven by any ``policy(carry, state, x)``, where ``x`` is
the scan's input for the step (a PRNG key, or a pre-drawn action).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp

EPISODE_METRICS = ("episode_done", "episode_success", "episode_length", "episode_return")


def starts_episode(state) -> jnp.ndarray:
    """(N,) bool: the frame in ``state`` is an episode's first.

    The auto-resetting env marks the step that ended an episode with ``done`` and returns the
    next episode's first frame with it. (After ``reset`` done is 0: a caller starts from a
    fresh memory there anyway.)"""
    return state.done > 0


def episode_metrics(done, success, length, ret) -> dict:
    """The per-step ``metrics`` of an env: the ended episode's numbers where ``done``."""
    values = (done, success, length, ret)
    return {name: jnp.asarray(v, jnp.float32) for name, v in zip(EPISODE_METRICS, values)}


def rollout(env, policy: Callable, state, carry, xs, record: Callable) -> tuple[Any, Any, Any]:
    """Step the batch ``state`` of ``env`` once per leading entry of ``xs``.

    ``policy(carry, state, x) -> (actions (N,) int32, carry)`` chooses each step's actions
    (``carry``: e.g. an LSTM's state); ``record(state, actions, next_state)`` is what the step
    keeps. Returns the last state, the last carry and the records stacked over steps."""
    step = jax.vmap(env.step)

    def body(c, x):
        state, carry = c
        actions, carry = policy(carry, state, x)
        next_state = step(state, actions)
        return (next_state, carry), record(state, actions, next_state)

    (state, carry), records = jax.lax.scan(body, (state, carry), xs)
    return state, carry, records


def uniform_policy(num_actions: int, num_envs: int):
    """A ``rollout`` policy that draws each env's action uniformly from the step's key."""

    def act(carry, state, key):
        return jax.random.randint(key, (num_envs,), 0, num_actions), carry

    return act


def given_actions(carry, state, actions):
    """A ``rollout`` policy that takes the step's input as the actions (drawn beforehand)."""
    return actions, carry
