"""``explore-goals``: a new maze every episode, after DMLab's Explore Goal Locations Small
(paper section 3.4, appendix D), with DMLab's own rules by default and the paper's wording as
``explore-goals-paper``.

``explore-goals`` (``ExploreGoalsEnv``) follows DeepMind Lab's level scripts
(google-deepmind/lab; read, not copied):

- the map: ``levels/contributed/dmlab30/explore_goal_locations_small.lua`` calls
  ``factories/explore/goal_locations_factory.lua`` with no options, which calls
  ``factories/explore/factory.lua``: each episode ``maze_generation.randomMazeGeneration`` draws
  an 11x11 text maze with up to 4 rooms (3 to 5 cells a side), corridors carved around them, one
  connection between every two touching regions, dead ends removed, 5 spawn points 'P' and 4
  goal candidates 'G' per room (``simjax.envs.dmlab.dmlab_maze`` has each value and its source);
- the goal (goal_locations_factory.lua ``level:start``): one 'G' cell drawn uniformly once per
  episode; it stays there all episode;
- the start and every restart (``level:restart``): a uniformly drawn 'P' cell reachable from
  the goal (every 'P': the maze is connected); a random heading;
- the reward: the goal pickup is ``pickups.defaults.goal``, 10 points, type GOAL
  (``common/pickups.lua``); a GOAL pickup "changes the agent's score and causes the current
  level to restart" (``docs/developers/reference/lua_api.md``), and the factory's ``nextMap``
  keeps the same map (quickRestart), so the agent alone moves to a new spawn point and the goal
  comes back where it was; the episode goes on;
- the length: ``episodeLengthSeconds`` 90 (factory.lua default; "an episode (one run with
  potentially many level restarts) ends after this many seconds", ``docs/levels.md``): 90 s at
  DMLab's 60 frames/s with 4 frames per agent step is 1350 agent steps, the paper's number.

``explore-goals-paper`` (``ExploreGoalsPaperEnv``) is the paper's wording (section 3.3): a 9x9
grid of 128-unit cells (a random spanning tree, then each remaining interior wall knocked out
with probability ``loop_prob``, every wall a random one of MISHMASH's 20 walls), no rooms,
the goal in a random cell, and after each pickup both the agent and the goal move to new random
cells. Same length and reward.

Looks (``look``): "dmlab" (the default) draws both as DeepMind Lab draws its generated maps
(``simjax.envs.dmlab.look``): MISHMASH's walls and floors (``explore-goals``: the rooms in one
drawn wall and floor, the corridors in the default ones, ``dmlab_maze.DMLabMazeGenerator``; the
paper variant: a drawn wall per wall row, the default floor), walls 100 units high, the sky
``lg_sky_03`` (whose faces are missing here: ``lg_sky_01`` stands in), the goal as its model.
"invented" is the look before 2026-12-07 (the raycaster's twelve looks), kept for the
``*-doom-motion`` tasks.

Both: 3 actions {turn left, turn right, forward}, moving and touching the goal as DeepMind
Lab does (``simjax.envs.dmlab.pmove``; ``motion="doom"`` gives the Doom motion they had before,
for runs made with it); after a pickup the agent's spawn keeps the client's view angle, as
DMLab's level restart does (``pmove.continue_view``); no early end (the time limit is a
truncation); ``episode_success`` is 1 for an episode that reached at least one goal.

The paper variant's spanning tree is the minimum spanning tree of random edge weights, which is
what randomised Kruskal builds, computed with Boruvka's rounds instead of Kruskal's edge-by-edge
loop: each round every component picks its lightest edge out and the components merge
(pointer jumping), so there are ``ceil(log2(cells^2))`` vectorised rounds and no data-dependent
loop.

A new maze is needed only where an episode ends, but under ``vmap`` a ``lax.cond`` on a per-env
``done`` turns into a select that generates a maze for every env at every step (measured under the
same load: 6,300 vs 30,000 agent steps/s at 1024 envs). ``regenerate`` is a ``custom_vmap`` function instead: each
``vmap`` level folds its axis into one batch, and one ``lax.cond`` on "any env of the batch
done" generates the batch's mazes only on steps where some episode ends (every 1350 steps
when the envs started together). ``make bench`` measures both generation and the env step.
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np

from simjax.envs import raycaster
from simjax.envs.dmlab import look as dmlab_look
from simjax.envs.dmlab import pmove
from simjax.envs.dmlab.dmlab_maze import MISHMASH_SIZE, DMLabMazeGenerator
from simjax.envs.maze import Layout, MazeEnv, MazeTask, goal_item

_FAR = 1e9


@dataclasses.dataclass(frozen=True)
class GridGraph:
    """The cells (``cells``^2, numbered ``y * cells + x``) and the interior walls between them:
    edge ``e`` joins cells ``a[e]`` and ``b[e]``; the first ``cells * (cells - 1)`` edges join
    east-west neighbours, the rest north-south ones."""

    cells: int

    @property
    def num_cells(self) -> int:
        return self.cells * self.cells

    def edges(self) -> tuple[np.ndarray, np.ndarray]:
        c = self.cells
        x, y = np.meshgrid(np.arange(c - 1), np.arange(c), indexing="xy")
        east = (y * c + x).ravel(), (y * c + x + 1).ravel()
        x, y = np.meshgrid(np.arange(c), np.arange(c - 1), indexing="xy")
        north = (y * c + x).ravel(), ((y + 1) * c + x).ravel()
        return np.concatenate([east[0], north[0]]), np.concatenate([east[1], north[1]])


def random_spanning_tree(key: jax.Array, graph: GridGraph) -> jnp.ndarray:
    """(E,) bool: which edges of ``graph`` form the minimum spanning tree of uniform random
    weights (Boruvka). With distinct weights (probability 1) it has exactly V - 1 edges."""
    a, b = (jnp.asarray(v) for v in graph.edges())
    num = graph.num_cells
    ids = jnp.arange(num)
    weight = jax.random.uniform(key, a.shape)
    comp = ids  # component label (its root cell) of every cell
    tree = jnp.zeros(a.shape, bool)
    rounds = max(1, math.ceil(math.log2(num)))
    for _ in range(rounds):
        ca, cb = comp[a], comp[b]
        w = jnp.where(ca != cb, weight, jnp.inf)
        best = jnp.full((num,), jnp.inf).at[ca].min(w).at[cb].min(w)  # lightest edge out, per root
        pick_a, pick_b = (w < jnp.inf) & (w == best[ca]), (w < jnp.inf) & (w == best[cb])
        tree = tree | pick_a | pick_b
        # each root points at the root across its picked edge; mutual pairs keep the smaller
        parent = ids.at[jnp.where(pick_a, ca, num)].set(cb, mode="drop")
        parent = parent.at[jnp.where(pick_b, cb, num)].set(ca, mode="drop")
        parent = jnp.where((parent[parent] == ids) & (ids < parent), ids, parent)
        for _ in range(rounds):  # pointer jumping: every root reaches its new root
            parent = parent[parent]
        comp = parent[comp]
    return tree


@dataclasses.dataclass(frozen=True)
class MazeGenerator:
    """The paper variant's mazes (``explore-goals-paper``) as raycaster layouts: the wall rows
    are fixed (every interior edge, then the outer boundary); a maze is which of them are open,
    and the looks of the closed ones."""

    cells: int = 9
    cell_size: float = 128.0
    loop_prob: float = 0.1
    # "dmlab": each wall a uniformly drawn one of MISHMASH's 20 walls
    # (``simjax.envs.dmlab.look.MISHMASH_WALLS``); "invented" (before 2026-12-07): one of the
    # raycaster's twelve looks
    look: str = "dmlab"

    def __post_init__(self):
        if self.look not in ("dmlab", "invented"):
            raise ValueError(f"look must be 'dmlab' or 'invented', got {self.look!r}")
        if not 2 <= self.cells <= 32:
            raise ValueError(f"cells must be in [2, 32], got {self.cells}")
        if not 0.0 <= self.loop_prob <= 1.0:
            raise ValueError(f"loop_prob must be in [0, 1], got {self.loop_prob}")
        if self.cell_size < 64:
            raise ValueError(f"cell_size must be at least 64 (the player is 32 wide), got {self.cell_size}")

    @property
    def graph(self) -> GridGraph:
        return GridGraph(self.cells)

    def wall_rows(self) -> np.ndarray:
        """(E + 4 * cells, 4) segments [x1, y1, x2, y2]: interior edges in ``graph`` order, then
        the boundary."""
        c, s = self.cells, self.cell_size
        a, b = self.graph.edges()
        ax, ay = a % c, a // c
        rows = []
        for e in range(a.size):
            if b[e] == a[e] + 1:  # east-west neighbours: a vertical wall on x = (ax + 1) s
                rows.append(((ax[e] + 1) * s, ay[e] * s, (ax[e] + 1) * s, (ay[e] + 1) * s))
            else:  # north-south neighbours: a horizontal wall on y = (ay + 1) s
                rows.append((ax[e] * s, (ay[e] + 1) * s, (ax[e] + 1) * s, (ay[e] + 1) * s))
        for i in range(c):
            rows += [(i * s, 0, (i + 1) * s, 0), (i * s, c * s, (i + 1) * s, c * s),
                     (0, i * s, 0, (i + 1) * s), (c * s, i * s, c * s, (i + 1) * s)]
        return np.asarray(rows, np.float32)

    def cell_centres(self) -> np.ndarray:
        c, s = self.cells, self.cell_size
        i = np.arange(c * c)
        return np.stack([(i % c + 0.5) * s, (i // c + 0.5) * s], 1).astype(np.float32)

    def template(self) -> Layout:
        """Every wall closed, look 0, the goal in cell 0; ``generate`` fills in a maze."""
        rows = [(*r, 0) for r in self.wall_rows()]
        return Layout.build(rows, [goal_item(self.cell_centres()[0], 10.0)], self.cell_centres())

    def open_edges(self, key: jax.Array) -> jnp.ndarray:
        """(E,) bool: the spanning tree's edges, plus each other edge with ``loop_prob``."""
        k_tree, k_loop = jax.random.split(key)
        tree = random_spanning_tree(k_tree, self.graph)
        loops = jax.random.bernoulli(k_loop, self.loop_prob, tree.shape)
        return tree | loops

    def generate(self, key: jax.Array, template: Layout | None = None) -> Layout:
        """A random maze (goal item still in cell 0)."""
        if template is None:
            with jax.ensure_compile_time_eval():  # the fixed rows are constants, also under jit
                template = self.template()
        k_open, k_look = jax.random.split(key)
        is_open = self.open_edges(k_open)
        walls, boxes = template.walls, template.boxes
        row_open = jnp.concatenate([is_open, jnp.zeros(4 * self.cells, bool)])
        v_open, h_open = row_open[walls.v_index], row_open[walls.h_index]
        walls = walls._replace(
            texture=jax.random.randint(k_look, walls.texture.shape, 0,
                                       raycaster.NUM_TEXTURES if self.look == "invented" else MISHMASH_SIZE),
            v_lo=jnp.where(v_open, _FAR, walls.v_lo), v_hi=jnp.where(v_open, -_FAR, walls.v_hi),
            h_lo=jnp.where(h_open, _FAR, walls.h_lo), h_hi=jnp.where(h_open, -_FAR, walls.h_hi),
        )
        boxes = jnp.where(row_open[:, None], _FAR, boxes)  # an open wall's box is out of reach
        return template._replace(walls=walls, boxes=boxes)


