"""The renderer, motion and the maze tasks."""

import dataclasses
import math

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import walk

from simjax.envs import TASK_NAMES, make, mywayhome_layout, raycaster, tiny_layout
from simjax.envs.doom import motion, mywayhome_map
from simjax.envs.maze import MazeEnv, MazeTask


def numpy_cast(rows, pos, heading, camera=raycaster.Camera()):
    """Plain reference: general ray/segment intersection, one column and one wall at a time."""
    fwd = np.array([math.cos(heading), math.sin(heading)])
    right = np.array([math.sin(heading), -math.cos(heading)])
    half = math.tan(math.radians(camera.fov_deg) / 2)
    depths, walls = [], []
    for c in range(camera.width):
        d = fwd + ((2 * (c + 0.5) / camera.width - 1) * half) * right
        best, best_i = np.inf, -1
        for i, (x1, y1, x2, y2, _) in enumerate(rows):
            a, e = np.array([x1, y1], float), np.array([x2 - x1, y2 - y1], float)
            den = d[0] * e[1] - d[1] * e[0]
            if abs(den) < 1e-12:
                continue
            q = a - pos
            t = (q[0] * e[1] - q[1] * e[0]) / den
            s = (q[0] * d[1] - q[1] * d[0]) / den
            if t > 1e-4 and 0 <= s <= 1 and t < best:
                best, best_i = t, i
        depths.append(best)
        walls.append(best_i)
    return np.array(depths), np.array(walls)


POSES = [((240.0, -176.0), 0.0), ((464.0, -300.0), 1.3), ((1040.0, -200.0), -1.5708),
         ((575.4, -171.8), 2.7), ((871.5, 54.6), -2.2), ((700.0, -62.0), 0.8)]


@pytest.mark.parametrize("pos,heading", POSES)
def test_raycaster_matches_numpy_reference(pos, heading):
    layout = mywayhome_layout()
    depth, wall, u = jax.jit(raycaster.cast_rays)(layout.walls, jnp.array(pos), jnp.float32(heading))
    ref_depth, ref_wall = numpy_cast(mywayhome_map.WALLS, np.array(pos), heading)
    np.testing.assert_allclose(np.asarray(depth), ref_depth, rtol=1e-4, atol=1e-2)
    # the same wall, except where two walls meet at the hit point (equal depth, a corner)
    same = np.asarray(wall) == ref_wall
    assert np.all(same | (np.abs(np.asarray(depth) - ref_depth) < 1e-2))
    assert same.mean() > 0.9
    # u is the distance from the wall's start to the hit point
    rows = np.asarray(mywayhome_map.WALLS, float)
    hit = np.array(pos) + np.asarray(depth)[:, None] * np.asarray(raycaster.ray_directions(jnp.float32(heading)))
    np.testing.assert_allclose(np.asarray(u), np.linalg.norm(hit - rows[np.asarray(wall), :2], axis=1), atol=0.05)


def test_render_shape_dtype_and_content():
    env = make("maze-dense")
    pose = motion.Pose.at(jnp.array([1040.0, -200.0]), jnp.float32(-math.pi / 2))
    render = jax.jit(env.render)
    frame = render(pose)
    chex.assert_shape(frame, (42, 42, 3))
    chex.assert_type(frame, jnp.uint8)
    # looking down the corridor at the goal, 152 units away: the armour covers about 5x6
    # pixels in the middle columns, below the horizon, and nothing else changes without it
    gone = jnp.ones((1,), bool)
    armour = np.abs(np.asarray(frame, int) - np.asarray(render(pose, None, gone), int)).sum(-1) > 30
    rows, cols = np.nonzero(armour)
    assert 12 <= armour.sum() <= 40
    assert cols.min() >= 17 and cols.max() <= 25 and rows.min() >= 18 and rows.max() <= 30
    # ...and it is hidden when a wall stands between (same spot, facing away)
    away = motion.Pose.at(pose.pos, jnp.float32(math.pi / 2))
    np.testing.assert_array_equal(np.asarray(render(away)), np.asarray(render(away, None, gone)))
    # floor below the horizon, ceiling above, differently lit
    assert not np.array_equal(np.asarray(frame)[0, 0], np.asarray(frame)[-1, 0])


