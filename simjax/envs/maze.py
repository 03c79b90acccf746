"""First-person maze navigation as a brax ``Env``: MyWayHome tasks (paper section 3.1, B.1).

An agent step repeats one of 4 actions {turn left, turn right, forward, no-op} (or the first 3,
``MazeTask.num_actions``) for 4 tics of the env's motion and renders one 42x42 RGB frame. The
motion params pick the motion: Doom's (``simjax.envs.doom.motion``, ``MotionParams``, the
default) or the module their ``model`` names (DeepMind Lab's ``simjax.envs.dmlab.pmove`` for its
``DmlabMotionParams``: 4 engine frames), and with it the pickup rule (Doom's
``MazeTask.touch_distance`` per axis, or the module's ``touches``: Quake's
``BG_PlayerTouchesItem`` box). The frame is drawn by ``doom_render`` where the env has a
``DoomLook`` (ViZDoom's look for MyWayHome, DeepMind Lab's for the DMLab worlds:
``simjax.envs.dmlab.look``), else with the invented looks of ``raycaster``. Items give their reward
on the first touch in an episode and disappear; touching one that ``ends`` (the goal) ends the
episode as a success (termination). Otherwise the episode is cut after ``max_steps`` agent steps
(truncation, ``info['truncation'] == 1``, so a learner bootstraps there and not at a
termination).

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

from simjax.envs import raycaster
from simjax.envs.base import Env, State
from simjax.envs.doom import doom_render, motion
from simjax.envs.episodes import episode_metrics, given_actions, rollout


class Items(NamedTuple):
    """Things to touch: ``pos`` (K, 2), ``look`` (K,) sprite look, ``reward`` (K,) given once per
    episode on the first touch (the item then disappears), ``ends`` (K,) whether touching it ends
    the episode as a success (MyWayHome's armour, the melon)."""

    pos: jnp.ndarray
    look: jnp.ndarray
    reward: jnp.ndarray
    ends: jnp.ndarray

    @staticmethod
    def build(rows) -> Items:
        """From rows ``(x, y, look, reward, ends)``."""
        rows = list(rows)
        if not rows:
            raise ValueError("a layout needs at least one item")
        x, y, look, reward, ends = (np.asarray(c) for c in zip(*rows))
        return Items(
            jnp.asarray(np.stack([x, y], 1), jnp.float32), jnp.asarray(look, jnp.int32),
            jnp.asarray(reward, jnp.float32), jnp.asarray(ends, bool),
        )


def goal_item(xy, reward: float = 1.0):
    """The item row of a navigation goal: the armour, ``reward`` on touch, the episode ends."""
    return (float(xy[0]), float(xy[1]), raycaster.GOAL, reward, True)


class Layout(NamedTuple):
    """A map: walls for rendering and collision, the items and the spawn spots."""

    walls: raycaster.Walls
    boxes: jnp.ndarray  # (S, 4) collision boxes of the walls
    items: Items
    spawns: jnp.ndarray  # (K, 2)
    line_dir: jnp.ndarray  # (S,) +1 where a wall row runs toward +x or +y (its front is on the right)
    block_origin: jnp.ndarray  # (2,) the lowest vertex coordinates: the blockmap's corner
    # (ny, nx) int32 floor surface per square cell (cell (iy, ix) at x in [ix, ix + 1) * size,
    # y likewise; the size is the look's ``floor_cell``), for a look that draws floors per
    # cell (``doom_render``); None: one floor everywhere
    floor: jnp.ndarray | None = None

    @staticmethod
    def build(wall_rows, item_rows, spawn_xy) -> Layout:
        """Wall rows run like Doom's linedefs, v1 -> v2 with the open side on the right."""
        walls = raycaster.Walls.from_rows(wall_rows)
        start, end = np.asarray(walls.start), np.asarray(walls.end)
        boxes = motion.wall_boxes(start, end)
        spawns = jnp.asarray(np.asarray(spawn_xy, np.float32).reshape(-1, 2))
        origin = jnp.asarray(np.minimum(start.min(0), end.min(0)), jnp.float32)
        return Layout(walls, boxes, Items.build(item_rows), spawns, motion.line_directions(start, end), origin)


class MazeState(NamedTuple):
    """Everything the simulator carries from step to step (brax's ``pipeline_state``)."""

    pose: motion.Pose  # or the Pose of the env's motion model (``MazeEnv.motion_model``)
    steps: jnp.ndarray  # () int32, agent steps taken in this episode
    ep_return: jnp.ndarray  # () float32, extrinsic return so far in this episode
    key: jnp.ndarray  # PRNG key that draws the next episode's start
    collected: jnp.ndarray  # (K,) bool, items touched in this episode (no longer drawn)
    world: Layout | None = None  # this episode's map where maps are generated, else None


@dataclasses.dataclass(frozen=True)
class MazeTask:
    """Rules of one navigation task on a layout."""

    name: str
    random_heading: bool = True  # else every episode starts facing `heading` (or within `angle_range`)
    heading: float = 0.0  # radians, east
    # if set (and random_heading is False), each episode's Doom angle is drawn uniformly from
    # these units, inclusive (65536 a turn), as an ACS ENTER script's random(lo, hi) draws it
    angle_range: tuple[int, int] | None = None
    max_steps: int = 525  # agent steps (2100 tics / 4)
    touch_distance: float = 36.0  # Doom pickup: player half-size 16 + item radius 20, per axis (Doom motion only)
    num_actions: int = 4  # the first of (turn left, turn right, forward, no-op)


class MazeEnv(Env):
    """A maze task: ``reset(rng) -> State``, ``step(state, action) -> State``; vmap for batches.

    Subclasses that generate maps override ``_start`` (a new map per episode, in
    ``MazeState.world``), ``_on_touch`` and ``_success``.
    """

    def __init__(
        self,
        layout: Layout,
        task: MazeTask,
        camera: raycaster.Camera | doom_render.DoomCamera | None = None,
        motion_params=motion.MotionParams(),
        auto_reset: bool = True,
        look: doom_render.DoomLook | None = None,
        light: doom_render.DoomLight = doom_render.DoomLight(),
    ):
        """``look`` None draws the layout with the invented looks of ``raycaster``; a
        ``DoomLook`` draws it with ``doom_render`` through a ``DoomCamera``: as ViZDoom does
        (Freedoom's textures, ``build_look``) or as DeepMind Lab does (its surfaces,
        ``simjax.envs.dmlab.look``).
        ``motion_params``: Doom's ``motion.MotionParams`` moves the player and touches items as
        ViZDoom does; params with a ``model`` (``simjax.envs.dmlab.pmove.DmlabMotionParams``)
        move it with that module's ``Pose`` and ``tic`` and touch items with its ``touches``."""
        if not 1 <= task.num_actions <= len(motion.ACTION_NAMES):
            raise ValueError(f"num_actions must be in [1, {len(motion.ACTION_NAMES)}], got {task.num_actions}")
        self.layout = layout
        self.task = task
        if camera is None:
            camera = raycaster.Camera() if look is None else doom_render.DoomCamera()
        if (look is None) != isinstance(camera, raycaster.Camera):
            raise ValueError("the invented looks need a raycaster.Camera, a DoomLook a DoomCamera")
        self.camera = camera
        self.look = look
        self.light = light
        self.motion_params = motion_params
        # the motion's module: its Pose and tic (one tic / engine frame, Doom's calling shape)
        self.motion_model = getattr(motion_params, "model", motion)
        self.auto_reset = auto_reset

    # brax Env interface -------------------------------------------------------------------
    @property
    def observation_size(self):
        return (self.camera.height, self.camera.width, 3)

    @property
    def action_size(self) -> int:
        return self.task.num_actions

    @property
    def backend(self) -> str:
        return "simjax-raycaster"

    @property
    def motion_name(self) -> str:
        """"doom" (ViZDoom's motion) or the motion model's NAME ("dmlab" for DMLab's pmove)."""
        return getattr(self.motion_model, "NAME", "doom")

    @property
    def num_items(self) -> int:
        return self.layout.items.pos.shape[0]

    def reset(self, rng: jax.Array) -> State:
        key, sub = jax.random.split(rng)
        pose, world = self._start(sub)
        return self._first_state(key, pose, world)

    def reset_to(self, rng: jax.Array, xy, heading) -> State:
        """An episode that starts standing still at ``xy`` facing ``heading`` (radians,
        counter-clockwise from east; rounded to the motion's angle unit) instead of at a spawn spot,
        e.g. to replay a ViZDoom walk from its start. The map (a generated one too) and later
        episodes come from ``rng`` as in ``reset``. Works under jit and vmap."""
        key, sub = jax.random.split(rng)
        _, world = self._start(sub)
        return self._first_state(key, self.motion_model.Pose.at(xy, heading), world)

    def _first_state(self, key, pose, world) -> State:
        collected = jnp.zeros((self.num_items,), bool)
        ms = MazeState(pose, jnp.int32(0), jnp.float32(0.0), key, collected, world)
        zero = jnp.float32(0.0)
        return State(
            pipeline_state=ms,
            obs=self.render(pose, world, collected),
            reward=zero,
            done=zero,
            metrics=episode_metrics(zero, zero, zero, zero),
            info={"truncation": zero},
        )

    def step(self, state: State, action: jax.Array) -> State:
        chex.assert_shape(action, ())
        ms: MazeState = state.pipeline_state
        world = self.world(ms)
        pose, touched = ms.pose, jnp.zeros_like(ms.collected)
        for _ in range(self.motion_params.tics_per_step):
            pose = self.motion_model.tic(pose, action, world.boxes, self.motion_params, world.line_dir,
                                         world.block_origin)
            touched = touched | (self.touches(world.items.pos, pose.pos) & ~ms.collected)
        reward = jnp.sum(jnp.where(touched, world.items.reward, 0.0)).astype(jnp.float32)
        reached = jnp.any(touched & world.items.ends)
        key, sub = jax.random.split(ms.key)
        pose, world, collected = self._on_touch(jax.random.fold_in(sub, 1), pose, world, ms.collected | touched)
        world = None if ms.world is None else world  # a fixed map is not carried in the state
        steps = ms.steps + 1
        truncated = (steps >= self.task.max_steps) & ~reached
        done = reached | truncated
        ep_return = ms.ep_return + reward
        metrics = episode_metrics(done, self._success(reached, ep_return), steps, ep_return)

        if not self.auto_reset:
            key = ms.key
        else:
            pose, world = self._restart(sub, done, pose, world)
            collected = collected & ~done
            steps = jnp.where(done, 0, steps)
            ep_return = jnp.where(done, 0.0, ep_return)
        ms = MazeState(pose, steps, ep_return, key, collected, world)
        return state.replace(
            pipeline_state=ms,
            obs=self.render(pose, world, collected),
            reward=reward,
            done=done.astype(jnp.float32),
            metrics=metrics,
            info={**state.info, "truncation": truncated.astype(jnp.float32)},
        )

    # pieces ------------------------------------------------------------------------------
    def world(self, ms: MazeState) -> Layout:
        """The map the state is in: the env's own layout, or the state's generated one."""
        return self.layout if ms.world is None else ms.world

    def render(self, pose, world: Layout | None = None, collected=None) -> jnp.ndarray:
        world = self.layout if world is None else world
        if collected is None:
            collected = jnp.zeros((world.items.pos.shape[0],), bool)
        sprites = raycaster.Sprites(world.items.pos, world.items.look, ~collected)
        if self.look is not None:
            return doom_render.render(world.walls, pose.pos, pose.heading, sprites, self.look, self.camera, self.light,
                                      floor=world.floor)
        return raycaster.render(world.walls, pose.pos, pose.heading, sprites, self.camera)

    def touches(self, item_pos: jnp.ndarray, pos: jnp.ndarray) -> jnp.ndarray:
        """(K,) whether the player at ``pos`` touches each item."""
        rule = getattr(self.motion_model, "touches", None)
        if rule is not None:
            return rule(item_pos, pos, self.motion_params)
        return jnp.all(jnp.abs(item_pos - pos) < self.task.touch_distance, axis=-1)

    def _start(self, key: jax.Array) -> tuple[motion.Pose, Layout | None]:
        """An episode's first pose and map (None: the env's own layout)."""
        return self._spawn(key), None

    def _restart(self, key, done, pose, world):
        """Auto-reset: (pose, world) of a new episode where ``done``, else as they are."""
        fresh = self._start(key)
        return jax.tree.map(lambda new, old: jnp.where(done, new, old), fresh, (pose, world))

    def _on_touch(self, key, pose, world, collected):
        """What touching items does besides reward and ending: nothing, for a fixed map."""
        return pose, world, collected

    def _respawned(self, new, old):
        """``new``, a spawn within an episode (a DMLab level restart), taking over what the
        motion keeps from ``old`` (the model's ``continue_view``: DMLab's client keeps its view
        angle); Doom's pose is ``new`` as it is."""
        keep = getattr(self.motion_model, "continue_view", None)
        return new if keep is None else keep(new, old)

    def _success(self, reached, ep_return):
        return reached

    def _spawn(self, key: jax.Array):
        k_spot, k_head = jax.random.split(key)
        spot = jax.random.randint(k_spot, (), 0, self.layout.spawns.shape[0])
        if self.task.random_heading:
            heading = jax.random.uniform(k_head, (), minval=-math.pi, maxval=math.pi)
        elif self.task.angle_range is not None:
            low, high = self.task.angle_range
            return self.motion_model.Pose.facing(self.layout.spawns[spot], jax.random.randint(k_head, (), low, high + 1))
        else:
            heading = jnp.float32(self.task.heading)
        return self.motion_model.Pose.at(self.layout.spawns[spot], heading)


def random_walks(env: Env, key: chex.PRNGKey, num_envs: int, steps: int):
    """Uniform random actions in ``num_envs`` copies of a maze env for ``steps`` steps (episodes
    that end are reset by the env itself). Returns the frame before each step (T, N, ...), the
    actions (T, N), the last frame (N, ...), the agent's positions (T+1, N, 2) and done (T, N).
    The diagnostics (``experiments/novelty_map.py``, ``look_loudness.py``) and the looks test
    measure the novelty targets on these."""
    k_reset, k_act = jax.random.split(key)
    state = jax.vmap(env.reset)(jax.random.split(k_reset, num_envs))
    actions = jax.random.randint(k_act, (steps, num_envs), 0, env.action_size)

    def keep(state, action, nxt):
        return state.obs, state.pipeline_state.pose.pos, nxt.done

    last, _, (obs, pos, done) = rollout(env, given_actions, state, (), actions, keep)
    pos = jnp.concatenate([pos, last.pipeline_state.pose.pos[None]], axis=0)
    return obs, actions, last.obs, pos, done