def regenerate_where_done(generator, template: Layout):
    """For a ``generator`` with ``generate(key, template) -> Layout`` (``MazeGenerator``,
    ``DMLabMazeGenerator``): ``fn(keys (B, 2), done (B,), old (Layout, leading axis B)) -> Layout``, a new maze from
    ``keys[i]`` where ``done[i]``, else ``old[i]``; the mazes are generated only if any is done,
    also under any number of ``vmap`` levels (they are folded into B)."""

    @jax.custom_batching.custom_vmap
    def fn(keys, done, old):
        def fresh():
            new = jax.vmap(lambda k: generator.generate(k, template))(keys)
            pick = lambda n, o: jnp.where(done.reshape(done.shape + (1,) * (n.ndim - 1)), n, o)
            return jax.tree.map(pick, new, old)

        return jax.lax.cond(jnp.any(done), fresh, lambda: old)

    @fn.def_vmap
    def _fold(axis_size, in_batched, keys, done, old):
        def lead(x, batched):  # give every argument the new axis, then fold it into B
            x = x if batched else jnp.broadcast_to(x, (axis_size,) + x.shape)
            return x.reshape((-1,) + x.shape[2:])

        keys_b, done_b, old_b = in_batched
        out = fn(lead(keys, keys_b), lead(done, done_b), jax.tree.map(lead, old, old_b))
        out = jax.tree.map(lambda x: x.reshape((axis_size, -1) + x.shape[1:]), out)
        return out, jax.tree.map(lambda _: True, out)

    return fn