def test_sprite_is_hidden_behind_nearer_walls():
    # goal at (200, 64) in a room; a wall between the eye and the goal must hide it
    rows = [(0, 0, 320, 0, 8), (320, 0, 320, 128, 7), (320, 128, 0, 128, 8), (0, 128, 0, 0, 0),
            (120, 32, 120, 96, 2)]
    walls = raycaster.Walls.from_rows(rows)
    goal = raycaster.Sprites.single([200.0, 64.0])
    render = jax.jit(lambda xy: raycaster.render(walls, xy, jnp.float32(0.0), goal))  # one program, not one per op
    seen, hidden = (np.asarray(render(jnp.array(xy))) for xy in ([150.0, 64.0], [60.0, 64.0]))
    is_green = lambda f: ((f[..., 1] > 150) & (f[..., 0] < 80) & (f[..., 2] < 100)).sum()
    assert is_green(seen) > 10 and is_green(hidden) == 0


def test_textures_tell_walls_apart():
    # the nine MyWayHome textures have distinct base colours
    bases = {look[0] for look in raycaster.TEXTURE_LOOKS[:9]}
    assert len(bases) == 9


def test_walls_must_be_axis_aligned():
    with pytest.raises(ValueError, match="axis-aligned"):
        raycaster.Walls.from_rows([(0, 0, 10, 10, 0)])


def test_walls_need_both_orientations():
    # a map of vertical walls only once crashed the ray caster on an empty gather
    with pytest.raises(ValueError, match="1 vertical, 0 horizontal"):
        raycaster.Walls.from_rows([(0, 0, 0, 10, 0)])
    raycaster.Walls.from_rows([(0, 0, 0, 10, 0), (0, 10, 10, 10, 0)])  # both: accepted




def test_collision_never_through_walls():
    env = MazeEnv(mywayhome_layout(), MazeTask("t", max_steps=10_000), auto_reset=False)
    keys = jax.random.split(jax.random.PRNGKey(3), 16)
    actions = jax.random.choice(jax.random.PRNGKey(4), 4, (16, 400), p=jnp.array([0.15, 0.15, 0.65, 0.05]))
    states = jax.jit(jax.vmap(walk, (None, 0, 0)), static_argnums=0)(env, keys, actions)
    pos = np.asarray(states.pipeline_state.pose.pos).reshape(-1, 2)
    boxes = np.asarray(env.layout.boxes)
    r = env.motion_params.radius
    overlap = ((pos[:, None, 0] - r < boxes[None, :, 2]) & (pos[:, None, 0] + r > boxes[None, :, 0])
               & (pos[:, None, 1] - r < boxes[None, :, 3]) & (pos[:, None, 1] + r > boxes[None, :, 1]))
    assert not overlap.any()
    xmin, ymin, xmax, ymax = mywayhome_map.BBOX
    assert (pos[:, 0] > xmin).all() and (pos[:, 0] < xmax).all()
    assert (pos[:, 1] > ymin).all() and (pos[:, 1] < ymax).all()
    # and the agents did move a lot: this is not a test of standing still
    travelled = np.abs(np.diff(np.asarray(states.pipeline_state.pose.pos), axis=1)).sum()
    assert travelled > 16 * 400 * 1.5  # (agents pinned in corners turn out slowly: Doom turns 7-14 deg a step)


def test_collision_slides_along_a_wall():
    layout = tiny_layout()  # room 0..320 x 0..128
    pose = motion.Pose.at(jnp.array([290.0, 30.0]), jnp.float32(math.pi / 4))
    params = motion.MotionParams()
    for _ in range(40):
        pose = motion.tic(pose, jnp.int32(motion.FORWARD), layout.boxes, params, layout.line_dir, layout.block_origin)
    x, y = np.asarray(pose.pos)
    assert x == pytest.approx(320 - params.radius, abs=9)  # pressed against the east wall
    assert x <= 320 - params.radius
    assert y > 30 + 60  # but kept moving north along it
    assert y <= 128 - params.radius


