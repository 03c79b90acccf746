"""DeepMind Lab's player motion (``simjax.envs.dmlab.pmove``): its constants against their
sources, a walk, a stop and a turn against the formulas worked by hand in float64, collision
with walls, the melon world stepping with it, and the Doom worlds left as they were."""

import functools
import math
import re
import subprocess
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from simjax.envs import make
from simjax.envs.dmlab import melon, pmove
from simjax.envs.dmlab.explore_goals import ExploreGoalsEnv, ExploreGoalsPaperEnv
from simjax.envs.doom import motion

P = pmove.DmlabMotionParams()
L, R, F, NOOP = pmove.TURN_LEFT, pmove.TURN_RIGHT, pmove.FORWARD, pmove.NOOP
DT = 0.016  # a 16 ms frame
# a 1000 x 1000 room: south, east, north, west walls as segments [xmin, ymin, xmax, ymax]
ROOM = jnp.asarray([[0, 0, 1000, 0], [1000, 0, 1000, 1000], [0, 1000, 1000, 1000], [0, 0, 0, 1000]], jnp.float32)
STOP = 1000 - 15 - 0.125  # where a box of half-size 15 stops before the east (north) wall
# float32 positions below 1024 are exact to 2^-14; a frame rounds a few times per coordinate
TOL = 16 * 2.0**-14
PUSHBACK = 320 * 0.001 * DT  # OVERCLIP leaves at most 0.1% of 320 units/s going back, for a frame

MIRROR = Path("/work/.mirror/google-deepmind+lab/repo")
COMMIT = "b1db91af5b4d2f3a24466f4632a3e5e1b0829cca"


@pytest.fixture(scope="module")
def tic():
    """One frame, compiled once per params."""
    return jax.jit(pmove.tic, static_argnums=3)


def frames(tic, pose, action, n, boxes=ROOM, params=P):
    """The poses after each of ``n`` frames of ``action``."""
    out = []
    for _ in range(n):
        pose = tic(pose, jnp.int32(action), boxes, params)
        out.append(pose)
    return out


def walk_model(vel, wishdir, n):
    """PM_Friction, PM_Accelerate and SnapVector on open ground, in float64 (``wishdir`` None:
    no forward key): (velocity after each frame, units moved in each frame), as (n, 2) arrays."""
    vel = np.asarray(vel, np.float64)
    vels, moved = [], []
    for _ in range(n):
        speed = math.hypot(*vel)
        if speed < 1:
            vel = np.zeros(2)
        else:
            vel = vel * max(speed - max(speed, 100.0) * 6.0 * DT, 0.0) / speed
        if wishdir is not None and 320.0 - vel @ wishdir > 0:
            vel = vel + min(10.0 * DT * 320.0, 320.0 - vel @ wishdir) * np.asarray(wishdir)
        moved.append(vel * DT)
        assert np.all(np.abs(vel - np.floor(vel) - 0.5) > 1e-3)  # no tie float32 could round the other way
        vel = np.rint(vel)
        vels.append(vel)
    return np.array(vels), np.array(moved)


def facing(units):
    """The unit vector of a yaw in 1/65536 of a turn."""
    return np.array([math.cos(units * 2 * math.pi / 65536), math.sin(units * 2 * math.pi / 65536)])


