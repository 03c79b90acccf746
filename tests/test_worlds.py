"""The paper's other two worlds: ``melon`` (Stairway to Melon) and ``explore-goals`` (generated
mazes: DMLab's generator and rules, and the paper's wording as ``explore-goals-paper``), and the
item sprites they use."""

import collections
import math

import chex
import dmlab_reference
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import walk

from simjax.envs import make, raycaster
from simjax.envs.dmlab import dmlab_maze, melon, pmove
from simjax.envs.dmlab import look as dmlab_look
from simjax.envs.dmlab.dmlab_maze import DMLabMazeGenerator
from simjax.envs.dmlab.explore_goals import ExploreGoalsEnv, ExploreGoalsPaperEnv, GridGraph, MazeGenerator, random_spanning_tree


def _placed(env, x, y, degrees, key=0):
    """A fresh state of ``env`` with the agent moved to (x, y) facing ``degrees``, standing still."""
    state = jax.jit(env.reset)(jax.random.PRNGKey(key))
    pose = env.motion_model.Pose.at(jnp.array([x, y], jnp.float32), jnp.float32(math.radians(degrees)))
    return state.replace(pipeline_state=state.pipeline_state._replace(pose=pose))


def _count(frame, lo, hi):
    """Pixels whose RGB lies within [lo, hi] per channel."""
    f = np.asarray(frame).astype(int)
    return int(np.all((f >= np.asarray(lo)) & (f <= np.asarray(hi)), axis=-1).sum())


RED = ((120, 0, 0), (255, 60, 60))  # an apple's body
YELLOW = ((200, 200, 0), (255, 255, 110))  # the lemon's body (not the orange floor, nor the apples' edges on it)


# ---- melon ---------------------------------------------------------------------------------
L, R, F = pmove.TURN_LEFT, pmove.TURN_RIGHT, pmove.FORWARD


def _route(*legs):
    """Actions: (action, count) legs one after the other, for DMLab's motion (``pmove``).
    Eleven turn steps turn 92.9 degrees (8.4485 a step); the small overshoot keeps the agent
    pressed to the block's wall it slides along. Forward from rest covers 7.2, 16.1, 20.4
    units in its first steps, then 20.48 a step, so the 437 units to the end of the south
    side (from x = +-60) take 23 steps, the 977 up a side 49, the 447 along the north side to
    the cliff 23, and the 372 along the platform until the melon is within reach (x >= -90,
    ``BG_PlayerTouchesItem``'s 50 units) 20; each leg below has 2-3 steps to spare."""
    return jnp.asarray([a for a, n in legs for _ in range(n)], jnp.int32)


# east along the south side, north up the east side, west along the north side to the cliff
APPLE_ROUTE = _route((F, 25), (L, 11), (F, 52), (L, 11), (F, 25))
# west through the lemon, north up the stair corridor, east along the platform to the melon
LEMON_ROUTE = _route((F, 25), (R, 11), (F, 52), (R, 11), (F, 22))


def test_melon_holds_the_fruit_of_dmlab_stairway_to_melon_map():
    # assets/maps/stairway_to_melon.map: 14 apple_reward, 1 lemon_reward, 1 watermelon_goal
    items = make("melon").layout.items
    look, reward, ends = (np.asarray(v) for v in (items.look, items.reward, items.ends))
    assert (look == raycaster.APPLE).sum() == len(melon.APPLES_XY) == 14
    assert (look == raycaster.LEMON).sum() == 1 and (look == raycaster.MELON).sum() == 1
    assert set(reward[look == raycaster.APPLE]) == {1.0} and reward[look == raycaster.LEMON] == -1.0
    assert reward[look == raycaster.MELON] == 20.0 and ends.tolist() == [False] * 15 + [True]
    pos = np.asarray(items.pos)
    # every fruit lies in the ring corridor between the block (|x|, |y| < 448) and the outer walls
    inside = np.all(np.abs(pos) < 512, 1) & np.any(np.abs(pos) > 448, 1)
    assert inside.all()
    np.testing.assert_allclose(pos[-1], (-40, 480))  # the melon, on the platform past the stairs


