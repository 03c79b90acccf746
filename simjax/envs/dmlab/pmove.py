"""DeepMind Lab's player motion, as ioquake3's ``bg_pmove.c`` moves its player: the motion of
``melon`` and ``explore-goals``.

Every fact below was read from google-deepmind/lab at commit b1db91a (read, not copied; file:line
are of that commit). DMLab ships ioquake3's player physics unchanged, and no level script of
these two levels changes a movement setting.

One agent step holds its action for 4 engine frames (the paper's "4-repeated steps"; the
episodic-curiosity code, whose EC baseline the paper runs, steps DMLab with
``num_steps=action_repeat=4``). DMLab's Python module runs at 60 frames a second
(``python/dmlab_module.c:245``), which is 16 engine milliseconds a frame
(``engine/code/deepmind/dmlab_connect.c:616-617``: ``(int)(0.96 * 1000 / fps + 0.5)``, 0.96
being ``kEngineTimePerExternalTime``, l.68). Each frame the client makes one usercmd and the
game runs one ``PmoveSingle`` with msec 16 (``bg_pmove.c:1835-2015``). Per frame (``tic``):

1. Turning, in the client (``engine/code/client/cl_input.c:558-602``, ``CL_FinishMove``): the
   action's LOOK_LEFT_RIGHT_PIXELS_PER_FRAME ``p`` becomes ``float yaw = -p * 0.0066``
   degrees per engine millisecond (``dmlab_connect.c:1140-1141``; 0.0066 =
   ``kPixelsPerFrameToDegreesPerMilliseconds`` = 0.11 * 60 / 1000, l.52), and the client's
   float view angle ``cl.viewangles[YAW]`` becomes ``AngleNormalize360(old + yaw * 16)``
   (cl_input.c:597; ``AngleMod``, ``q_math.c:581-583``, 593-595). The usercmd carries it as
   ``ANGLE2SHORT`` (cl_input.c:599-600; ``(int)(x * 65536.0f / 360.0f + 0.5f) & 65535``,
   ``q_shared.h:1088``), and the game's yaw is that short plus ``ps->delta_angles[YAW]``,
   wrapped to a 16-bit short (``PM_UpdateViewAngles``, bg_pmove.c:1796-1824). So a turn step of
   20 pixels turns 4 x 2.112 = 8.448 degrees, seen by the game to 1/65536 of a turn (1538 units
   from a client angle of 0). Positive pixels turn right (the yaw goes down; Quake's yaw runs
   counter-clockwise from +x, as ``heading`` does here). ``Pose.view_yaw`` is the client's
   angle and ``Pose.delta_yaw`` the game's delta; the yaw the game moves and draws with is
   ``Pose.yaw``.
2. ``PM_WalkMove`` (bg_pmove.c:691-808) on the ground: ``PM_Friction`` (l.171-229: below 1
   unit/s the velocity stops; else it loses max(speed, pm_stopspeed 100) * pm_friction 6 *
   0.016 of its length), the wish direction (the facing, ``AngleVectors``, ``q_math.c:925-``,
   normalised twice as PM_WalkMove does, l.731-748) and speed (``PM_CmdScale``, l.289-310:
   forwardmove 127 gives ``g_speed`` 320), ``PM_Accelerate`` (l.239-257, q2 style:
   ``add = wishspeed - v . wishdir``; if positive, ``v += min(10 * 0.016 * wishspeed, add) *
   wishdir``), the speed-keeping renormalisation (l.789-797), then, if the velocity is not
   zero, ``PM_StepSlideMove`` (``bg_slidemove.c:244-``).
3. ``trap_SnapVector(ps->velocity)`` (bg_pmove.c:2014): each component rounded to the nearest
   whole number. On x86-64 ``Q_SnapVector`` is ``qsnapvectorsse`` (``q_shared.h:455-461``),
   ``cvtps2dq`` under the default rounding mode (``engine/code/asm/snapvector.c:36-54``): ties
   go to even, as ``jnp.round`` does. (The ``round()`` of ``q_shared.h:479-488``, ties away
   from zero, is the path for other CPUs.)

The velocity is in units per engine second; the origin is not snapped. A walk from rest goes
51, 93, 135, 173 units/s over the first 4 frames (7.23 units in the first agent step) and tops
out at 320 units/s, 5.12 units a frame, 20.48 an agent step. With no forward key the speed
falls 289, 261, 236, 213, ... (x 0.904 a frame) and, below 100, by 9.6 a frame.

Collision (``PM_SlideMove``, bg_slidemove.c:45-236) for a flat floor and full-height walls: the
player is a box with x, y half-size 15 (``playerMins/playerMaxs``, ``g_client.c:27-28``),
swept against every wall box (``Layout.boxes``: a zero-thickness segment is a brush whose two
faces coincide) as ``CM_TraceThroughBrush`` does it (``cm_trace.c:583-661``: each of the
brush's axial sides, in the order -x, +x, -y, +y that ``CM_BoundBrush``, ``cm_load.c:215-224``,
relies on, moved out by the box's extent; the trace stops ``SURFACE_CLIP_EPSILON`` = 0.125
(``cm_local.h:134``) before the side it enters, in the fraction of the move); the endpoint is
``start + fraction * (end - start)`` (``cm_trace.c:1344-1349``). Then, with the time left, the
velocity is clipped (``PM_ClipVelocity``, bg_pmove.c:144-161: ``v -= n * (v . n) * OVERCLIP``
1.001, or ``/ 1.001`` when ``v . n >= 0``) and the move goes on, 4 bumps at most (l.61), 5
clip planes at most (``MAX_CLIP_PLANES``, l.44; the list starts with the ground's normal and
the velocity's own direction, l.79-89; a fifth plane clears the velocity, l.119-123). A plane
hit again nudges the velocity out along it (l.130-138). On the ground, the ground plane is
the first plane the velocity "enters" (its z is 0, below 0.1, l.147-150), and clipping against
it changes nothing, so the velocity is clipped against each later plane in turn that it
enters (dot below 0.1), and the crease and triple-plane cases (l.182-212) are never reached
(their condition ``dot(clip, ground) < 0`` is never met): into a corner of two walls the
velocity loses both components and the box stops there. A box trapped inside a wall
(``allsolid``) does not move. Ties between walls entered at the same fraction go to the
first in ``boxes`` (Quake takes the first brush its BSP walk meets).

``PM_StepSlideMove`` (bg_slidemove.c:244-330), when the slide hit something, repeats the slide
from ``STEPSIZE`` = 18 (``bg_local.h:27``) higher and pushes back down: with full-height walls
on a flat floor the raised slide meets the same walls at the same x, y and the push down ends
at the old height, so stepping changes nothing here and is left out. Gravity and jumping
(``PM_AirMove``, ``PM_CheckJump``) are left out too: the floor is flat and the agent never
jumps, so the player is always on the ground (``PM_GroundTrace`` finds the floor 0.125 below
the box, where the landing trace left it) and its vertical velocity is 0.

Pickups (``G_TouchTriggers``, ``g_active.c:236-310``, run after every Pmove, l.1040): an item
is touched when ``BG_PlayerTouchesItem`` (``bg_misc.c:1149-1165``) holds: player minus item
within [-50, 44] on x and [-36, 36] on y (and z). The item's own box (``ITEM_RADIUS`` 15, ``bg_public.h:41``,
``g_items.c:688-689``, so 16 with the link pad, ``sv_world.c:274-279``) only preselects
candidates within 40 + 16 of the player (g_active.c:242, 253-256), a wider box, so Quake's
asymmetric box is the rule; DMLab's Lua pickups and ``deepmind/`` code do not change it.

Arithmetic is float32 in the order the C code does it (the C promotes a few steps to double;
where that matters the value is computed in float64 on the host: the facing table, the turn
rate). XLA may fuse a multiply and an add into one rounding, so a result can differ from
DMLab's in its last bit, and then, rarely, a snapped velocity by 1. Ignored: the client's
``CL_AdjustTimeDelta`` nudging a frame's msec by +1 / -2 when a server snapshot arrives
(``cl_cgame.c:857-868``), and the 3 engine frames a level restart runs before the agent acts.
"""