# ---- the constants, against DMLab's sources -----------------------------------------------------
# (params field or None, value, file, line, the line's text with whitespace collapsed)
CITED = [
    ("pixels_to_degrees_per_msec", 0.11 * 60 / 1000, "engine/code/deepmind/dmlab_connect.c", 52,
     "static const double kPixelsPerFrameToDegreesPerMilliseconds = 0.11 * 60 / 1000;"),
    ("frame_msec", int(0.96 * 1000.0 / 60 + 0.5), "engine/code/deepmind/dmlab_connect.c", 617,
     "(int)((kEngineTimePerExternalTime * 1000.0 / v_double) + 0.5);"),
    (None, 0.96, "engine/code/deepmind/dmlab_connect.c", 68, "static const double kEngineTimePerExternalTime = 0.96;"),
    (None, 60, "python/dmlab_module.c", 245, 'if (self->env_c_api->setting(self->context, "fps", "60") != 0) {'),
    ("forwardmove", 127, "engine/code/deepmind/dmlab_connect.c", 1139,
     "int forwardmove = act_d[kActions_MoveBackForward] * 127;"),
    (None, None, "engine/code/deepmind/dmlab_connect.c", 1141,
     "-act_d[kActions_LookLeftRight] * kPixelsPerFrameToDegreesPerMilliseconds;"),
    ("speed", 320, "engine/code/game/g_main.c", 143, '{ &g_speed, "g_speed", "320", 0, 0, qtrue },'),
    ("accelerate", 10.0, "engine/code/game/bg_pmove.c", 38, "float pm_accelerate = 10.0f;"),
    ("friction", 6.0, "engine/code/game/bg_pmove.c", 43, "float pm_friction = 6.0f;"),
    ("stop_speed", 100.0, "engine/code/game/bg_pmove.c", 34, "float pm_stopspeed = 100.0f;"),
    ("overclip", 1.001, "engine/code/game/bg_local.h", 34, "#define OVERCLIP 1.001f"),
    ("clip_epsilon", 0.125, "engine/code/qcommon/cm_local.h", 134, "#define SURFACE_CLIP_EPSILON (0.125)"),
    ("radius", 15.0, "engine/code/game/g_client.c", 27, "static vec3_t playerMins = {-15, -15, -24};"),
    (None, 15.0, "engine/code/game/g_client.c", 28, "static vec3_t playerMaxs = {15, 15, 32};"),
    ("max_clip_planes", 5, "engine/code/game/bg_slidemove.c", 44, "#define MAX_CLIP_PLANES 5"),
    ("bumps", 4, "engine/code/game/bg_slidemove.c", 61, "numbumps = 4;"),
    ("step_size", 18.0, "engine/code/game/bg_local.h", 27, "#define STEPSIZE 18"),
    (None, None, "engine/code/game/bg_misc.c", 1155, "if ( ps->origin[0] - origin[0] > 44"),
    (None, None, "engine/code/game/bg_misc.c", 1156, "|| ps->origin[0] - origin[0] < -50"),
    (None, None, "engine/code/game/bg_misc.c", 1157, "|| ps->origin[1] - origin[1] > 36"),
    (None, None, "engine/code/game/bg_misc.c", 1158, "|| ps->origin[1] - origin[1] < -36"),
    (None, 15, "engine/code/game/bg_public.h", 41, "#define ITEM_RADIUS 15 // item sizes are needed for client side pickup detection"),
    (None, None, "engine/code/game/bg_pmove.c", 1908, "pml.frametime = pml.msec * 0.001;"),
    (None, None, "engine/code/game/bg_pmove.c", 2014, "trap_SnapVector( pm->ps->velocity );"),
    (None, None, "engine/code/qcommon/q_shared.h", 461, "#define Q_SnapVector qsnapvectorsse"),
    (None, None, "engine/code/asm/snapvector.c", 45, '"cvtps2dq %%xmm0, %%xmm0\\n"'),
    (None, None, "engine/code/qcommon/q_shared.h", 1088, "#define ANGLE2SHORT(x) ((int)((x)*(65536.0f/360.0f)+0.5f) & 65535)"),
    (None, None, "engine/code/client/cl_input.c", 597,
     "cl.viewangles[YAW] = AngleNormalize360( old_angles[YAW] + yaw * eng_frame_msec );"),
    (None, None, "engine/code/client/cl_input.c", 600, "cmd->angles[i] = ANGLE2SHORT(cl.viewangles[i]);"),
    (None, None, "engine/code/game/bg_pmove.c", 1810, "temp = cmd->angles[i] + ps->delta_angles[i];"),
]


def test_params_hold_the_cited_values():
    for field, value, *_ in CITED:
        if field is not None:
            assert getattr(P, field) == pytest.approx(value, rel=0, abs=0), field
    assert P.frame_msec == 16 and P.look_pixels == 20 and P.tics_per_step == 4
    assert P.touch_box == (-50.0, 44.0, -36.0, 36.0)  # bg_misc.c:1155-1158, below