def test_melon_apple_route_pays_fourteen_and_ends_at_the_cliff():
    env = make("melon")
    run = jax.jit(lambda s, a: walk(env, s, a))
    states = run(_placed(env, 60.0, -480.0, 0.0), APPLE_ROUTE)
    reward = np.asarray(states.reward)
    assert reward.sum() == 14 and set(reward[reward != 0]) == {1.0}
    assert np.asarray(states.done).sum() == 0  # the dead end ends nothing
    collected = np.asarray(states.pipeline_state.collected)[-1]
    assert collected[:14].all() and not collected[14:].any()  # neither the lemon nor the melon
    x, y = np.asarray(states.pipeline_state.pose.pos[-1])
    # stopped by the cliff under the melon: the box's half-size and Quake's 1/8 unit short of it
    assert x == pytest.approx(melon.CLIFF_X + env.motion_params.radius + env.motion_params.clip_epsilon, abs=0.01)
    assert y > 448


def test_melon_lemon_route_costs_one_and_the_melon_ends_the_episode():
    env = make("melon")
    run = jax.jit(lambda s, a: walk(env, s, a))
    states = run(_placed(env, -60.0, -480.0, 180.0), LEMON_ROUTE)
    done, reward = np.asarray(states.done), np.asarray(states.reward)
    t = int(np.argmax(done))
    assert done[t] == 1 and reward[t] == 20.0 and reward[:t].sum() == -1.0
    assert states.metrics["episode_success"][t] == 1 and states.info["truncation"][t] == 0
    assert states.metrics["episode_return"][t] == 19.0
    # the next episode starts at the start, facing north, every fruit back in place
    np.testing.assert_allclose(np.asarray(states.pipeline_state.pose.pos[t]), melon.START_XY)
    assert float(states.pipeline_state.pose.heading[t]) == pytest.approx(math.pi / 2, abs=1e-3)
    assert not np.asarray(states.pipeline_state.collected[t]).any()


def test_melon_has_three_actions_and_525_steps():
    env = make("melon")
    assert env.action_size == 3 and env.task.max_steps == 525
    states = jax.jit(lambda s, a: walk(env, s, a))(jax.jit(env.reset)(jax.random.PRNGKey(0)), jnp.zeros((525,), jnp.int32))
    assert np.flatnonzero(np.asarray(states.done)).tolist() == [524]
    assert states.info["truncation"][524] == 1 and states.metrics["episode_success"][524] == 0


def test_melon_dmlab_rules_restart_the_level_at_the_melon_and_run_900_steps():
    env = make("melon-dmlab")
    assert env.action_size == 3 and env.task.max_steps == 900
    run = jax.jit(lambda s, a: walk(env, s, a))
    pad = lambda route: jnp.concatenate([route, jnp.full((900 - route.shape[0],), L, jnp.int32)])
    # the lemon route to the melon, then turning on the spot where the level put the agent back
    states = run(_placed(env, -60.0, -480.0, 180.0), pad(LEMON_ROUTE))
    done, reward = np.asarray(states.done), np.asarray(states.reward)
    t = int(np.argmax(reward == 20.0))
    assert reward[t] == 20.0 and reward[:t].sum() == -1.0 and reward[t + 1:].sum() == 0
    np.testing.assert_allclose(np.asarray(states.pipeline_state.pose.pos[t]), melon.START_XY)
    assert not np.asarray(states.pipeline_state.collected[t]).any()  # every fruit back, the lemon too
    assert np.flatnonzero(done).tolist() == [899]  # the melon ended nothing; the clock did
    assert states.metrics["episode_success"][899] == 1 and states.metrics["episode_return"][899] == 19.0
    # the apple route's 14 points without the melon are no success
    states = run(_placed(env, 60.0, -480.0, 0.0), pad(APPLE_ROUTE))
    assert np.flatnonzero(np.asarray(states.done)).tolist() == [899]
    assert states.metrics["episode_return"][899] == 14.0 and states.metrics["episode_success"][899] == 0