from __future__ import annotations

import functools
import math
import sys
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from simjax.envs.doom import motion as doom_motion

TURN_LEFT, TURN_RIGHT, FORWARD, NOOP = doom_motion.TURN_LEFT, doom_motion.TURN_RIGHT, doom_motion.FORWARD, doom_motion.NOOP
ACTION_NAMES = doom_motion.ACTION_NAMES

NAME = "dmlab"  # MazeEnv.motion_name
ANGLE_UNITS = 65536  # a whole turn in ANGLE2SHORT's units (q_shared.h:1088)
_RAD_PER_UNIT = 2.0 * math.pi / ANGLE_UNITS
_SIDE_NORMALS = np.array([[-1.0, 0.0], [1.0, 0.0], [0.0, -1.0], [0.0, 1.0]], np.float32)  # brush sides -x, +x, -y, +y


class DmlabMotionParams(NamedTuple):
    """DeepMind Lab's movement constants (module docstring), each with its source in
    google-deepmind/lab b1db91a."""

    # LOOK_LEFT_RIGHT_PIXELS_PER_FRAME of a turn action: the episodic-curiosity code's
    # ACTION_SET_SMALL (Look Left -20, Look Right +20; episodic_curiosity/environments/dmlab_utils.py)
    look_pixels: int = 20
    pixels_to_degrees_per_msec: float = 0.11 * 60 / 1000  # kPixelsPerFrameToDegreesPerMilliseconds, dmlab_connect.c:52
    frame_msec: int = 16  # (int)(0.96 * 1000 / 60 + 0.5), dmlab_connect.c:616-617, 68; fps 60, python/dmlab_module.c:245
    forwardmove: int = 127  # MOVE_BACK_FORWARD * 127, dmlab_connect.c:1139
    speed: int = 320  # g_speed, g_main.c:143 (ps->speed, g_active.c:908)
    accelerate: float = 10.0  # pm_accelerate, bg_pmove.c:38
    friction: float = 6.0  # pm_friction, bg_pmove.c:43
    stop_speed: float = 100.0  # pm_stopspeed, bg_pmove.c:34
    overclip: float = 1.001  # OVERCLIP, bg_local.h:34
    clip_epsilon: float = 0.125  # SURFACE_CLIP_EPSILON, cm_local.h:134
    radius: float = 15.0  # the player box's x, y half-size: playerMins / playerMaxs, g_client.c:27-28
    max_clip_planes: int = 5  # MAX_CLIP_PLANES, bg_slidemove.c:44
    bumps: int = 4  # numbumps, bg_slidemove.c:61
    step_size: float = 18.0  # STEPSIZE, bg_local.h:27 (changes nothing here: module docstring)
    # BG_PlayerTouchesItem, bg_misc.c:1155-1158: player minus item, inclusive: (x lo, x hi, y lo, y hi)
    touch_box: tuple[float, float, float, float] = (-50.0, 44.0, -36.0, 36.0)
    tics_per_step: int = 4  # engine frames per agent step (the paper's 4-repeated steps; EC's action_repeat=4)

    @property
    def model(self):
        """This module: a MazeEnv with these params moves with its ``Pose`` and ``tic`` and
        touches items with its ``touches`` (``simjax.envs.maze`` does not import the DMLab layer)."""
        return sys.modules[__name__]