class ExploreGoalsPaperEnv(MazeEnv):
    """``explore-goals-paper``: the paper's wording of Explore Goal Locations (no rooms, a new
    goal after each pickup); ``MazeState.world`` holds the episode's maze."""

    def __init__(self, generator: MazeGenerator = MazeGenerator(), max_steps: int = 1350,
                 goal_reward: float = 10.0, motion: str = "dmlab", look: str = "dmlab", **kwargs):
        """``motion``: "dmlab" or "doom" (``pmove.params_for``); ``look``: "dmlab" or
        "invented" (the generator's ``look`` is set to it); a ``motion_params`` or ``camera``
        in ``kwargs`` (MazeEnv's) wins."""
        kwargs.setdefault("motion_params", pmove.params_for(motion))
        generator = dataclasses.replace(generator, look=dmlab_look.check_look(look))
        if look == "dmlab":  # no floor grid: one floor, MISHMASH's first
            kwargs.setdefault("camera", dmlab_look.CAMERA)
            kwargs["look"] = dmlab_look.text_level_look(generator.template().walls)
        self.generator = generator
        self.goal_reward = goal_reward
        task = MazeTask("explore-goals-paper", random_heading=True, max_steps=max_steps, num_actions=3)
        template = generator.template()
        # the goal pays ``goal_reward`` and does not end the episode
        items = template.items._replace(reward=jnp.full((1,), goal_reward), ends=jnp.zeros((1,), bool))
        template = template._replace(items=items)
        super().__init__(template, task, **kwargs)
        self._regenerate = regenerate_where_done(generator, template)

    def _place(self, key, world: Layout):
        """A random start pose and a goal in another random cell."""
        k_goal, k_cell, k_head = jax.random.split(key, 3)
        num = self.generator.graph.num_cells
        goal = jax.random.randint(k_goal, (), 0, num)
        cell = (goal + jax.random.randint(k_cell, (), 1, num)) % num
        heading = jax.random.uniform(k_head, (), minval=-math.pi, maxval=math.pi)
        pose = self.motion_model.Pose.at(world.spawns[cell], heading)
        items = world.items._replace(pos=world.spawns[goal][None])
        return pose, world._replace(items=items)

    def _start(self, key):
        k_maze, k_place = jax.random.split(key)
        return self._place(k_place, self.generator.generate(k_maze, self.layout))

    def _restart(self, key, done, pose, world):
        k_maze, k_place = jax.random.split(key)
        one = lambda x: x[None]
        maze = jax.tree.map(lambda x: x[0], self._regenerate(one(k_maze), one(done), jax.tree.map(one, world)))
        fresh_pose, placed = self._place(k_place, maze)
        pose = jax.tree.map(lambda n, o: jnp.where(done, n, o), fresh_pose, pose)
        items = jax.tree.map(lambda n, o: jnp.where(done, n, o), placed.items, world.items)
        return pose, maze._replace(items=items)

    def _on_touch(self, key, pose, world, collected):
        # the goal was touched: the agent moves to a random cell and the goal to another
        new_pose, new_world = self._place(key, world)
        new_pose = self._respawned(new_pose, pose)
        hit = collected[0]
        pose, world = jax.tree.map(lambda n, o: jnp.where(hit, n, o), (new_pose, new_world), (pose, world))
        return pose, world, jnp.zeros_like(collected)

    def _success(self, reached, ep_return):
        return ep_return > 0