def test_fruit_sprites_have_their_own_look_and_vanish_once_collected():
    env = make("melon")
    east = env.motion_model.Pose.at(jnp.array([40.0, -480.0]), jnp.float32(0.0))  # down the south side: apples
    west = env.motion_model.Pose.at(jnp.array([-40.0, -480.0]), jnp.float32(math.pi))  # the lemon
    render = jax.jit(env.render)
    every = jnp.ones((env.num_items,), bool)
    apples, lemon = np.asarray(render(east)), np.asarray(render(west))
    gone_east, gone_west = np.asarray(render(east, None, every)), np.asarray(render(west, None, every))
    # the pixels the fruit cover (the orange floor is no fruit): red apples, a yellow lemon
    on_apples, on_lemon = np.any(apples != gone_east, -1), np.any(lemon != gone_west, -1)
    assert _count(apples[on_apples], *RED) >= 8 and _count(apples[on_apples], *YELLOW) == 0
    assert _count(lemon[on_lemon], *YELLOW) >= 4 and _count(lemon[on_lemon], *RED) == 0
    assert _count(gone_east, *RED) == 0


def test_nearer_sprites_hide_farther_ones():
    # a melon right in front of the eye, an apple behind it on the same line of sight
    walls = raycaster.Walls.from_rows([(-1000, -200, 100, -200, 8), (100, -200, 100, 200, 8),
                                       (100, 200, -1000, 200, 8), (-1000, 200, -1000, -200, 8)])
    sprites = raycaster.Sprites(jnp.array([[-800.0, 0.0], [-650.0, 0.0]]), jnp.array([raycaster.MELON, raycaster.APPLE]),
                                jnp.ones(2, bool))
    eye = jnp.array([-900.0, 0.0])
    render = jax.jit(raycaster.render)
    frame = lambda visible: np.asarray(render(walls, eye, jnp.float32(0.0), sprites._replace(visible=jnp.array(visible))))
    apple = np.any(frame([False, True]) != frame([False, False]), axis=-1)  # the apple's pixels
    assert apple.sum() >= 2
    # with both drawn, every apple pixel shows the melon (the apple alone shows through nowhere)
    np.testing.assert_array_equal(frame([True, True])[apple], frame([True, False])[apple])
    # and the melon behind a nearer apple is hidden where they overlap
    near_apple = sprites._replace(pos=jnp.array([[-300.0, 0.0], [-850.0, 0.0]]))
    seen = lambda v: np.asarray(render(walls, eye, jnp.float32(0.0), near_apple._replace(visible=jnp.array(v))))
    apple = np.any(seen([False, True]) != seen([False, False]), axis=-1)
    np.testing.assert_array_equal(seen([True, True])[apple], seen([False, True])[apple])


# ---- explore-goals: DMLab's generator ------------------------------------------------------
def _open_components(open_grid, start):
    """Flood fill (numpy) of a text grid's open cells from ``start``: the set reached."""
    h, w = open_grid.shape
    seen, todo = {start}, [start]
    while todo:
        r, c = todo.pop()
        for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            n = (r + dr, c + dc)
            if 0 <= n[0] < h and 0 <= n[1] < w and open_grid[n] and n not in seen:
                seen.add(n)
                todo.append(n)
    return seen


@pytest.fixture(scope="module")
def dmlab_mazes():
    gen = DMLabMazeGenerator()
    keys = jax.random.split(jax.random.PRNGKey(0), 300)
    return gen, jax.tree.map(np.asarray, jax.jit(jax.vmap(gen.maze))(keys))


def test_dmlab_generator_has_explore_goal_locations_small_settings():
    # factories/explore/factory.lua defaults, passed to randomMazeGeneration unchanged by
    # goal_locations_factory.lua for explore_goal_locations_small.lua
    gen = DMLabMazeGenerator()
    assert (gen.height, gen.width, gen.max_rooms, gen.room_min_size, gen.room_max_size) == (11, 11, 4, 3, 5)
    assert (gen.room_spawn_count, gen.room_object_count, gen.extra_connection_prob) == (5, 4, 0.0)
    assert gen.simplify and gen.cell_size == 100.0 and gen.decal_frequency == 0.1
    # MakeRandomRectangle's proposals: 3x3 rooms half the time, 3x5 and 5x3 a quarter each
    props, prob = gen.room_proposals()
    assert prob.sum() == pytest.approx(1.0)
    sizes = collections.defaultdict(float)
    for (_, _, h, w), p in zip(props, prob):
        sizes[(2 * h + 1, 2 * w + 1)] += p
    assert dict(sizes) == pytest.approx({(3, 3): 0.5, (3, 5): 0.25, (5, 3): 0.25})
    for name, bad in [("height", 10), ("room_max_size", 11), ("extra_connection_prob", 2.0)]:
        with pytest.raises(ValueError, match=name):
            DMLabMazeGenerator(**{name: bad})