@functools.cache
def _source(path: str) -> list[str]:
    text = subprocess.run(["git", "-C", str(MIRROR), "show", f"{COMMIT}:{path}"], capture_output=True, text=True,
                          check=True).stdout
    return text.splitlines()


@pytest.mark.skipif(not MIRROR.exists(), reason="needs the google-deepmind/lab mirror")
@pytest.mark.parametrize("field,value,path,line,text", CITED, ids=[f"{c[2].rsplit('/', 1)[1]}:{c[3]}" for c in CITED])
def test_cited_lines_say_so(field, value, path, line, text):
    collapse = lambda s: re.sub(r"\s+", " ", s).strip()
    assert collapse(_source(path)[line - 1]) == collapse(text)


# ---- walking, stopping, turning, by hand --------------------------------------------------------
def test_forward_from_rest_moves_as_worked_by_hand_then_tops_out_at_320(tic):
    start = pmove.Pose.at(jnp.array([100.0, 500.0]), 0.0)
    poses = frames(tic, start, F, 16)
    vels, moved = walk_model([0.0, 0.0], facing(0), 16)
    speeds, moved = vels[:, 0].tolist(), moved[:, 0].tolist()
    # the first agent step: 51.2 (snapped 51), 41.4 + 51.2 = 92.6 (93), 83.4 + 51.2 = 134.6 (135),
    # 135 * 0.904 + 51.2 = 173.24 (173); moving 0.8192 + 1.4816 + 2.1536 + 2.77184 units
    assert speeds[:4] == [51, 93, 135, 173]
    np.testing.assert_allclose(moved[:4], [0.8192, 1.4816, 2.1536, 2.77184], rtol=1e-12)
    assert [round(m, 3) for m in moved[:4]] == [0.819, 1.482, 2.154, 2.772]
    # then 208, 239, 267, 293, 316 and 320 from the tenth frame on: 5.12 units a frame
    assert speeds[4:10] == [208, 239, 267, 293, 316, 320] and set(speeds[10:]) == {320}
    x = np.array([100.0] + [float(p.pos[0]) for p in poses])
    np.testing.assert_array_equal([np.asarray(p.vel) for p in poses], [[s, 0.0] for s in speeds])
    np.testing.assert_allclose(np.diff(x), moved, atol=TOL)
    assert x[4] - x[0] == pytest.approx(7.22624, abs=TOL)
    assert x[16] - x[12] == pytest.approx(4 * 320 * DT, abs=TOL) == pytest.approx(20.48, abs=TOL)
    assert all(float(p.pos[1]) == 500.0 for p in poses)  # due east: the facing's y is exactly 0


@pytest.mark.parametrize("action", [NOOP, L])
def test_stopping_from_top_speed(tic, action):
    # no forward key (a turn step has none either): x 0.904 a frame, then -9.6 below 100 units/s
    start = pmove.Pose.at(jnp.array([100.0, 500.0]), 0.0)._replace(vel=jnp.array([320.0, 0.0]))
    poses = frames(tic, start, action, 24)
    vels, moved = walk_model([320.0, 0.0], None, 24)
    speeds, moved = vels[:, 0].tolist(), moved[:, 0].tolist()
    assert speeds[:4] == [289, 261, 236, 213]
    slow = [s for s in speeds if 0 < s < 100]
    assert slow == [95, 85, 75, 65, 55, 45, 35, 25, 15, 5] and speeds[-1] == 0  # 95 - 9.6 = 85.4, ...
    np.testing.assert_array_equal([float(np.linalg.norm(np.asarray(p.vel))) for p in poses], speeds)
    travelled = np.linalg.norm(np.asarray(poses[-1].pos) - np.asarray(start.pos))
    assert travelled == pytest.approx(sum(moved), abs=4 * TOL)


