"""simjax's MyWayHome tasks as Gymnasium 1.x environments (the ``gymnasium`` extra:
``pip install -e '.[gymnasium]'``).

Importing this module registers, for ``gymnasium.make`` and ``gymnasium.make_vec``:

============================================  =======================  ===================================
id                                            simjax task               start of every episode
============================================  =======================  ===================================
``simjax/MyWayHome-dense-v0``                 ``maze-dense``            a random spot of the 17
``simjax/MyWayHome-sparse-v1``                ``maze-sparse``           spot 10, facing 0-3.6 degrees
``simjax/MyWayHome-very-sparse-v1``           ``maze-very-sparse``      spot 15, facing 176.4-183.6 degrees
``simjax/MyWayHome-sparse-v0``                ``maze-spot16-east``      spot 16, facing east
``simjax/MyWayHome-very-sparse-v0``           ``maze-spot10-east``      spot 10, facing east
============================================  =======================  ===================================

The v1 ids are the paper's tasks, started as the ICM code's scenario files start them
(``simjax.envs.doom.icm_scenarios``); the v0 ids keep the starts they had before 2026-12-04.

Either import it first or name it in the id (Gymnasium's ``"module:id"`` form, which imports the
module before looking the id up; ``gymnasium.envs.registration._find_spec``)::

    import gymnasium
    env = gymnasium.make("simjax.gymnasium_env:simjax/MyWayHome-very-sparse-v1", render_mode="rgb_array")
    envs = gymnasium.make_vec("simjax.gymnasium_env:simjax/MyWayHome-very-sparse-v1", num_envs=16)

``make_vec`` builds ``SimjaxVectorEnv`` (the ids' ``vector_entry_point``; also with
``vectorization_mode="vector_entry_point"``): all N envs step in one jitted ``jax.vmap`` call.
``vectorization_mode="sync"`` or ``"async"`` gives Gymnasium's own vectorisers of ``SimjaxEnv``
instead (one compiled call per env per step). ``SimjaxEnv(task)`` and
``SimjaxVectorEnv(num_envs, task)`` also take ``maze-tiny`` (the 50-step smoke-test room), which is
not registered.

Spaces: observations ``Box(0, 255, (42, 42, 3), uint8)``, the first-person RGB frame, read from
the task (``jax.eval_shape`` of its ``reset``); actions ``Discrete(4)``: 0 turn left, 1 turn right,
2 forward, 3 no-op, each held for 4 tics (the vector env: ``MultiDiscrete([4] * N)``, numpy
in and out). Reward +1 at the goal, which ends the episode (``terminated``); otherwise the
task cuts it after 525 agent steps (``truncated``). The time limit is the task's own, so the ids
carry no ``max_episode_steps`` and ``gymnasium.make`` adds no ``TimeLimit``. ``render()``
(``render_mode="rgb_array"``) returns the current frame, the observation itself; the vector
env's ``render()`` a tuple of its N frames. ``info`` is ``{}``.

Episodes and keys. The wrappers step the task as ``simjax.envs.make(task)`` builds it, with its
own auto-reset held back: an episode's last step returns its last frame, and the next episode
starts where Gymnasium says (``reset()``, or the vector env's next ``step``). The next episode's
start comes from the state's own PRNG key, drawn exactly as the auto-resetting env draws it, so
for the same keys and actions the wrappers see the same episodes as ``jax.vmap(env.step)``
(tested):

- ``SimjaxEnv.reset(seed=s)`` is ``env.reset(jax.random.PRNGKey(s))`` (for s >= 2**32:
  ``fold_in(PRNGKey(s % 2**32), s >> 32)``); ``reset()`` without a seed goes on from the state's
  key (the next episode the auto-resetting env would start; before any state, a key drawn from
  ``np_random``);
- ``SimjaxVectorEnv.reset(seed=s)`` resets env i with ``jax.random.split(PRNGKey(s), N)[i]``; a
  list of N seeds resets env i as ``SimjaxEnv.reset(seed=seeds[i])`` does (so
  ``gymnasium.vector.SyncVectorEnv`` over ``SimjaxEnv``s reset with the same list gives the same
  numbers, tested); ``seed=None`` draws one seed from ``np_random``.

Autoreset: Gymnasium 1.x's default, ``AutoresetMode.NEXT_STEP`` (``metadata["autoreset_mode"]``),
as ``gymnasium.vector.SyncVectorEnv`` does it: the step that ends an env's episode returns its
last frame with ``terminated`` or ``truncated``; that env's next ``step`` ignores its action and
returns the next episode's first frame, reward 0, both flags False. On that call the whole batch is
reset as well as stepped (one ``lax.cond`` on any env needing it), so calls with an episode start
cost about twice the others. ``reset(options=...)`` takes no options (``reset_mask`` included).
"""

from __future__ import annotations

import copy
import functools
from typing import Any, NamedTuple

import gymnasium
import jax
import jax.numpy as jnp
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from simjax import envs as simjax_envs
from simjax.envs.maze import MazeEnv