def test_dmlab_mazes_have_rooms_spawns_and_goals(dmlab_mazes):
    gen, m = dmlab_mazes
    counts = m["room_valid"].sum(1)
    # up to 4 rooms; rooms placed at random often leave no place for a fourth (of 2,000 mazes
    # 71% had 4, 28% 3, 1.5% 2)
    assert counts.min() >= 2 and counts.max() == 4 and 3.5 < counts.mean() < 3.9
    for i in range(len(counts)):
        rooms = [m["room_rc"][i, k] for k in range(gen.max_rooms) if m["room_valid"][i, k]]
        covered = np.zeros((11, 11), int)
        for r, c, h, w in rooms:
            assert (2 * h + 1, 2 * w + 1) in {(3, 3), (3, 5), (5, 3)}
            covered[2 * r + 1:2 * (r + h) + 2, 2 * c + 1:2 * (c + w) + 2] += 1
        assert covered.max() == 1  # rooms never overlap ...
        np.testing.assert_array_equal(covered == 1, m["room"][i])
        assert (m["grid"][i][m["room"][i]] == dmlab_maze.EMPTY).all()  # ... and are open all through
        # 5 spawn points and 4 goal candidates per room, distinct cells inside the rooms
        sp = m["spawn_cells"][i][m["spawn_valid"][i]]
        gl = m["goal_cells"][i][m["goal_valid"][i]]
        assert len(sp) == 5 * len(rooms) and len(gl) == 4 * len(rooms)
        cells = [tuple(x) for x in np.concatenate([sp, gl])]
        assert len(set(cells)) == len(cells) and all(m["room"][i][c] for c in cells)


def test_dmlab_mazes_are_connected_without_dead_ends(dmlab_mazes):
    _, m = dmlab_mazes
    for i in range(len(m["grid"])):
        is_open = m["grid"][i] == dmlab_maze.EMPTY
        assert not is_open[0].any() and not is_open[-1].any() and not is_open[:, 0].any() and not is_open[:, -1].any()
        goal = tuple(m["goal_cells"][i][0])
        reached = _open_components(is_open, goal)
        assert len(reached) == is_open.sum()  # every open cell, so every spawn and goal, connected
        # simplified: outside rooms no open cell is a dead end
        p = np.pad(is_open, 1)
        nbrs = p[:-2, 1:-1].astype(int) + p[2:, 1:-1] + p[1:-1, :-2] + p[1:-1, 2:]
        assert (nbrs[is_open & ~m["room"][i]] >= 2).all()


@pytest.mark.parametrize("size", [11, 21])
def test_dmlab_simplification_matches_dmlab_step_by_step(size):
    # the vectorised dead-end and horseshoe removal against a sequential transcription of
    # algorithm.cc (tests/dmlab_reference.py) on the same unsimplified mazes; at 21x21 almost
    # every maze has horseshoe bends to pull
    gen = DMLabMazeGenerator(height=size, width=size)
    raw = jax.jit(jax.vmap(lambda k: gen.maze(k)["raw"]))(jax.random.split(jax.random.PRNGKey(size), 50))
    got = np.asarray(jax.jit(jax.vmap(lambda g: dmlab_maze.simplify(g, size)))(raw))
    bends = 0
    for r, g in zip(np.asarray(raw), got):
        rows = dmlab_maze.to_text(r).split("\n")
        want = dmlab_reference.simplify(rows)
        assert dmlab_maze.to_text(g).split("\n") == want
        bends += want != ["".join(x) for x in dmlab_reference.remove_dead_ends([list(x) for x in rows])]
    assert bends > (40 if size == 21 else -1)