def test_walking_speed_is_doom_like():
    layout = tiny_layout()
    pose = motion.Pose.at(jnp.array([20.0, 64.0]), jnp.float32(0.0))
    p = motion.MotionParams()
    for _ in range(35):  # ~260 units: stays clear of the east wall
        before, pose = pose, motion.tic(pose, jnp.int32(motion.FORWARD), layout.boxes, p, layout.line_dir, layout.block_origin)
    speed = float(pose.pos[0] - before.pos[0])
    assert 7.8 < speed < 8.5  # "about 8 units per tic" (Doom: 0.78 thrust, 0.90625 friction)


def test_turning_is_dooms_integer_rule():
    # per tic: 320 angle units (1.758 deg) while fewer than 6 tics in a row had a turn button
    # down, then 640 (3.516 deg); either button counts, a tic without one restarts the count
    layout, p = tiny_layout(), motion.MotionParams()
    pose = motion.Pose.at(jnp.array([160.0, 64.0]), jnp.float32(0.0))
    L, R, N = motion.TURN_LEFT, motion.TURN_RIGHT, motion.NOOP
    turns = []
    for a in [L] * 8 + [R] * 2 + [N] + [R] * 2:
        new = motion.tic(pose, jnp.int32(a), layout.boxes, p, layout.line_dir, layout.block_origin)
        turns.append((int(new.angle) - int(pose.angle) + 32768) % 65536 - 32768)
        pose = new
    assert turns == [320] * 5 + [640] * 3 + [-640] * 2 + [0] + [-320] * 2
    assert pose.angle.dtype == jnp.int32 and 0 <= int(pose.angle) < motion.ANGLE_UNITS
    signed = (int(pose.angle) + 32768) % 65536 - 32768
    assert float(pose.heading) == pytest.approx(signed * 2 * math.pi / 65536, abs=1e-6)
    # whole 4-tic agent steps, as measured in ViZDoom: 7.031, 12.305, then 14.063 degrees
    env = MazeEnv(tiny_layout(), MazeTask("t", random_heading=False))
    states = jax.jit(walk, static_argnums=0)(env, jax.random.PRNGKey(0), jnp.full((4,), L))
    angles = np.concatenate([[0], np.asarray(states.pipeline_state.pose.angle)])
    np.testing.assert_allclose(np.diff(angles) * 360 / 65536, [7.03125, 12.3046875, 14.0625, 14.0625])


def test_reward_and_termination_at_goal():
    env = MazeEnv(tiny_layout(), MazeTask("t", random_heading=False, heading=0.0, max_steps=50))
    # spawn (40, 64) facing east, goal at (200, 64): walking forward reaches it
    states = jax.jit(walk, static_argnums=0)(env, jax.random.PRNGKey(0), jnp.full((20,), motion.FORWARD))
    reward, done = np.asarray(states.reward), np.asarray(states.done)
    t = int(np.argmax(done))
    assert done[t] == 1 and reward[t] == 1.0 and reward.sum() >= 1.0
    assert reward[:t].sum() == 0 and states.info["truncation"][t] == 0
    assert states.metrics["episode_success"][t] == 1 and states.metrics["episode_length"][t] == t + 1
    assert states.metrics["episode_return"][t] == 1.0
    # touch distance: the step that ended it has the box within reach of the goal item
    assert 5 <= t <= 12
    # auto-reset: the next state is a fresh episode at the spawn spot
    np.testing.assert_allclose(np.asarray(states.pipeline_state.pose.pos[t]), [40.0, 64.0])
    assert int(states.pipeline_state.steps[t]) == 0


