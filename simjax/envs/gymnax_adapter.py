"""Any gymnax environment as the brax ``Env`` the learner takes: ``make("gymnax:CartPole-v1")``.

This is how a user brings a world of their own (anything gymnax can ``make``), and how the
paper's Atari appendix gets a JAX-native stand-in (the MinAtar games gymnax ships). The adapter
keeps our tasks' conventions:
- ``step`` auto-resets (gymnax's own ``step`` does): the observation after a finished episode
  is the next episode's first; ``reward`` and ``done`` describe the step that ended the old one;
- ``done`` = terminated or truncated, and ``info['truncation']`` marks a time-limit end that
  was not also a termination, so the learner bootstraps there;
- ``metrics`` carry the finished episode's length and return where ``episode_done == 1``;
  ``episode_success`` is always 0 (gymnax has no notion of success: read the return);
- observations are float32 with the environment's own shape, e.g. (4,) for CartPole (the
  actor-critic then encodes them with a dense layer) or (10, 10, C) for MinAtar (convolutions).
  A 2-D observation (bsuite's Catch, DeepSea) is an image of one channel and gets that channel
  axis, (H, W, 1), because the learner's networks read images as (H, W, C); a scalar one
  (FrozenLake's cell) becomes a vector of one, (1,).
Only discrete action spaces are accepted: the policy is categorical.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from simjax.envs.base import Env, State
from simjax.envs.episodes import episode_metrics


def _gymnax():
    try:
        import gymnax
    except ImportError as err:  # pragma: no cover - gymnax is a dependency
        raise ValueError(f"gymnax:NAME tasks need gymnax (pip install gymnax six): {err}") from err
    return gymnax


def check_gymnax_name(name: str) -> None:
    """A clear error for a name gymnax does not know (its action space is checked where the
    env is built, ``GymnaxEnv``)."""
    gymnax = _gymnax()
    if name not in gymnax.registered_envs:
        raise ValueError(f"unknown gymnax environment {name!r}; gymnax knows: {', '.join(gymnax.registered_envs)}")


class GymnaxState(NamedTuple):
    env_state: Any  # gymnax's own state
    key: jnp.ndarray  # the key the next step's randomness is drawn from
    steps: jnp.ndarray  # () int32, steps in this episode
    ep_return: jnp.ndarray  # () float32, return so far in this episode


class GymnaxEnv(Env):
    """A gymnax environment behind brax's ``Env`` (``reset(rng)``, ``step(state, action)``)."""

    def __init__(self, name: str, **param_overrides):
        check_gymnax_name(name)
        self.name = name
        self.env, params = _gymnax().make(name)
        self.params = params.replace(**param_overrides) if param_overrides else params
        space = self.env.action_space(self.params)
        if not hasattr(space, "n"):
            raise ValueError(
                f"gymnax:{name} has a {type(space).__name__} action space; the learner's policy is "
                "categorical, so only discrete action spaces are supported"
            )
        self._num_actions = int(space.n)
        self._obs_shape = observation_shape(self.env.observation_space(self.params).shape)

    @property
    def observation_size(self):
        return self._obs_shape

    @property
    def action_size(self) -> int:
        return self._num_actions

    @property
    def backend(self) -> str:
        return "gymnax"

    def reset(self, rng: jax.Array) -> State:
        key, sub = jax.random.split(rng)
        obs, env_state = self.env.reset(sub, self.params)
        zero = jnp.float32(0.0)
        return State(
            pipeline_state=GymnaxState(env_state, key, jnp.int32(0), zero),
            obs=self._obs(obs),
            reward=zero,
            done=zero,
            metrics=episode_metrics(zero, zero, zero, zero),
            info={"truncation": zero},
        )

    def step(self, state: State, action: jax.Array) -> State:
        ps: GymnaxState = state.pipeline_state
        key, sub = jax.random.split(ps.key)
        obs, env_state, reward, terminated, truncated, _ = self.env.step(sub, ps.env_state, action, self.params)
        reward = jnp.asarray(reward, jnp.float32)
        terminated, truncated = jnp.asarray(terminated, bool), jnp.asarray(truncated, bool)
        done = terminated | truncated
        steps, ep_return = ps.steps + 1, ps.ep_return + reward
        metrics = episode_metrics(done, 0.0, steps, ep_return)  # gymnax has no success
        steps = jnp.where(done, 0, steps)
        ep_return = jnp.where(done, 0.0, ep_return)
        return state.replace(
            pipeline_state=GymnaxState(env_state, key, steps, ep_return),
            obs=self._obs(obs),
            reward=reward,
            done=done.astype(jnp.float32),
            metrics=metrics,
            info={**state.info, "truncation": (truncated & ~terminated).astype(jnp.float32)},
        )

    def _obs(self, obs) -> jnp.ndarray:
        return jnp.asarray(obs, jnp.float32).reshape(self._obs_shape)


def observation_shape(shape) -> tuple[int, ...]:
    """The shape the learner sees for a gymnax observation of ``shape``: (H, W) frames get a
    channel axis, a scalar becomes a vector of one; others stay as they are."""
    shape = tuple(int(d) for d in shape)
    if len(shape) == 2:
        return shape + (1,)
    return shape or (1,)