def test_dmlab_layout_walls_are_the_faces_between_open_and_walled_cells():
    gen = DMLabMazeGenerator()
    keys = jax.random.split(jax.random.PRNGKey(3), 10)
    mazes = jax.jit(jax.vmap(lambda k: gen.maze(jax.random.split(k, 3)[0])))(keys)  # as generate draws it
    layouts = jax.jit(jax.vmap(gen.generate))(keys)
    _, side_a, side_b = gen.faces()
    centres = gen.cell_centres()
    for i in range(10):
        layout = jax.tree.map(lambda x, i=i: x[i], layouts)
        is_open = (np.asarray(mazes["grid"][i]) == dmlab_maze.EMPTY).reshape(-1)
        standing = layout.walls.standing()
        np.testing.assert_array_equal(standing, is_open[side_a] != is_open[side_b])
        assert (np.asarray(layout.boxes)[~standing] > 1e8).all()  # open faces are out of reach
        # the goal is a 'G' cell's centre; the spawn spots the 'P' cells' (missing rooms far away)
        goals = {tuple(centres[r, c]) for (r, c), ok in zip(np.asarray(mazes["goal_cells"][i]),
                                                             np.asarray(mazes["goal_valid"][i])) if ok}
        assert tuple(np.asarray(layout.items.pos[0])) in goals
        sp_ok = np.asarray(mazes["spawn_valid"][i])
        spawns = np.asarray(layout.spawns)
        np.testing.assert_array_equal(spawns[:, 0] < 1e8, sp_ok)
        want = [centres[r, c] for r, c in np.asarray(mazes["spawn_cells"][i])[sp_ok]]
        np.testing.assert_allclose(spawns[sp_ok], want)
    looks = np.asarray(layouts.walls.texture)
    standing = np.stack([jax.tree.map(lambda x, i=i: x[i], layouts).walls.standing() for i in range(10)])
    assert len(np.unique(looks[standing])) > 2  # the corridors' wall and each maze's drawn room wall


# ---- explore-goals: the DMLab task ----------------------------------------------------------
def _respawned_at_spawn_point(world, pos):
    spawns = np.asarray(world.spawns)
    return np.min(np.abs(spawns - np.asarray(pos)).sum(1)) < 1e-3


def test_explore_goals_is_dmlab_by_default_and_paper_on_request():
    dm, paper = make("explore-goals"), make("explore-goals-paper")
    assert isinstance(dm, ExploreGoalsEnv) and isinstance(dm.generator, DMLabMazeGenerator)
    assert isinstance(paper, ExploreGoalsPaperEnv) and isinstance(paper.generator, MazeGenerator)
    for env in (dm, paper):
        assert env.action_size == 3 and env.task.max_steps == 1350
        assert float(env.layout.items.reward[0]) == 10.0 and not bool(env.layout.items.ends[0])


def test_explore_goals_pickup_respawns_the_agent_and_keeps_the_goal():
    env = make("explore-goals")
    state = jax.jit(env.reset)(jax.random.PRNGKey(2))
    ms = state.pipeline_state
    assert _respawned_at_spawn_point(ms.world, ms.pose.pos)
    goal = np.asarray(ms.world.items.pos)
    step = jax.jit(env.step)
    # the agent stepped onto the goal
    onto = state.replace(pipeline_state=ms._replace(pose=env.motion_model.Pose.at(ms.world.items.pos[0], ms.pose.heading)))
    after = step(onto, jnp.int32(0))
    assert float(after.reward) == 10.0 and float(after.done) == 0.0 and float(after.pipeline_state.ep_return) == 10.0
    new = after.pipeline_state
    np.testing.assert_array_equal(np.asarray(new.world.items.pos), goal)  # the goal stays
    np.testing.assert_array_equal(np.asarray(new.world.walls.v_lo), np.asarray(ms.world.walls.v_lo))  # same maze
    assert _respawned_at_spawn_point(new.world, new.pose.pos)  # the agent moved to a spawn point
    assert not bool(env.touches(new.world.items.pos, new.pose.pos)[0])  # ... off the goal
    assert not np.asarray(new.collected).any()  # the goal is back, to be found again
    again = step(after.replace(pipeline_state=new._replace(
        pose=env.motion_model.Pose.at(new.world.items.pos[0], new.pose.heading))), jnp.int32(0))
    assert float(again.reward) == 10.0 and float(again.pipeline_state.ep_return) == 20.0


@pytest.fixture(scope="module")
def explore_goals_walks():
    """8 agents x 300 random steps (turn, turn, forward at 0.2, 0.2, 0.6) through DMLab's
    explore-goals with 40-step episodes, so 7 new mazes each: one compiled program for the two
    tests below. The states after each step, on the host."""
    return _walks(ExploreGoalsEnv(max_steps=40))