class ExploreGoalsEnv(MazeEnv):
    """``explore-goals``: Explore Goal Locations Small with DMLab's map and rules (module
    docstring). ``MazeState.world`` holds the episode's maze; its ``items`` the goal, its
    ``spawns`` the 'P' cells (slots of rooms the maze does not have sit at 1e9)."""

    def __init__(self, generator: DMLabMazeGenerator = DMLabMazeGenerator(), max_steps: int = 1350,
                 goal_reward: float = 10.0, motion: str = "dmlab", look: str = "dmlab", **kwargs):
        """``motion``: "dmlab" or "doom" (``pmove.params_for``); ``look``: "dmlab" or
        "invented" (the generator's ``look`` is set to it); a ``motion_params`` or ``camera``
        in ``kwargs`` (MazeEnv's) wins."""
        kwargs.setdefault("motion_params", pmove.params_for(motion))
        generator = dataclasses.replace(generator, look=dmlab_look.check_look(look))
        if look == "dmlab":  # a floor grid of the maze's cells
            kwargs.setdefault("camera", dmlab_look.CAMERA)
            kwargs["look"] = dmlab_look.text_level_look(generator.template().walls, floor_cell=generator.cell_size)
        self.generator = generator
        self.goal_reward = goal_reward
        task = MazeTask("explore-goals", random_heading=True, max_steps=max_steps, num_actions=3)
        template = generator.template()
        # the goal pays ``goal_reward`` (pickups.lua: goal, 10) and restarts the level, not the episode
        items = template.items._replace(reward=jnp.full((1,), goal_reward), ends=jnp.zeros((1,), bool))
        template = template._replace(items=items)
        super().__init__(template, task, **kwargs)
        self._regenerate = regenerate_where_done(generator, template)

    def _respawn(self, key, world: Layout):
        """A uniformly drawn spawn point ('P') of the maze, a uniformly random heading."""
        k_spot, k_head = jax.random.split(key)
        valid = world.spawns[:, 0] < _FAR / 2
        spot = jax.random.categorical(k_spot, jnp.where(valid, 0.0, -jnp.inf))
        heading = jax.random.uniform(k_head, (), minval=-math.pi, maxval=math.pi)
        return self.motion_model.Pose.at(world.spawns[spot], heading)

    def _start(self, key):
        k_maze, k_spawn = jax.random.split(key)
        world = self.generator.generate(k_maze, self.layout)
        return self._respawn(k_spawn, world), world

    def _restart(self, key, done, pose, world):
        k_maze, k_spawn = jax.random.split(key)
        one = lambda x: x[None]
        maze = jax.tree.map(lambda x: x[0], self._regenerate(one(k_maze), one(done), jax.tree.map(one, world)))
        fresh = self._respawn(k_spawn, maze)
        pose = jax.tree.map(lambda n, o: jnp.where(done, n, o), fresh, pose)
        return pose, maze

    def _on_touch(self, key, pose, world, collected):
        # the goal was touched: the level restarts, the agent alone moves to a spawn point and
        # the goal is back in its place
        hit = collected[0]
        pose = jax.tree.map(lambda n, o: jnp.where(hit, n, o), self._respawned(self._respawn(key, world), pose), pose)
        return pose, world, jnp.zeros_like(collected)

    def _success(self, reached, ep_return):
        return ep_return > 0


__all__ = ["ExploreGoalsEnv", "ExploreGoalsPaperEnv", "MazeGenerator", "DMLabMazeGenerator", "GridGraph",
           "random_spanning_tree"]