def test_truncation_at_525_steps():
    env = make("maze-very-sparse")
    states = jax.jit(walk, static_argnums=0)(env, jax.random.PRNGKey(0), jnp.full((530,), motion.NOOP))
    done = np.asarray(states.done)
    assert np.flatnonzero(done).tolist() == [524]  # the 525th step
    assert states.info["truncation"][524] == 1 and states.reward.sum() == 0
    assert states.metrics["episode_length"][524] == 525 and states.metrics["episode_success"][524] == 0


def test_fixed_and_random_spawns():
    # the paper's fixed starts and their angle ranges: tests/test_icm_scenarios.py
    sparse = jax.jit(jax.vmap(make("maze-spot16-east").reset))(jax.random.split(jax.random.PRNGKey(0), 8))
    np.testing.assert_allclose(np.asarray(sparse.pipeline_state.pose.pos), [mywayhome_map.SPAWN_SPOTS[16]] * 8, rtol=1e-6)
    assert np.all(np.asarray(sparse.pipeline_state.pose.angle) == 0)
    very = jax.jit(make("maze-very-sparse").reset)(jax.random.PRNGKey(1))
    np.testing.assert_allclose(np.asarray(very.pipeline_state.pose.pos), mywayhome_map.SPAWN_SPOTS[15], rtol=1e-6)
    dense = jax.jit(jax.vmap(make("maze-dense").reset))(jax.random.split(jax.random.PRNGKey(0), 64))
    assert len({tuple(np.round(p, 2)) for p in np.asarray(dense.pipeline_state.pose.pos)}) > 8
    assert np.unique(np.round(np.asarray(dense.pipeline_state.pose.heading), 3)).size > 32


def test_fresh_spawn_after_auto_reset():
    # 3-step episodes: every 3rd state is a new episode's start, drawn anew each time
    env = MazeEnv(mywayhome_layout(), MazeTask("t", max_steps=3))
    states = jax.jit(walk, static_argnums=0)(env, jax.random.PRNGKey(7), jnp.full((60,), motion.NOOP))
    starts = np.asarray(states.pipeline_state.pose.heading)[np.asarray(states.done) > 0]
    assert starts.size == 20
    assert np.unique(np.round(starts, 4)).size == 20  # brax's AutoResetWrapper would give 1
    spots = np.asarray(states.pipeline_state.pose.pos)[np.asarray(states.done) > 0]
    known = np.asarray(list(mywayhome_map.SPAWN_SPOTS.values()))
    assert np.all(np.min(np.abs(spots[:, None] - known[None]).sum(-1), axis=1) < 1e-3)


def test_shapes_dtypes_and_determinism():
    env = make("maze-dense")
    keys = jax.random.split(jax.random.PRNGKey(0), 4)
    reset = jax.jit(jax.vmap(env.reset))
    step = jax.jit(jax.vmap(env.step))
    s = reset(keys)
    chex.assert_shape(s.obs, (4, 42, 42, 3))
    chex.assert_type(s.obs, jnp.uint8)
    chex.assert_shape([s.reward, s.done, s.info["truncation"]], (4,))
    chex.assert_shape(s.pipeline_state.pose.pos, (4, 2))
    s2 = step(s, jnp.array([0, 1, 2, 3]))
    chex.assert_type([s2.reward, s2.done], jnp.float32)
    chex.assert_tree_all_finite(s2.pipeline_state.pose)
    again = step(reset(keys), jnp.array([0, 1, 2, 3]))
    chex.assert_trees_all_equal(s2, again)
    other = reset(jax.random.split(jax.random.PRNGKey(1), 4))
    assert not np.array_equal(np.asarray(other.obs), np.asarray(s.obs))
    assert env.observation_size == (42, 42, 3) and env.action_size == 4