def _walks(env):
    keys = jax.random.split(jax.random.PRNGKey(5), 8)
    actions = jax.random.choice(jax.random.PRNGKey(6), 3, (8, 300), p=jnp.array([0.2, 0.2, 0.6]))
    run = jax.jit(jax.vmap(lambda k, a: walk(env, k, a)))
    return env, jax.device_get(run(keys, actions)), jax.device_get(run(keys, actions))  # twice: determinism


def test_explore_goals_goal_and_maze_stay_all_episode_and_change_between(explore_goals_walks):
    _, states, _ = explore_goals_walks
    done = np.asarray(states.done)
    assert (done.sum(1) == 7).all() and (np.asarray(states.info["truncation"])[done > 0] == 1).all()
    goal = np.asarray(states.pipeline_state.world.items.pos[:, :, 0])  # (8, T, 2)
    walls = np.asarray(states.pipeline_state.world.walls.v_lo)  # (8, T, V)
    for i in range(8):
        ends = np.flatnonzero(done[i])
        episodes = np.split(np.arange(300), ends + 1)[:-1]
        for ep in episodes:
            after_end = ep[:-1]  # the last state of an episode already holds the next one
            assert (goal[i, after_end] == goal[i, after_end[0]]).all()
            assert (walls[i, after_end] == walls[i, after_end[0]]).all()
        firsts = [ep[0] for ep in episodes[1:]]
        assert all(not (walls[i, a] == walls[i, b]).all() for a, b in zip([ends[0] - 1] + firsts[:-1], firsts))


def _assert_walks_never_cross_a_wall(env, states):
    """No state's player box overlaps a wall of its own maze, and the agents moved 1.5 units a
    step on average within episodes (agents pinned in corners turn out slowly: 8.4 deg a step).
    Returns the positions (8, T, 2)."""
    r = env.motion_params.radius
    pos = np.asarray(states.pipeline_state.pose.pos)  # (8, T, 2)
    boxes = np.asarray(states.pipeline_state.world.boxes)  # (8, T, S, 4): each state's own maze
    overlap = ((pos[..., None, 0] - r < boxes[..., 2]) & (pos[..., None, 0] + r > boxes[..., 0])
               & (pos[..., None, 1] - r < boxes[..., 3]) & (pos[..., None, 1] + r > boxes[..., 1]))
    assert not overlap.any()
    moves = np.abs(np.diff(pos, axis=1)).sum(-1)  # (8, T - 1)
    within = np.asarray(states.done)[:, 1:] == 0  # not the jump to a new episode's spawn point
    assert moves[within].sum() > within.sum() * 1.5
    return pos


def test_explore_goals_agents_never_cross_a_standing_wall(explore_goals_walks):
    pos = _assert_walks_never_cross_a_wall(*explore_goals_walks[:2])
    assert (np.abs(pos - 550) < 450).all()  # inside the maze's outer wall ring


# ---- explore-goals-paper: the paper's wording ---------------------------------------------
def _components(num_cells, a, b, is_open):
    """Flood fill (numpy): the number of cells reachable from cell 0 through open edges."""
    nbrs = collections.defaultdict(list)
    for e in np.flatnonzero(is_open):
        nbrs[a[e]].append(b[e])
        nbrs[b[e]].append(a[e])
    seen, todo = {0}, [0]
    while todo:
        for n in nbrs[todo.pop()]:
            if n not in seen:
                seen.add(n)
                todo.append(n)
    return len(seen)


@pytest.mark.parametrize("cells", [2, 9, 11])
def test_spanning_tree_connects_every_cell_without_loops(cells):
    graph = GridGraph(cells)
    a, b = graph.edges()
    trees = np.asarray(jax.jit(jax.vmap(lambda k: random_spanning_tree(k, graph)))(
        jax.random.split(jax.random.PRNGKey(cells), 300)))
    for tree in trees:
        assert tree.sum() == graph.num_cells - 1  # V - 1 edges ...
        assert _components(graph.num_cells, a, b, tree) == graph.num_cells  # ... and connected: a tree
    # random: every tree a different one on big grids; on 2x2 (a 4-cycle) each of its 4 trees
    # (drop the heaviest edge) about equally often
    counts = collections.Counter(t.tobytes() for t in trees)
    if cells == 2:
        assert len(counts) == 4 and all(45 <= c <= 105 for c in counts.values())
    else:
        assert len(counts) == len(trees)
    assert trees.any(axis=0).all()


