"""First-person maze navigation as a brax ``Env``: MyWayHome tasks (paper section 3.1, B.1).

An agent step repeats one of 4 actions {turn left, turn right, forward, no-op} for 4 tics of
Doom-like motion (``simjax.envs.motion``) and renders one 42x42 RGB frame (``raycaster``).
Touching the goal item gives ``goal_reward`` and ends the episode (termination); otherwise the
episode is cut after ``max_steps`` agent steps (truncation, ``info['truncation'] == 1``, so a
learner bootstraps there and not at a termination).

Auto-reset happens inside ``step`` (unlike brax's ``AutoResetWrapper``, which replays the first
state it saw): a finished episode's next start is drawn from the state's own key, and the frame
returned is the new episode's first frame, rendered once. ``reward``, ``done`` and ``metrics``
still describe the step that ended the old episode. ``metrics`` holds that episode's success,
length and return wherever ``metrics['episode_done'] == 1``.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import chex
import jax
import jax.numpy as jnp
import numpy as np
from brax.envs.base import Env, State

from simjax.envs import motion, raycaster


class Layout(NamedTuple):
    """A static map: walls for rendering and collision, the goal item and the spawn spots."""

    walls: raycaster.Walls
    boxes: jnp.ndarray  # (S, 4) collision boxes of the walls
    goal: jnp.ndarray  # (2,)
    spawns: jnp.ndarray  # (K, 2)

    @staticmethod
    def build(wall_rows, goal_xy, spawn_xy) -> "Layout":
        walls = raycaster.Walls.from_rows(wall_rows)
        boxes = motion.wall_boxes(np.asarray(walls.start), np.asarray(walls.end))
        spawns = jnp.asarray(np.asarray(spawn_xy, np.float32).reshape(-1, 2))
        return Layout(walls, boxes, jnp.asarray(goal_xy, jnp.float32), spawns)


class MazeState(NamedTuple):
    """Everything the simulator carries from step to step (brax's ``pipeline_state``)."""

    pose: motion.Pose
    steps: jnp.ndarray  # () int32, agent steps taken in this episode
    ep_return: jnp.ndarray  # () float32, extrinsic return so far in this episode
    key: jnp.ndarray  # PRNG key that draws the next episode's start


@dataclasses.dataclass(frozen=True)
class MazeTask:
    """Rules of one navigation task on a layout."""

    name: str
    random_heading: bool = True  # else every episode starts facing `heading`
    heading: float = 0.0  # radians, east
    max_steps: int = 525  # agent steps (2100 tics / 4)
    goal_reward: float = 1.0
    touch_distance: float = 36.0  # Doom pickup: player half-size 16 + item radius 20, per axis


class MazeEnv(Env):
    """A maze task: ``reset(rng) -> State``, ``step(state, action) -> State``; vmap for batches."""

    num_actions = 4

    def __init__(
        self,
        layout: Layout,
        task: MazeTask,
        camera: raycaster.Camera = raycaster.Camera(),
        motion_params: motion.MotionParams = motion.MotionParams(),
        auto_reset: bool = True,
    ):
        self.layout = layout
        self.task = task
        self.camera = camera
        self.motion_params = motion_params
        self.auto_reset = auto_reset

    # brax Env interface -------------------------------------------------------------------
    @property
    def observation_size(self):
        return (self.camera.height, self.camera.width, 3)

    @property
    def action_size(self) -> int:
        return self.num_actions

    @property
    def backend(self) -> str:
        return "simjax-raycaster"

    def reset(self, rng: jax.Array) -> State:
        key, sub = jax.random.split(rng)
        ms = MazeState(self._spawn(sub), jnp.int32(0), jnp.float32(0.0), key)
        zero = jnp.float32(0.0)
        return State(
            pipeline_state=ms,
            obs=self.render(ms.pose),
            reward=zero,
            done=zero,
            metrics=self._episode_metrics(zero, zero, zero, zero),
            info={"truncation": zero},
        )

    def step(self, state: State, action: jax.Array) -> State:
        chex.assert_shape(action, ())
        ms: MazeState = state.pipeline_state
        pose, reached = ms.pose, jnp.bool_(False)
        for _ in range(self.motion_params.tics_per_step):
            pose = motion.tic(pose, action, self.layout.boxes, self.motion_params)
            reached = reached | self.touches_goal(pose.pos)
        steps = ms.steps + 1
        reward = jnp.where(reached, self.task.goal_reward, 0.0).astype(jnp.float32)
        truncated = (steps >= self.task.max_steps) & ~reached
        done = reached | truncated
        ep_return = ms.ep_return + reward
        metrics = self._episode_metrics(done, reached, steps, ep_return)

        key = ms.key
        if self.auto_reset:
            key, sub = jax.random.split(ms.key)
            fresh = self._spawn(sub)
            pose = jax.tree.map(lambda new, old: jnp.where(done, new, old), fresh, pose)
            steps = jnp.where(done, 0, steps)
            ep_return = jnp.where(done, 0.0, ep_return)
        ms = MazeState(pose, steps, ep_return, key)
        return state.replace(
            pipeline_state=ms,
            obs=self.render(pose),
            reward=reward,
            done=done.astype(jnp.float32),
            metrics=metrics,
            info={**state.info, "truncation": truncated.astype(jnp.float32)},
        )

    # pieces ------------------------------------------------------------------------------
    def render(self, pose: motion.Pose) -> jnp.ndarray:
        return raycaster.render(self.layout.walls, pose.pos, pose.heading, self.layout.goal, self.camera)

    def touches_goal(self, pos: jnp.ndarray) -> jnp.ndarray:
        return jnp.all(jnp.abs(pos - self.layout.goal) < self.task.touch_distance)

    def _spawn(self, key: jax.Array) -> motion.Pose:
        k_spot, k_head = jax.random.split(key)
        spot = jax.random.randint(k_spot, (), 0, self.layout.spawns.shape[0])
        if self.task.random_heading:
            heading = jax.random.uniform(k_head, (), minval=-math.pi, maxval=math.pi)
        else:
            heading = jnp.float32(self.task.heading)
        return motion.Pose(self.layout.spawns[spot], heading, jnp.zeros(2, jnp.float32))

    @staticmethod
    def _episode_metrics(done, success, length, ret):
        f = lambda x: jnp.asarray(x, jnp.float32)
        return {
            "episode_done": f(done),
            "episode_success": f(success),
            "episode_length": f(length),
            "episode_return": f(ret),
        }