def _f32(x):
    return np.float32(x)


def angle2short(degrees) -> jnp.ndarray:
    """ANGLE2SHORT (q_shared.h:1088): ``(int)(x * (65536.0f / 360.0f) + 0.5f) & 65535``, in
    float32, the int cast truncating toward zero."""
    scaled = jnp.asarray(degrees, jnp.float32) * _f32(_f32(65536.0) / _f32(360.0)) + _f32(0.5)
    return scaled.astype(jnp.int32) & (ANGLE_UNITS - 1)


def angle_mod(degrees) -> jnp.ndarray:
    """AngleMod (q_math.c:581-583): ``angle - 360.0f * floorf(angle * (1.0f / 360.0f))``."""
    a = jnp.asarray(degrees, jnp.float32)
    return a - _f32(360.0) * jnp.floor(a * _f32(_f32(1.0) / _f32(360.0)))


def _short(units) -> jnp.ndarray:
    """An int as C stores it in a ``short``: wrapped into [-32768, 32768)."""
    return jnp.mod(units + ANGLE_UNITS // 2, ANGLE_UNITS) - ANGLE_UNITS // 2


class Pose(NamedTuple):
    pos: jnp.ndarray  # (2,) float32, ps->origin x, y
    vel: jnp.ndarray  # (2,) float32, ps->velocity x, y in units per engine second (whole after each frame)
    view_yaw: jnp.ndarray  # () float32, the client's cl.viewangles[YAW], degrees in [0, 360)
    delta_yaw: jnp.ndarray  # () int32, the game's ps->delta_angles[YAW], in [0, 65536)

    @property
    def yaw(self) -> jnp.ndarray:
        """() int32 in [-32768, 32768): the game's yaw in 1/65536 of a turn (PM_UpdateViewAngles,
        bg_pmove.c:1810: the usercmd's ANGLE2SHORT plus the delta, as a short)."""
        return _short(angle2short(self.view_yaw) + self.delta_yaw)

    @property
    def heading(self) -> jnp.ndarray:
        """() float32, radians in [-pi, pi), counter-clockwise from east: the yaw."""
        return self.yaw.astype(jnp.float32) * jnp.float32(_RAD_PER_UNIT)

    @staticmethod
    def at(xy, heading) -> Pose:
        """A player standing still at ``xy`` spawned facing ``heading`` (radians), as a level
        start leaves it: the client's view angle 0 (a new map clears the client,
        ``cl_parse.c:476``, ``cl_main.c:1329-1334``) and the spawn angle in the delta
        (``SetClientViewAngle``, ``g_client.c:548-560``: ANGLE2SHORT of the angle in degrees,
        a negative one truncated toward zero as C does). Works on traced values."""
        degrees = jnp.asarray(heading, jnp.float32) * jnp.float32(180.0 / math.pi)
        return Pose.facing(xy, angle2short(degrees))

    @staticmethod
    def facing(xy, angle) -> Pose:
        """A player standing still at ``xy`` facing ``angle`` (1/65536 of a turn, taken modulo a
        turn), the client's view angle 0. Works on traced values."""
        delta = jnp.mod(jnp.asarray(angle, jnp.int32), ANGLE_UNITS)
        return Pose(jnp.asarray(xy, jnp.float32).reshape(2), jnp.zeros(2, jnp.float32), jnp.float32(0.0), delta)


def continue_view(new: Pose, old: Pose) -> Pose:
    """``new`` (a spawn) as a level restart within an episode leaves it: DMLab restarts the
    level with ``map_restart`` (``dev_map``, dmlab_connect.c:384-387: both levels' ``nextMap``
    returns '' after the first map), which keeps the client and its view angle, and
    ``ClientSpawn`` sets the delta from the client's last usercmd (``g_client.c:1233-1234``,
    556), so the yaw is ``new``'s and the client's angle ``old``'s."""
    delta = new.delta_yaw + angle2short(new.view_yaw) - angle2short(old.view_yaw)
    return new._replace(view_yaw=old.view_yaw, delta_yaw=jnp.mod(delta, ANGLE_UNITS).astype(jnp.int32))


@functools.cache
def _wish_table(forwardmove: int, speed: int) -> tuple[np.ndarray, np.ndarray]:
    """(65536, 2) wish direction and (65536,) wish speed of a forward key, per yaw short (index
    yaw & 65535), float32 as the C code computes them."""
    f32 = np.float32
    short = np.arange(ANGLE_UNITS, dtype=np.int64)
    short = np.where(short >= ANGLE_UNITS // 2, short - ANGLE_UNITS, short)
    degrees = short.astype(f32) * f32(f32(360.0) / f32(65536.0))  # SHORT2ANGLE, q_shared.h:1089
    # AngleVectors (q_math.c:930-932): float angle = yaw * (M_PI*2 / 360) in double; sin, cos in double
    angle = (degrees.astype(np.float64) * (math.pi * 2 / 360)).astype(f32)
    cy, sy = np.cos(angle.astype(np.float64)).astype(f32), np.sin(angle.astype(np.float64)).astype(f32)

    def normalize(x, y):  # VectorNormalize, q_math.c:783-800: (v / |v|, |v|) as it computes them
        length2 = x * x + y * y + f32(0.0) * f32(0.0)
        ilength = f32(1.0) / np.sqrt(length2.astype(np.float64)).astype(f32)
        return x * ilength, y * ilength, length2 * ilength

    fx, fy, _ = normalize(cy, sy)  # PM_WalkMove, bg_pmove.c:731-739 (pitch 0: forward[2] is 0)
    fmove = f32(forwardmove)
    wx, wy, wishspeed = normalize(fx * fmove, fy * fmove)  # l.741-748
    total = f32(math.sqrt(forwardmove * forwardmove))  # PM_CmdScale, l.305-307
    scale = f32(float(f32(speed) * f32(abs(forwardmove))) / (127.0 * float(total))) if forwardmove else f32(0.0)
    return np.stack([wx, wy], 1).astype(f32), (wishspeed * scale).astype(f32)


def _turn_steps(params: DmlabMotionParams) -> tuple[np.float32, np.float32]:
    """Degrees the client's view angle moves in a frame for turn left / right: ``float yaw =
    -pixels * k`` (dmlab_connect.c:1140-1141), times the frame's msec in double (cl_input.c:597;
    exact in float32 for 16 msec)."""
    rate = lambda pixels: np.float32(-pixels * params.pixels_to_degrees_per_msec)
    step = lambda pixels: np.float32(float(rate(pixels)) * params.frame_msec)
    return step(-params.look_pixels), step(params.look_pixels)


def _dot(a, b):
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]


def _normalize2(v):
    """VectorNormalize2 (q_math.c:802-822): v / |v| as it computes it, 0 for a zero vector."""
    length2 = _dot(v, v)
    ilength = jnp.float32(1.0) / jnp.sqrt(jnp.where(length2 > 0, length2, 1.0))
    return jnp.where(length2 > 0, v * ilength, 0.0)


def clip_velocity(v, normal, overbounce):
    """PM_ClipVelocity (bg_pmove.c:144-161)."""
    backoff = _dot(v, normal)
    backoff = jnp.where(backoff < 0, backoff * jnp.float32(overbounce), backoff / jnp.float32(overbounce))
    return v - normal * backoff[..., None]


def trace(start, end, boxes, params: DmlabMotionParams):
    """The player box swept from ``start`` to ``end`` (2,) through the walls ``boxes`` (S, 4)
    (CM_Trace / CM_TraceThroughBrush, module docstring): (fraction, endpos (2,), plane normal
    (2,), allsolid)."""
    r, eps = jnp.float32(params.radius), jnp.float32(params.clip_epsilon)
    xmin, ymin, xmax, ymax = boxes[:, 0], boxes[:, 1], boxes[:, 2], boxes[:, 3]
    # each side's plane->dist - offsets[signbits] . normal (cm_trace.c:588)
    dist = jnp.stack([-xmin + r, xmax + r, -ymin + r, ymax + r], 1)  # (S, 4)
    along = lambda p: jnp.stack([-p[0], p[0], -p[1], p[1]])  # p . normal for the 4 sides
    d1 = along(start)[None] - dist
    d2 = along(end)[None] - dist
    getout = jnp.any(d2 > 0, 1)
    startout = jnp.any(d1 > 0, 1)
    clear = jnp.any((d1 > 0) & ((d2 >= eps) | (d2 >= d1)), 1)  # completely in front of a side
    crosses = ~((d1 <= 0) & (d2 <= 0))
    enters = crosses & (d1 > d2)
    leaves = crosses & ~(d1 > d2)
    denom = jnp.where(d1 == d2, 1.0, d1 - d2)
    f_enter = jnp.where(enters, jnp.maximum((d1 - eps) / denom, 0.0), -1.0)
    f_leave = jnp.where(leaves, jnp.minimum((d1 + eps) / denom, 1.0), 1.0)
    side = jnp.argmax(f_enter, 1)  # the first side with the latest entry (``f > enterFrac``)
    enter = jnp.max(f_enter, 1)
    leave = jnp.min(f_leave, 1)
    hits = ~clear & startout & (enter < leave) & (enter > -1)
    allsolid = jnp.any(~clear & ~startout & ~getout)
    frac_b = jnp.where(hits, enter, 2.0)
    best = jnp.argmin(frac_b)  # the first wall with the earliest entry (``enterFrac < fraction``)
    fraction = jnp.where(allsolid, 0.0, jnp.minimum(frac_b[best], 1.0)).astype(jnp.float32)
    normal = jnp.asarray(_SIDE_NORMALS)[side[best]]
    endpos = jnp.where(fraction == 1, end, start + fraction * (end - start))
    return fraction, endpos, normal, allsolid


def slide_move(pos, vel, boxes, params: DmlabMotionParams, frametime):
    """PM_SlideMove (bg_slidemove.c:45-236) on the ground with gravity off: (new pos, new vel).
    The clip planes are kept as their x, y parts: the ground's (0, 0, 1) is (0, 0), and every
    velocity and wall normal here has z 0."""
    n_planes = params.max_clip_planes
    planes = jnp.zeros((n_planes, 2), jnp.float32).at[1].set(_normalize2(vel))  # l.79-89
    count = jnp.int32(2)
    time_left = jnp.float32(frametime)
    done = jnp.bool_(False)
    slots = jnp.arange(n_planes)
    for _ in range(params.bumps):
        end = pos + vel * time_left  # VectorMA, l.94
        fraction, endpos, normal, allsolid = trace(pos, end, boxes, params)
        done = done | allsolid  # l.99-103: trapped, nothing moves (vz would be zeroed)
        pos = jnp.where(~done & (fraction > 0), endpos, pos)
        done = done | (fraction == 1)
        live = ~done
        time_left = jnp.where(live, time_left - time_left * fraction, time_left)
        full = live & (count >= n_planes)  # l.119-123
        vel = jnp.where(full, 0.0, vel)
        done = done | full
        live = ~done
        seen = jnp.any((slots < count) & (_dot(planes, normal[None]) > 0.99))  # l.130-138
        vel = jnp.where(live & seen, vel + normal, vel)
        new = live & ~seen
        planes = jnp.where(new & (slots == count)[:, None], normal[None], planes)
        count = count + new.astype(jnp.int32)
        clip = vel  # the ground plane (i = 0) is entered and leaves it as it is (l.147-159)
        for j in range(1, n_planes):  # l.167-176; every crease test at l.183 continues
            enters = (j < count) & (_dot(clip, planes[j]) < 0.1)
            clip = jnp.where(enters, clip_velocity(clip, planes[j], params.overclip), clip)
        vel = jnp.where(new, clip, vel)
    return pos, vel


def touches(item_pos, pos, params: DmlabMotionParams) -> jnp.ndarray:
    """(K,) whether the player at ``pos`` touches each item at ``item_pos`` (K, 2)
    (BG_PlayerTouchesItem, bg_misc.c:1149-1165)."""
    x_lo, x_hi, y_lo, y_hi = params.touch_box
    d = pos[None] - item_pos
    return (d[:, 0] >= x_lo) & (d[:, 0] <= x_hi) & (d[:, 1] >= y_lo) & (d[:, 1] <= y_hi)


def tic(pose: Pose, action: jnp.ndarray, boxes: jnp.ndarray, params: DmlabMotionParams,
        line_dir: jnp.ndarray | None = None, origin: jnp.ndarray | None = None) -> Pose:
    """One engine frame (one PmoveSingle of ``params.frame_msec``) of the action (0 turn left,
    1 turn right, 2 forward, 3 nothing) among the walls ``boxes`` (S, 4). ``line_dir`` and
    ``origin`` are Doom's (``simjax.envs.doom.motion.tic``'s calling shape) and unused."""
    del line_dir, origin
    frametime = np.float32(params.frame_msec * 0.001)  # bg_pmove.c:1908
    left, right = _turn_steps(params)
    turn = jnp.where(action == TURN_LEFT, left, jnp.where(action == TURN_RIGHT, right, np.float32(0.0)))
    view_yaw = angle_mod(pose.view_yaw + turn)  # cl_input.c:597
    yaw = _short(angle2short(view_yaw) + pose.delta_yaw)  # cl_input.c:600, bg_pmove.c:1810-1821

    table_dir, table_speed = _wish_table(params.forwardmove, params.speed)
    walking = action == FORWARD
    index = yaw & (ANGLE_UNITS - 1)
    wishdir = jnp.where(walking, jnp.asarray(table_dir)[index], 0.0)
    wishspeed = jnp.where(walking, jnp.asarray(table_speed)[index], 0.0)

    # PM_Friction (bg_pmove.c:171-229)
    vel = pose.vel
    speed = jnp.sqrt(_dot(vel, vel))
    control = jnp.where(speed < params.stop_speed, jnp.float32(params.stop_speed), speed)
    drop = control * jnp.float32(params.friction) * frametime
    newspeed = jnp.maximum(speed - drop, 0.0) / jnp.where(speed < 1, 1.0, speed)
    vel = jnp.where(speed < 1, 0.0, vel * newspeed)

    # PM_Accelerate (bg_pmove.c:239-257)
    add = wishspeed - _dot(vel, wishdir)
    accel = jnp.minimum(jnp.float32(params.accelerate) * frametime * wishspeed, add)
    vel = jnp.where(add > 0, vel + accel * wishdir, vel)

    # keep the speed through the ground clip (bg_pmove.c:789-797): v / |v| * |v| as computed
    length = jnp.sqrt(_dot(vel, vel))
    vel = _normalize2(vel) * length
    vel = jnp.where(length > 0, vel, 0.0)

    moving = jnp.any(vel != 0)  # l.800-802
    pos, slid = slide_move(pose.pos, vel, boxes, params, frametime)
    pos = jnp.where(moving, pos, pose.pos)
    vel = jnp.where(moving, slid, vel)
    vel = jnp.round(vel)  # trap_SnapVector, bg_pmove.c:2014: cvtps2dq, ties to even
    return Pose(pos.astype(jnp.float32), vel.astype(jnp.float32), view_yaw.astype(jnp.float32),
                pose.delta_yaw)


def params_for(motion: str):
    """The motion params of a DMLab world's ``motion`` setting: "dmlab" (this module) or "doom"
    (Doom's motion and pickup rule, which these worlds had before; old runs rebuild with it)."""
    if motion == "dmlab":
        return DmlabMotionParams()
    if motion == "doom":
        return doom_motion.MotionParams()
    raise ValueError(f"motion must be 'dmlab' or 'doom', got {motion!r}")


__all__ = ["DmlabMotionParams", "Pose", "tic", "touches", "trace", "slide_move", "clip_velocity", "continue_view",
           "angle2short", "angle_mod", "params_for", "ANGLE_UNITS", "ACTION_NAMES"]