def test_generated_mazes_are_connected_have_loops_and_match_their_walls():
    gen = MazeGenerator()
    a, b = gen.graph.edges()
    keys = jax.random.split(jax.random.PRNGKey(0), 300)
    is_open = np.asarray(jax.jit(jax.vmap(lambda k: gen.open_edges(jax.random.split(k)[0])))(keys))  # as generate
    layouts = jax.jit(jax.vmap(gen.generate))(keys[:20])
    for edges in is_open:
        assert _components(gen.graph.num_cells, a, b, edges) == gen.graph.num_cells  # every goal reachable
    extra = is_open.sum(1) - (gen.graph.num_cells - 1)
    assert (extra >= 0).all() and extra.mean() > 2  # loops: ~10% of the non-tree walls are open
    for i in range(20):
        layout = jax.tree.map(lambda x, i=i: x[i], layouts)
        standing = layout.walls.standing()
        edges = len(a)
        np.testing.assert_array_equal(standing[:edges], ~is_open[i])  # open edge = no wall
        assert standing[edges:].all()  # the boundary always stands
        far = np.asarray(layout.boxes)[:edges][is_open[i]]
        assert (far > 1e8).all()  # an open wall's collision box is out of reach
    looks = np.asarray(layouts.walls.texture)  # DMLab's look: MISHMASH's 20 walls
    assert len(np.unique(looks)) == len(dmlab_look.MISHMASH_WALLS) and not (looks == looks[0]).all()


def test_generator_rejects_bad_settings():
    with pytest.raises(ValueError, match="cells"):
        MazeGenerator(cells=1)
    with pytest.raises(ValueError, match="loop_prob"):
        MazeGenerator(loop_prob=1.5)


@pytest.fixture(scope="module")
def paper_walks():
    """As ``explore_goals_walks``, in the paper's wording of the task (``explore-goals-paper``)."""
    return _walks(ExploreGoalsPaperEnv(max_steps=40))


def test_explore_goals_paper_new_maze_each_episode_same_maze_within(paper_walks):
    _, states, _ = paper_walks
    standing = np.asarray(states.pipeline_state.world.walls.v_lo) < 1e8  # (8, T, V) per step
    done = np.asarray(states.done)
    assert [np.flatnonzero(d).tolist() for d in done] == [list(range(39, 300, 40))] * 8
    assert (states.info["truncation"][done > 0] == 1).all()  # the time limit; there is no other end
    for i in range(8):
        for end in range(39, 300, 40):
            assert (standing[i, end - 39] == standing[i, end - 1]).all()  # same maze within an episode
            assert not (standing[i, end] == standing[i, end - 1]).all()  # a new one after its end


def test_explore_goals_paper_goal_pays_ten_and_moves_agent_and_goal():
    env = make("explore-goals-paper")
    assert env.action_size == 3 and env.task.max_steps == 1350
    state = jax.jit(env.reset)(jax.random.PRNGKey(2))
    ms = state.pipeline_state
    world = ms.world._replace(items=ms.world.items._replace(pos=ms.pose.pos[None]))  # goal under the agent
    state = state.replace(pipeline_state=ms._replace(world=world))
    after = jax.jit(env.step)(state, jnp.int32(0))
    assert float(after.reward) == 10.0 and float(after.done) == 0.0
    new = after.pipeline_state
    assert not np.allclose(np.asarray(new.pose.pos), np.asarray(ms.pose.pos))
    assert not np.allclose(np.asarray(new.world.items.pos), np.asarray(new.pose.pos))
    assert not np.asarray(new.collected).any()
    np.testing.assert_array_equal(np.asarray(new.world.walls.v_lo), np.asarray(ms.world.walls.v_lo))  # same maze
    # agent and goal sit at cell centres
    centres = env.generator.cell_centres()
    for p in (new.pose.pos, new.world.items.pos[0]):
        assert np.min(np.abs(centres - np.asarray(p)).sum(1)) < 1e-3
    assert float(new.ep_return) == 10.0