@pytest.mark.parametrize("name", ["maze-dense", "maze-very-sparse"])
def test_the_invented_looks_tasks_differ_from_their_twins_only_in_the_picture(name):
    # a diagnostic world: the same spots, motion, goal and rewards, drawn without the textures
    keys = jax.random.split(jax.random.PRNGKey(3), 4)
    actions = jax.random.randint(jax.random.PRNGKey(4), (40, 4), 0, 4)

    def play(env):
        def step(s, a):
            s = jax.vmap(env.step)(s, a)
            return s, (s.obs, s.pipeline_state.pose.pos, s.pipeline_state.pose.angle, s.reward, s.done)
        first = jax.vmap(env.reset)(keys)
        frames, *rest = jax.lax.scan(step, first, actions)[1]
        return jnp.concatenate([first.obs[None], frames]), rest

    textured, plain = make(name), make(f"{name}-invented-looks")
    assert textured.look is not None and plain.look is None
    (frames_t, rest_t), (frames_p, rest_p) = (jax.jit(play, static_argnums=0)(e) for e in (textured, plain))
    chex.assert_trees_all_equal(rest_t, rest_p)
    chex.assert_equal_shape([frames_t, frames_p])
    # every frame differs: the walls and the light are another world's
    assert np.all(np.abs(np.asarray(frames_t, int) - np.asarray(frames_p, int)).mean(axis=(2, 3, 4)) > 5)


def test_a_flat_textures_task_paints_the_named_textures_their_mean_colour_and_nothing_else():
    # a diagnostic world: which paint a bonus follows, with the map, light and rules unchanged
    from simjax.envs.doom import doom_assets, doom_render

    base, flat = make("maze-very-sparse"), make("maze-very-sparse-flat-SILVER2-TLITE6_1")
    assert flat.task == dataclasses.replace(base.task, name="maze-very-sparse-flat-SILVER2-TLITE6_1")
    chex.assert_trees_all_equal(flat.layout, base.layout)
    for field in ("tex_start", "tex_width", "wall_offset", "wall_sign", "light_rgb", "plane_rgb", "sprite_prefix"):
        chex.assert_trees_all_equal(getattr(flat.look, field), getattr(base.look, field))

    def columns(look):  # (levels, columns, rows, 3): each filter level's texels, from the prefix sums
        prefix = np.asarray(look.wall_prefix, np.float64).reshape(doom_render.LEVELS, look.tex_columns, -1, 3)
        return np.diff(prefix[:, :, :-1], axis=2)

    before, after = columns(base.look), columns(flat.look)
    starts, widths = np.asarray(base.look.tex_start), np.asarray(base.look.tex_width)
    for i, name in enumerate(mywayhome_map.TEXTURE_NAMES):
        own = slice(starts[i], starts[i] + widths[i])
        if name in ("SILVER2", "TLITE6_1"):
            mean = np.asarray(doom_assets.load()[f"wall_{name}"], np.float64).mean((0, 1)) / 255.0
            np.testing.assert_allclose(after[:, own], np.broadcast_to(mean, after[:, own].shape), atol=1e-4)
            assert np.abs(before[:, own] - mean).max() > 0.2, name  # it had a pattern to lose
        else:
            np.testing.assert_array_equal(after[:, own], before[:, own], err_msg=name)


@pytest.mark.parametrize("name,match", [
    ("maze-very-sparse-flat-SILVER", "texture names"),
    ("maze-very-sparse-flat-SILVER2-SILVER2", "distinct"),
    ("maze-very-sparse-flat-", "texture names"),
    ("maze-tiny-flat-SILVER2", "only maze-dense"),
    ("maze-dense-invented-looks-flat-SILVER2", "only maze-dense"),
])
def test_a_bad_flat_textures_name_is_refused_before_anything_is_built(name, match):
    with pytest.raises(ValueError, match=match):
        make(name)


def test_a_spot_walk_starts_at_the_spot_in_the_runs_own_world():
    from simjax.envs import mywayhome_spot

    env = make("maze-very-sparse")
    walk = mywayhome_spot(env, 26)
    assert walk.look is env.look and walk.camera == env.camera and walk.motion_params == env.motion_params
    starts = jax.jit(jax.vmap(walk.reset))(jax.random.split(jax.random.PRNGKey(0), 8)).pipeline_state.pose
    np.testing.assert_allclose(np.asarray(starts.pos), [mywayhome_map.SPAWN_SPOTS[26]] * 8, rtol=1e-6)
    assert np.unique(np.round(np.asarray(starts.angle), 3)).size == 8