# simjax task -> Gymnasium id
ENV_IDS = {
    "maze-dense": "simjax/MyWayHome-dense-v0",
    "maze-sparse": "simjax/MyWayHome-sparse-v1",
    "maze-very-sparse": "simjax/MyWayHome-very-sparse-v1",
    "maze-spot16-east": "simjax/MyWayHome-sparse-v0",
    "maze-spot10-east": "simjax/MyWayHome-very-sparse-v0",
}
# the tasks the wrappers take (the registered ones and the smoke-test room)
TASKS = (*ENV_IDS, "maze-tiny")
# Doom runs 35 tics a second; an agent step is 4 tics
RENDER_FPS = 35 / 4
ACTION_MEANINGS = ("turn left", "turn right", "forward", "no-op")


def seed_key(seed: int) -> jax.Array:
    """The PRNG key a Gymnasium seed stands for: ``jax.random.PRNGKey(seed)``, with the high 32
    bits folded in for seeds of 2**32 and more (``PRNGKey`` keeps only the low 32 bits)."""
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**64:
        raise ValueError(f"a seed must be an integer in [0, 2**64), got {seed!r}")
    seed = int(seed)
    key = jax.random.PRNGKey(seed & 0xFFFFFFFF)
    return key if seed < 2**32 else jax.random.fold_in(key, seed >> 32)


def _drawn_seed(rng: np.random.Generator) -> int:
    return int(rng.integers(0, 2**64, dtype=np.uint64))


class Programs(NamedTuple):
    """One task's env and its jitted batch functions, shared by every wrapper of the task."""

    env: MazeEnv  # without auto-reset: a finished episode's state (and last frame) stays
    obs_space: spaces.Box
    num_actions: int
    reset: Any  # keys (N, ...) -> states
    step: Any  # (states, autoreset (N,) bool, actions (N,) int32) -> (states, autoreset, (obs, reward, terminated, truncated))


def check_task(task: str) -> None:
    if task not in TASKS:
        raise ValueError(f"no Gymnasium wrapper for task {task!r}; the wrapped tasks are {', '.join(TASKS)}")


@functools.cache
def programs(task: str) -> Programs:
    """The env and the compiled-once (per batch size) reset and step of ``task``."""
    check_task(task)
    made = simjax_envs.make(task)
    if not isinstance(made, MazeEnv):
        raise ValueError(f"task {task!r} is not a maze env")
    env = copy.copy(made)
    env.auto_reset = False  # the wrappers reset where Gymnasium says, from the key the env would use

    shape = jax.eval_shape(env.reset, jax.ShapeDtypeStruct((2,), jnp.uint32)).obs
    if shape.dtype != jnp.uint8:
        raise TypeError(f"task {task!r} renders {shape.dtype} frames, not uint8")
    obs_space = spaces.Box(0, 255, tuple(shape.shape), np.uint8)

    batch_reset = jax.vmap(env.reset)

    def step(state, autoreset, actions):
        stepped = jax.vmap(env.step)(state, actions)
        done = stepped.done > 0
        truncated = stepped.info["truncation"] > 0
        # The auto-resetting env splits its key every step and starts the next episode from the
        # split of the key before the last step, as reset(that key) does. Keep that key where the
        # episode ended (the next call resets from it), else advance it as the env would.
        old_key = state.pipeline_state.key
        advanced = jax.vmap(lambda k: jax.random.split(k)[0])(old_key)
        key = jax.vmap(lambda d, old, new: jnp.where(d, old, new))(done, old_key, advanced)
        stepped = stepped.replace(pipeline_state=stepped.pipeline_state._replace(key=key))

        def with_resets():
            fresh = batch_reset(old_key)
            pick = lambda new, old: jax.vmap(lambda r, a, b: jnp.where(r, a, b))(autoreset, new, old)
            return jax.tree.map(pick, fresh, stepped)

        state = jax.lax.cond(jnp.any(autoreset), with_resets, lambda: stepped)
        reward = jnp.where(autoreset, 0.0, stepped.reward).astype(jnp.float32)
        terminated = done & ~truncated & ~autoreset
        truncated = truncated & ~autoreset
        return state, terminated | truncated, (state.obs, reward, terminated, truncated)

    return Programs(env, obs_space, env.action_size, jax.jit(batch_reset), jax.jit(step))


def _copy_out(arrays):
    """Device arrays to writable numpy copies (``torch.from_numpy`` warns on read-only ones)."""
    return tuple(np.array(a) for a in jax.device_get(arrays))


RENDER_MODES = ["rgb_array"]


def _check_render_mode(render_mode) -> None:
    if render_mode is not None and render_mode not in RENDER_MODES:
        raise ValueError(f"render_mode must be None or one of {RENDER_MODES}, got {render_mode!r}")


def _renders(render_mode) -> bool:
    """Whether ``render()`` has a frame to give; warns as Gymnasium's envs do when it has not."""
    if render_mode is None:
        gymnasium.logger.warn("render() without a render_mode: make the env with render_mode='rgb_array'")
    return render_mode is not None