def test_a_turn_step_turns_8448_millidegrees_left_or_right(tic):
    start = pmove.Pose.at(jnp.array([500.0, 500.0]), 0.0)
    # 20 px x 0.11 * 60 / 1000 deg/ms x 16 ms x 4 frames = 8.448 deg, as ANGLE2SHORT sees it
    units = int(20 * 0.0066 * 16 * 4 * 65536 / 360 + 0.5)
    assert units == 1538
    left, right = frames(tic, start, L, 4)[-1], frames(tic, start, R, 4)[-1]
    assert int(left.yaw) == units and int(right.yaw) == -units
    assert float(left.view_yaw) == pytest.approx(8.448, abs=1e-4)
    assert float(right.view_yaw) == pytest.approx(360 - 8.448, abs=1e-4)
    assert float(left.heading) == pytest.approx(units * 2 * math.pi / 65536, rel=1e-6)  # left: counter-clockwise
    assert float(right.heading) == -float(left.heading)
    # walking after a left turn from east heads north of east: 51.2 units/s along 8.4485 degrees
    # is (50.65, 7.52), snapped to (51, 8), and so on
    walked = frames(tic, left, F, 4)
    vels, moved = walk_model([0.0, 0.0], facing(units), 4)
    assert vels[0].tolist() == [51.0, 8.0]
    np.testing.assert_array_equal([np.asarray(p.vel) for p in walked], vels)
    np.testing.assert_allclose(np.asarray(walked[-1].pos - left.pos), moved.sum(0), atol=4 * TOL)
    # two steps: the client adds 8.448 again, the game sees ANGLE2SHORT(16.896) = 3076
    assert int(frames(tic, left, L, 4)[-1].yaw) == int(16.896 * 65536 / 360 + 0.5) == 3076


def test_the_look_rate_is_a_parameter(tic):
    params = P._replace(look_pixels=25)  # 25 px: 10.56 degrees a step
    pose = pmove.Pose.at(jnp.array([500.0, 500.0]), 0.0)
    for _ in range(4):
        pose = tic(pose, jnp.int32(L), ROOM, params)
    assert int(pose.yaw) == int(25 * 0.0066 * 16 * 4 * 65536 / 360 + 0.5) == 1922


def test_spawning_and_respawning_keep_dmlabs_angle_arithmetic(tic):
    north = pmove.Pose.at(jnp.array([0.0, 0.0]), math.pi / 2)
    assert int(north.yaw) == 16384 and float(north.view_yaw) == 0.0  # ANGLE2SHORT(90) = 16384
    turned = frames(tic, north, L, 12)[-1]  # 3 steps: the client holds 25.344 degrees
    again = pmove.continue_view(pmove.Pose.at(jnp.array([5.0, 5.0]), math.pi / 2), turned)
    assert int(again.yaw) == 16384 and float(again.view_yaw) == float(turned.view_yaw)
    assert float(turned.view_yaw) == pytest.approx(25.344, abs=1e-4)
    after = frames(tic, again, L, 4)[-1]
    # the game sees the step as the client's angle moves: ANGLE2SHORT(33.792) - ANGLE2SHORT(25.344)
    seen = lambda deg: int(deg * 65536 / 360 + 0.5)
    assert int(after.yaw) - 16384 == seen(33.792) - seen(25.344) == 6152 - 4614
    assert int(pmove.Pose.facing(jnp.zeros(2), -1).yaw) == -1


# ---- walls -----------------------------------------------------------------------------------
def test_a_run_into_a_wall_stops_15_and_an_eighth_short_of_it(tic):
    fraction, endpos, normal, allsolid = pmove.trace(jnp.array([900.0, 500.0]), jnp.array([1000.0, 500.0]), ROOM, P)
    # the box side enters x = 1000 - 15 at 85 of the 100 units; the trace stops 0.125 before
    assert float(fraction) == pytest.approx((85 - 0.125) / 100, rel=1e-6) and not bool(allsolid)
    assert float(endpos[0]) == pytest.approx(STOP, abs=TOL) and normal.tolist() == [-1.0, 0.0]
    poses = frames(tic, pmove.Pose.at(jnp.array([900.0, 500.0]), 0.0), F, 32)
    for pose in poses[-12:]:
        x, y = (float(v) for v in pose.pos)
        assert STOP - PUSHBACK - TOL <= x <= STOP + TOL and y == 500.0
        assert np.asarray(pose.vel).tolist() == [0.0, 0.0]


