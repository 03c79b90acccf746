"""Doom's player motion as ViZDoom plays it: turning, thrust with momentum and friction, box
collision with sliding.

Facts measured in ViZDoom 1.3.2 (shared/reference/vizdoom_facts.md):

- Turning. Doom keeps the player's angle as an integer; a keyboard turn adds 640 units a tic,
  where a whole turn is 65536 units (3.516 deg), but only 320 (1.758 deg) while the turn
  counter is below 6 (SLOWTURNTICS). The counter goes up on every tic with either turn button
  down (left then right continues it) and back to 0 on a tic with neither. So one 4-tic turn
  step from rest turns 7.031 deg, a second consecutive one 12.305, then 14.063 a step. The
  angle is kept here as that integer (``Pose.angle``); ``Pose.heading`` is its value in
  radians, for the renderer.
- Walking. The thrust adds 0.78 units/tic to the momentum along the facing, taken from Doom's
  8192-entry sine table (angle >> 3 of our 16-bit units); friction then multiplies the momentum
  by 0.90625, so the player walks at about 7.5 units per tic. A player with no thrust whose
  momentum is below STOPSPEED (1/16 unit) on both axes stops dead, as in Doom's P_XYMovement.
- The player is a square box of half-size 16 (Doom's "radius"). One agent step repeats its
  action for 4 tics.

Collision is ZDoom's (P_XYMovement, P_TryMove, P_SlideMove), for axis-aligned walls: a tic's
whole move is taken if the player's box at its end overlaps no wall (a move of at most ~9 units
can never carry a 32-unit box across one). Otherwise the player slides: three traces run from
the box's leading corners along the move, and the nearest wall line they cross stops the box
1/32 of the move short of it; the rest of the move, with its component across that wall
removed, becomes the new momentum and is tried from there (twice at most). Like Doom's, a short
trace counts a line as crossed when its two ends lie on either side of the line's infinite
extension, for every line in the 128-unit blockmap cells the trace touches: walking past the end
of a wall can catch on its extension, which is where players part most at corners when this is
left out. When no line is found, or the tries fail, the move is "stairstepped": along y alone,
else along x alone, else not at all.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

TURN_LEFT, TURN_RIGHT, FORWARD, NOOP = 0, 1, 2, 3
ACTION_NAMES = ("turn_left", "turn_right", "forward", "noop")

ANGLE_UNITS = 65536  # a whole turn in Doom's ticcmd angle units
_FINE_SHIFT = 3  # Doom's sine table has 8192 entries: angle >> 3 of our 16-bit units
_RAD_PER_UNIT = 2.0 * math.pi / ANGLE_UNITS
_BLOCK = 128.0  # Doom's blockmap cell
_FUDGE = 1.0 / 32.0  # P_SlideMove stops this fraction of the move short of the wall


class MotionParams(NamedTuple):
    turn_units_per_tic: int = 640  # Doom's angleturn at walking speed
    slow_turn_units_per_tic: int = 320  # while the turn counter is below slow_turn_tics
    slow_turn_tics: int = 6  # SLOWTURNTICS
    thrust: float = 0.78125  # forwardmove 25 * 2048 / 65536
    friction: float = 0.90625
    stop_speed: float = 0.0625  # STOPSPEED, 0x1000 in 16.16 fixed point
    radius: float = 16.0
    tics_per_step: int = 4


class Pose(NamedTuple):
    pos: jnp.ndarray  # (2,) float32
    vel: jnp.ndarray  # (2,) float32, momentum in units/tic
    angle: jnp.ndarray  # () int32, Doom's angle in 1/65536 of a turn, in [0, 65536)
    turn_tics: jnp.ndarray  # () int32, consecutive tics with a turn button down (capped)

    @property
    def heading(self) -> jnp.ndarray:
        """() float32, radians in [-pi, pi): angle * 2 pi / 65536."""
        return heading_of(self.angle)

    @staticmethod
    def at(xy, heading) -> Pose:
        """A player standing still at ``xy`` facing ``heading`` (radians; rounded to Doom's
        nearest angle unit, 0.0055 deg). Works on traced values."""
        return Pose.facing(xy, angle_units(heading))

    @staticmethod
    def facing(xy, angle) -> Pose:
        """A player standing still at ``xy`` facing Doom angle ``angle`` (integer units, 65536 a
        turn, taken modulo a turn). Works on traced values."""
        angle = jnp.mod(jnp.asarray(angle, jnp.int32), ANGLE_UNITS)
        return Pose(jnp.asarray(xy, jnp.float32).reshape(2), jnp.zeros(2, jnp.float32), angle, jnp.int32(0))


def angle_units(heading) -> jnp.ndarray:
    """Radians -> Doom angle units in [0, 65536), rounded to the nearest unit."""
    units = jnp.round(jnp.asarray(heading, jnp.float32) / _RAD_PER_UNIT).astype(jnp.int32)
    return jnp.mod(units, ANGLE_UNITS)


def heading_of(angle) -> jnp.ndarray:
    """Doom angle units -> radians in [-pi, pi)."""
    signed = jnp.mod(jnp.asarray(angle, jnp.int32) + ANGLE_UNITS // 2, ANGLE_UNITS) - ANGLE_UNITS // 2
    return signed.astype(jnp.float32) * jnp.float32(_RAD_PER_UNIT)


def _fine_direction(angle) -> jnp.ndarray:
    """(2,) Doom's finecosine/finesine of the angle: its 8192-entry table is sampled at the
    middle of each of its angle bins, sin((i + 0.5) 2 pi / 8192)."""
    fine = (angle >> _FINE_SHIFT).astype(jnp.float32) + 0.5
    a = fine * jnp.float32(2.0 * math.pi / (ANGLE_UNITS >> _FINE_SHIFT))
    return jnp.stack([jnp.cos(a), jnp.sin(a)])


def line_directions(start: np.ndarray, end: np.ndarray) -> jnp.ndarray:
    """(S,) +1 where a wall row (Doom's linedef v1 -> v2) runs toward +x or +y, else -1."""
    return jnp.asarray(np.sign(np.asarray(end) - np.asarray(start)).sum(1), jnp.float32)


def wall_boxes(start: np.ndarray, end: np.ndarray) -> jnp.ndarray:
    """(S, 4) boxes [xmin, ymin, xmax, ymax] of axis-aligned segments; refuses diagonal walls."""
    start, end = np.asarray(start), np.asarray(end)
    if np.any((start[:, 0] != end[:, 0]) & (start[:, 1] != end[:, 1])):
        raise ValueError("collision needs axis-aligned walls; a diagonal wall was given")
    lo, hi = np.minimum(start, end), np.maximum(start, end)
    return jnp.asarray(np.concatenate([lo, hi], axis=1), jnp.float32)


def overlaps(boxes: jnp.ndarray, pos: jnp.ndarray, radius: float) -> jnp.ndarray:
    """Whether the player box at ``pos`` overlaps (strictly) any wall."""
    x, y = pos[0], pos[1]
    hit = (
        (x - radius < boxes[:, 2])
        & (x + radius > boxes[:, 0])
        & (y - radius < boxes[:, 3])
        & (y + radius > boxes[:, 1])
    )
    return jnp.any(hit)


def _side(px, py, box, line_dir):
    """Doom's P_PointOnLineSide for axis-aligned lines: 0 on the front (right of v1 -> v2), 1 on
    the back. ``box`` (..., 4) [xmin, ymin, xmax, ymax]; ``line_dir`` +1 where v2 is above/right
    of v1, else -1."""
    vertical = box[..., 0] == box[..., 2]
    v_side = jnp.where(px <= box[..., 0], line_dir > 0, line_dir < 0)
    h_side = jnp.where(py <= box[..., 1], line_dir < 0, line_dir > 0)
    return jnp.where(vertical, v_side, h_side)


def _slide_hit(pos, move, boxes, line_dir, origin, radius):
    """Doom's three corner traces for P_SlideMove: the nearest crossing fraction (> 1 where
    none) and whether that line runs along x."""
    lead = pos + jnp.where(move > 0, radius, -radius)
    trail = pos - jnp.where(move > 0, radius, -radius)
    starts = jnp.stack([lead, jnp.stack([trail[0], lead[1]]), jnp.stack([lead[0], trail[1]])])  # (3, 2)
    ends = starts + move
    # blockmap cells: a start exactly on a cell edge is nudged one unit in (ZDoom), the trace
    # covers the cells between its ends; a line lies in the cells of its span (its low cell
    # for a line on a cell edge, and the next one up for an end on an edge)
    on_edge = jnp.mod(starts - origin, _BLOCK) == 0
    first = jnp.floor((starts + on_edge - origin) / _BLOCK)
    last = jnp.floor((ends - origin) / _BLOCK)
    t_lo, t_hi = jnp.minimum(first, last), jnp.maximum(first, last)  # (3, 2)
    l_lo = jnp.floor((boxes[:, :2] - origin) / _BLOCK)  # (S, 2)
    l_hi = jnp.floor((boxes[:, 2:] - origin) / _BLOCK)
    near = jnp.all((l_lo[None] <= t_hi[:, None]) & (l_hi[None] >= t_lo[:, None]), axis=-1)  # (3, S)
    s0 = _side(starts[:, None, 0], starts[:, None, 1], boxes[None], line_dir[None])
    s1 = _side(ends[:, None, 0], ends[:, None, 1], boxes[None], line_dir[None])
    vertical = boxes[:, 0] == boxes[:, 2]
    at = jnp.where(vertical, boxes[:, 0], boxes[:, 1])
    d = jnp.where(vertical[None], move[0], move[1])  # (1, S)
    start_on_axis = jnp.where(vertical[None], starts[:, :1], starts[:, 1:])  # (3, S)
    frac = (at[None] - start_on_axis) / jnp.where(d == 0, 1e-9, d)
    # (Doom skips a one-sided line seen from its back; every wall here blocks from both sides,
    # and a MyWayHome player is never behind one)
    hit = near & (s0 != s1) & (frac >= 0)
    frac = jnp.where(hit, frac, 2.0).min(axis=0)  # (S,)
    best = jnp.argmin(frac)
    return frac[best], ~vertical[best]


def _move(pos, vel, boxes, line_dir, origin, radius):
    """One tic's move of the player box with momentum ``vel``: (new pos, new momentum)."""
    clear = lambda p: ~overlaps(boxes, p, radius)
    full = pos + vel
    done = clear(full)
    p, v, tryv = jnp.where(done, full, pos), vel, vel
    stair = jnp.bool_(False)
    for _ in range(2):  # ZDoom gives up and stairsteps on the third hit
        active = ~done & ~stair
        best, along_x = _slide_hit(p, tryv, boxes, line_dir, origin, radius)
        no_line = best > 1.0
        frac = best - _FUDGE
        up = p + tryv * jnp.maximum(frac, 0.0)
        up_ok = (frac <= 0) | clear(up)
        stair = stair | (active & (no_line | ~up_ok))
        active = active & ~no_line & up_ok
        p = jnp.where(active, up, p)
        rest = jnp.minimum(1.0 - best, 1.0)
        stop = active & (rest <= 0)  # pressed against the wall: momentum kept as it was
        done = done | stop
        active = active & ~stop
        slid = tryv * rest * jnp.where(along_x, jnp.array([1.0, 0.0]), jnp.array([0.0, 1.0]))
        tryv = jnp.where(active, slid, tryv)
        v = jnp.where(active, slid, v)
        ok = clear(p + tryv)
        p = jnp.where(active & ok, p + tryv, p)
        done = done | (active & ok)
    stair = stair | ~done
    only_y = p + jnp.stack([0.0, v[1]])
    only_x = p + jnp.stack([v[0], 0.0])
    y_ok, x_ok = clear(only_y), clear(only_x)
    sp = jnp.where(y_ok, only_y, jnp.where(x_ok, only_x, p))
    sv = jnp.where(y_ok, v * jnp.array([0.0, 1.0]), jnp.where(x_ok, v * jnp.array([1.0, 0.0]), 0.0))
    return jnp.where(stair, sp, p), jnp.where(stair, sv, v)


def tic(pose: Pose, action: jnp.ndarray, boxes: jnp.ndarray, params: MotionParams,
        line_dir: jnp.ndarray, origin: jnp.ndarray) -> Pose:
    """One simulator tic of the action. ``boxes`` (S, 4) are the walls, ``line_dir`` (S,) their
    direction (+1 where the linedef runs up or right), ``origin`` (2,) the blockmap's corner
    (the map's lowest vertex coordinates)."""
    turning = (action == TURN_LEFT) | (action == TURN_RIGHT)
    turn_tics = jnp.where(turning, jnp.minimum(pose.turn_tics + 1, params.slow_turn_tics), 0)
    rate = jnp.where(turn_tics < params.slow_turn_tics, params.slow_turn_units_per_tic, params.turn_units_per_tic)
    sign = jnp.where(action == TURN_LEFT, 1, jnp.where(action == TURN_RIGHT, -1, 0))
    angle = jnp.mod(pose.angle + sign * rate, ANGLE_UNITS).astype(jnp.int32)

    walking = action == FORWARD
    vel = pose.vel + jnp.where(walking, params.thrust, 0.0) * _fine_direction(angle)
    pos, vel = _move(pose.pos, vel, boxes, line_dir, origin, params.radius)
    stopped = ~walking & jnp.all(jnp.abs(vel) < params.stop_speed)
    vel = jnp.where(stopped, 0.0, vel * params.friction)
    return Pose(pos, vel, angle, turn_tics.astype(jnp.int32))