def _action_list(n: int) -> str:
    return ", ".join(f"{i} {m}" for i, m in enumerate(ACTION_MEANINGS[:n]))


def _check_options(options) -> None:
    if options:
        raise ValueError(f"reset takes no options, got {sorted(options)}")


class SimjaxEnv(gymnasium.Env):
    """One simjax maze task as a ``gymnasium.Env`` (module docstring: spaces, seeding, episodes)."""

    metadata = {"render_modes": RENDER_MODES, "render_fps": RENDER_FPS}

    def __init__(self, task: str = "maze-very-sparse", render_mode: str | None = None):
        _check_render_mode(render_mode)
        self.task = task
        self.render_mode = render_mode
        self._programs = programs(task)
        self.observation_space = self._programs.obs_space
        self.action_space = spaces.Discrete(self._programs.num_actions)
        self._state = None
        self._obs = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        _check_options(options)
        if seed is not None:
            key = seed_key(seed)
        elif self._state is not None:
            key = self._state.pipeline_state.key[0]
        else:
            key = seed_key(_drawn_seed(self.np_random))
        self._state = self._programs.reset(key[None])
        (self._obs,) = _copy_out((self._state.obs[0],))
        return self._obs.copy(), {}

    def step(self, action):
        if self._state is None:
            raise ResetNeeded("call reset() before step()")
        if not self.action_space.contains(action):
            raise ValueError(f"action {action!r} is not in {self.action_space} "
                             f"({_action_list(self.action_space.n)})")
        actions = np.full((1,), action, np.int32)
        self._state, _, out = self._programs.step(self._state, np.zeros((1,), bool), actions)
        obs, reward, terminated, truncated = _copy_out(out)
        self._obs = obs[0]
        return self._obs.copy(), float(reward[0]), bool(terminated[0]), bool(truncated[0]), {}

    def render(self):
        if not _renders(self.render_mode):
            return None
        return None if self._obs is None else self._obs.copy()


class SimjaxVectorEnv(VectorEnv):
    """``num_envs`` copies of a simjax maze task stepped in one jitted ``jax.vmap`` call, numpy in
    and out, with Gymnasium's next-step autoreset (module docstring)."""

    metadata = {"render_modes": RENDER_MODES, "render_fps": RENDER_FPS, "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int, task: str = "maze-very-sparse", render_mode: str | None = None):
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        _check_render_mode(render_mode)
        self.num_envs = int(num_envs)
        self.task = task
        self.render_mode = render_mode
        self._programs = programs(task)
        self.single_observation_space = self._programs.obs_space
        self.single_action_space = spaces.Discrete(self._programs.num_actions)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._state = None
        self._autoreset = None
        self._obs = None

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None):
        _check_options(options)
        if isinstance(seed, (list, tuple)):
            if len(seed) != self.num_envs:
                raise ValueError(f"a list of seeds needs one per env ({self.num_envs}), got {len(seed)}")
            keys = jnp.stack([seed_key(_drawn_seed(self.np_random) if s is None else s) for s in seed])
        else:
            super().reset(seed=seed)  # seeds np_random
            keys = jax.random.split(seed_key(_drawn_seed(self.np_random) if seed is None else seed), self.num_envs)
        self._state = self._programs.reset(keys)
        self._autoreset = jnp.zeros((self.num_envs,), bool)
        (self._obs,) = _copy_out((self._state.obs,))
        return self._obs.copy(), {}

    def step(self, actions):
        if self._state is None:
            raise ResetNeeded("call reset() before step()")
        actions = self._checked(actions)
        self._state, self._autoreset, out = self._programs.step(self._state, self._autoreset, actions)
        self._obs, reward, terminated, truncated = _copy_out(out)
        return self._obs.copy(), reward, terminated, truncated, {}

    def _checked(self, actions) -> np.ndarray:
        a = np.asarray(actions)
        n = self.single_action_space.n
        if a.shape != (self.num_envs,):
            raise ValueError(f"actions must have shape ({self.num_envs},), one per env, got shape {a.shape}")
        if not np.issubdtype(a.dtype, np.integer):
            raise ValueError(f"actions must be integers, got dtype {a.dtype}")
        if np.any((a < 0) | (a >= n)):
            raise ValueError(f"actions must be in [0, {n}) ({_action_list(n)}), "
                             f"got {a[(a < 0) | (a >= n)][:8].tolist()}")
        return a.astype(np.int32)

    def render(self):
        if not _renders(self.render_mode):
            return None
        return None if self._obs is None else tuple(self._obs.copy())


def register() -> None:
    """Register the MyWayHome ids (done on import; a second call changes nothing)."""
    for task, env_id in ENV_IDS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point="simjax.gymnasium_env:SimjaxEnv",
                               vector_entry_point="simjax.gymnasium_env:SimjaxVectorEnv", kwargs={"task": task})


register()

__all__ = ["SimjaxEnv", "SimjaxVectorEnv", "ENV_IDS", "TASKS", "programs", "register", "seed_key"]