def test_a_slanted_run_slides_along_the_wall_keeping_its_tangential_speed(tic):
    pose = pmove.Pose.at(jnp.array([950.0, 300.0]), math.radians(30))
    assert int(pose.yaw) == 5461  # ANGLE2SHORT(30)
    s = math.sin(5461 * 2 * math.pi / 65536)  # the facing's y; its x goes into the wall
    poses = frames(tic, pose, F, 40)
    sliding = [i for i, p in enumerate(poses) if float(p.pos[0]) >= STOP - PUSHBACK - TOL]
    assert sliding and sliding[0] < 12 and sliding == list(range(sliding[0], 40))
    for before, after in zip(poses[sliding[0]:-1], poses[sliding[0] + 1:]):
        vy = float(before.vel[1])
        assert float(before.vel[0]) == 0.0
        # the frame in open ground, then the wall takes the x part and leaves the y part
        vy *= max(vy - max(vy, 100.0) * 6 * DT, 0.0) / vy
        accel = min(10 * DT * 320, 320 - vy * s)
        vy += accel * s
        if abs(vy - math.floor(vy) - 0.5) > 1e-3:  # (float32 may round a near-tie the other way)
            assert float(after.vel[1]) == np.rint(vy)
        assert float(after.vel[0]) == 0.0
        assert float(after.pos[1] - before.pos[1]) == pytest.approx(vy * DT, abs=TOL)
        assert STOP - PUSHBACK - TOL <= float(after.pos[0]) <= STOP + TOL
    assert float(poses[-1].vel[1]) > 200  # towards 0.5 * 51.2 / 0.096 = 267


def test_a_corner_stops_the_box(tic):
    poses = frames(tic, pmove.Pose.at(jnp.array([900.0, 900.0]), math.radians(45)), F, 40)
    for pose in poses[-8:]:
        assert np.all(np.asarray(pose.pos) >= STOP - PUSHBACK - TOL) and np.all(np.asarray(pose.pos) <= STOP + TOL)
        assert np.asarray(pose.vel).tolist() == [0.0, 0.0]


def test_pickups_use_quakes_asymmetric_box():
    item = jnp.array([[0.0, 0.0]])
    at = lambda x, y: bool(pmove.touches(item, jnp.array([x, y]), P)[0])
    assert at(44.0, 0.0) and not at(44.01, 0.0) and at(-50.0, 0.0) and not at(-50.01, 0.0)
    assert at(0.0, 36.0) and at(0.0, -36.0) and not at(0.0, 36.01) and not at(0.0, -36.01)


# ---- the worlds ------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def melon_env():
    env = make("melon")
    return env, jax.jit(env.reset), jax.jit(env.step)


def test_melon_steps_as_pmove_says(melon_env, tic):
    env, reset, step = melon_env
    assert env.motion_name == "dmlab"
    state = reset(jax.random.PRNGKey(0))
    pose = state.pipeline_state.pose
    assert np.asarray(pose.pos).tolist() == list(melon.START_XY) and int(pose.yaw) == 16384  # angle 90
    ys = [float(pose.pos[1])]
    for _ in range(3):
        direct = pose
        for _ in range(P.tics_per_step):
            direct = tic(direct, jnp.int32(F), env.layout.boxes, P)
        state = step(state, jnp.int32(F))
        pose = state.pipeline_state.pose
        np.testing.assert_allclose(np.asarray(pose.pos), np.asarray(direct.pos), atol=TOL)
        np.testing.assert_array_equal(np.asarray(pose.vel), np.asarray(direct.vel))
        assert float(state.reward) == 0.0
        ys.append(float(pose.pos[1]))
    assert ys[1] - ys[0] == pytest.approx(7.22624, abs=TOL)  # the hand-worked first step, due north
    assert abs(float(pose.pos[0])) < 1e-4
    # the block's south face is at y = -448: the box stops 15.125 short of it in the second step
    assert -448 - 15.125 - PUSHBACK - TOL <= ys[3] <= -448 - 15.125 + TOL
    # pickups: Quake's box around the lemon (-128, -480)
    lemon = env.layout.items.pos[14:15]
    assert bool(env.touches(lemon, jnp.array([-128.0 + 44.0, -480.0]))[0])
    assert not bool(env.touches(lemon, jnp.array([-128.0 + 45.0, -480.0]))[0])