def test_unknown_task_lists_known_ones():
    with pytest.raises(ValueError, match="known tasks: maze-dense"):
        make("maze-nope")
    assert {"maze-dense", "maze-sparse", "maze-very-sparse", "maze-spot10-east", "maze-spot16-east"} <= set(TASK_NAMES)


def test_topdown_drawing_shows_walls_goal_and_agent(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    from simjax.envs.topdown import draw_topdown

    layout = mywayhome_layout()
    ax = draw_topdown(layout, pose=(240.0, -176.0, 0.0), trajectory=np.array([[240, -176], [300, -176]]))
    assert len(ax.lines) == len(mywayhome_map.WALLS) + 1  # one line per wall, plus the trajectory
    assert len(ax.patches) == 1  # the agent's arrow
    offsets = np.concatenate([c.get_offsets() for c in ax.collections]).tolist()
    assert [1040.0, -352.0] in offsets and len(offsets) == 17 + 1  # spawns + goal
    ax.figure.savefig(tmp_path / "map.png")
    assert (tmp_path / "map.png").stat().st_size > 5_000


def test_fine_patterns_are_box_filtered_not_aliased():
    from simjax.envs.raycaster import _filtered_square

    x = jnp.linspace(-3.0, 3.0, 601)
    point = 1.0 - 2.0 * jnp.mod(jnp.floor(x), 2.0)
    np.testing.assert_array_equal(np.asarray(_filtered_square(x, jnp.zeros_like(x))), np.asarray(point))
    np.testing.assert_allclose(np.asarray(_filtered_square(x, jnp.full_like(x, 2.0))), 0.0, atol=1e-5)  # a whole period
    # numeric mean over the footprint agrees
    fine = jnp.linspace(0.3 - 0.35, 0.3 + 0.35, 70001)
    assert float(_filtered_square(jnp.float32(0.3), jnp.float32(0.7))) == pytest.approx(
        float(jnp.mean(1.0 - 2.0 * jnp.mod(jnp.floor(fine), 2.0))), abs=1e-3)
    # a far wall of 12-unit stripes (spare look 11): a 2-unit sideways step barely changes the
    # frame (point sampling made it flicker: every stripe is finer than a pixel out there)
    rows = [(0, -400, 900, -400, 8), (900, -400, 900, 400, 11), (900, 400, 0, 400, 8), (0, 400, 0, -400, 8)]
    walls = raycaster.Walls.from_rows(rows)
    nothing = raycaster.Sprites(jnp.zeros((1, 2)), jnp.zeros((1,), jnp.int32), jnp.zeros((1,), bool))
    frame = lambda y: np.asarray(raycaster.render(walls, jnp.array([100.0, y]), jnp.float32(0.0), nothing)).astype(int)
    a, b = frame(0.0), frame(2.0)
    far_wall = slice(19, 22), slice(14, 28)  # rows and columns showing only the far wall
    assert np.abs(a[far_wall] - b[far_wall]).max() <= 6  # box filter: 1; point sampling: 18
    # and the wall shows the blend of its two colours, not one of them
    base, alt = (np.asarray(c) for c in raycaster.TEXTURE_LOOKS[11][:2])
    # (at 800 units: fog 1 - 800/1100, side shade 1), within a quarter of their gap of the middle
    fog = 1.0 - 800.0 / 1100.0
    mean = a[far_wall].reshape(-1, 3).mean(0)
    np.testing.assert_allclose(mean, fog * 255 * (base + alt) / 2, atol=fog * 255 * (base - alt).min() / 4)


def test_the_tasks_said_to_end_early_are_those_with_an_item_that_ends_an_episode():
    # EC's default offset follows envs.episodes_end_early, a list kept beside the registry
    from simjax.envs import episodes_end_early

    for name in TASK_NAMES:
        env = make(name)
        assert episodes_end_early(name) == bool(np.any(np.asarray(env.layout.items.ends))), name
    assert episodes_end_early("gymnax:CartPole-v1")