def test_explore_goals_paper_agents_never_cross_a_standing_wall(paper_walks):
    _assert_walks_never_cross_a_wall(*paper_walks[:2])


@pytest.mark.parametrize("walks", ["explore_goals_walks", "paper_walks"])
def test_explore_goals_shapes_dtypes_and_determinism(walks, request):
    """On the walks' vmapped program: the registered tasks are these envs with 1,350-step episodes."""
    env, states, again = request.getfixturevalue(walks)
    chex.assert_shape(states.obs, (8, 300, 42, 42, 3))
    chex.assert_type(states.obs, jnp.uint8)
    chex.assert_shape([states.reward, states.done, states.info["truncation"]], (8, 300))
    chex.assert_type([states.reward, states.done], jnp.float32)
    chex.assert_tree_all_finite(states.pipeline_state.pose)
    chex.assert_trees_all_equal(states, again)
    name = "explore-goals" if walks == "explore_goals_walks" else "explore-goals-paper"
    registered = make(name)
    assert type(registered) is type(env) and registered.task.max_steps == 1350
    assert registered.action_size == env.action_size == 3 and registered.observation_size == (42, 42, 3)


@pytest.mark.parametrize("name,actions", [("melon", 3)])
def test_new_tasks_shapes_dtypes_and_determinism(name, actions):
    env = make(name)
    keys = jax.random.split(jax.random.PRNGKey(0), 4)
    reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
    s = reset(keys)
    chex.assert_shape(s.obs, (4, 42, 42, 3))
    chex.assert_type(s.obs, jnp.uint8)
    s2 = step(s, jnp.array([0, 1, 2, 2]))
    chex.assert_shape([s2.reward, s2.done, s2.info["truncation"]], (4,))
    chex.assert_type([s2.reward, s2.done], jnp.float32)
    chex.assert_tree_all_finite(s2.pipeline_state.pose)
    chex.assert_trees_all_equal(s2, step(reset(keys), jnp.array([0, 1, 2, 2])))
    assert env.action_size == actions and env.observation_size == (42, 42, 3)


def test_mazes_are_regenerated_only_where_done_under_nested_vmap():
    env = make("explore-goals-paper")
    gen = env.generator
    keys = jax.random.split(jax.random.PRNGKey(4), 6).reshape(2, 3, 2)
    generate = jax.jit(jax.vmap(jax.vmap(lambda k: gen.generate(k, env.layout))))  # one program, not one per op
    old = generate(keys)
    new_keys = jax.random.split(jax.random.PRNGKey(9), 6).reshape(2, 3, 2)
    done = np.array([[False, True, False], [False, False, True]])
    one = lambda x: x[None]
    per_env = lambda k, d, w: jax.tree.map(lambda x: x[0], env._regenerate(one(k), one(d), jax.tree.map(one, w)))
    fn = jax.jit(jax.vmap(jax.vmap(per_env)))
    out, expected, old_host = jax.device_get((fn(new_keys, done, old), generate(new_keys), old))
    for i in range(2):
        for j in range(3):
            got = jax.tree.map(lambda x, i=i, j=j: x[i, j], out)
            want = jax.tree.map(lambda x, i=i, j=j: x[i, j], expected if done[i, j] else old_host)
            chex.assert_trees_all_equal(got, want)
    chex.assert_trees_all_equal(jax.device_get(fn(new_keys, np.zeros_like(done), old)), old_host)
    # the generation stays behind a real conditional after both vmaps (not a select that always runs)
    assert "cond[" in str(jax.make_jaxpr(jax.vmap(jax.vmap(per_env)))(new_keys, done, old))


def test_dmlab_mazes_are_generated_behind_a_conditional_under_nested_vmap():
    env = make("explore-goals")
    keys = jax.random.split(jax.random.PRNGKey(4), 6).reshape(2, 3, 2)
    old = jax.eval_shape(jax.vmap(jax.vmap(lambda k: env.generator.generate(k, env.layout))), keys)
    done = jnp.array([[False, True, False], [False, False, True]])
    one = lambda x: x[None]
    per_env = lambda k, d, w: jax.tree.map(lambda x: x[0], env._regenerate(one(k), one(d), jax.tree.map(one, w)))
    assert "cond[" in str(jax.make_jaxpr(jax.vmap(jax.vmap(per_env)))(keys, done, old))