def test_melon_lemon_route_reaches_the_melon_with_a_30_unit_box(melon_env):
    env, reset, step = melon_env
    # every item and the start leave room for the box (15 + 0.125) from every wall
    boxes = np.asarray(env.layout.boxes)
    for x, y in [melon.START_XY, *np.asarray(env.layout.items.pos).tolist()]:
        gap = np.maximum(np.maximum(boxes[:, 0] - x, x - boxes[:, 2]), np.maximum(boxes[:, 1] - y, y - boxes[:, 3]))
        assert gap.min() >= 15.125
    # west through the lemon, north up the stair corridor, east along the platform to the melon
    route = [L] * 11 + [F] * 26 + [R] * 11 + [F] * 48 + [R] * 11 + [F] * 24
    state = reset(jax.random.PRNGKey(0))
    rewards = []
    for a in route:
        state = step(state, jnp.int32(a))
        rewards.append(float(state.reward))
        if float(state.done):
            break
    assert sorted(r for r in rewards if r) == [-1.0, 20.0] and rewards[-1] == 20.0
    assert float(state.metrics["episode_success"]) == 1.0 and float(state.metrics["episode_return"]) == 19.0


def test_dmlab_worlds_move_as_dmlab_by_default_and_as_doom_on_request():
    key = jax.random.PRNGKey(0)
    builders = [melon.melon_env, melon.MelonLevelEnv, ExploreGoalsEnv, ExploreGoalsPaperEnv]
    for build in builders:
        env = build()
        assert isinstance(env.motion_params, pmove.DmlabMotionParams) and env.motion_model is pmove
        # the whole step traces with DMLab's pose (auto-reset, level restarts, respawns)
        state = jax.eval_shape(env.reset, key)
        after = jax.eval_shape(env.step, state, jnp.int32(0))
        assert isinstance(after.pipeline_state.pose, pmove.Pose)
        old = build(motion="doom")
        assert old.motion_params == motion.MotionParams() and old.motion_model is motion and old.motion_name == "doom"
        assert isinstance(jax.eval_shape(old.reset, key).pipeline_state.pose, motion.Pose)
    for name in ("melon", "melon-dmlab", "explore-goals", "explore-goals-paper"):
        assert make(name).motion_name == "dmlab"
    with pytest.raises(ValueError, match="motion"):
        melon.melon_env(motion="quake")


def test_mywayhome_still_steps_with_dooms_motion():
    env = make("maze-dense-invented-looks")
    assert env.motion_model is motion and env.motion_name == "doom"
    state = jax.jit(env.reset)(jax.random.PRNGKey(3))
    step = jax.jit(env.step)
    direct_tic = jax.jit(lambda p, a: motion.tic(p, a, env.layout.boxes, env.motion_params, env.layout.line_dir,
                                                 env.layout.block_origin))
    for action in (motion.FORWARD, motion.TURN_LEFT, motion.FORWARD):
        pose = state.pipeline_state.pose
        for _ in range(env.motion_params.tics_per_step):
            pose = direct_tic(pose, jnp.int32(action))
        state = step(state, jnp.int32(action))
        got = state.pipeline_state.pose
        assert int(got.angle) == int(pose.angle) and int(got.turn_tics) == int(pose.turn_tics)
        np.testing.assert_array_equal(np.asarray(got.pos), np.asarray(pose.pos))
        np.testing.assert_array_equal(np.asarray(got.vel), np.asarray(pose.vel))
