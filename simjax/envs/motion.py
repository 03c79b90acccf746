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

Collision: each tic the move is tried along x, then along y, each axis against every wall; an
axis whose move would make the box overlap a wall is refused and its momentum dropped. That is
sliding: running diagonally into a wall keeps the component along it. Walls must be axis-aligned
segments (MyWayHome's are, on a 16-unit grid), for which a box-segment overlap test is exact.
A move of at most ~9 units per axis per tic can never carry a 32-unit box across a wall.
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
    heading: jnp.ndarray  # () float32, radians in [-pi, pi): angle * 2 pi / 65536
    vel: jnp.ndarray  # (2,) float32, momentum in units/tic
    angle: jnp.ndarray  # () int32, Doom's angle in 1/65536 of a turn, in [0, 65536)
    turn_tics: jnp.ndarray  # () int32, consecutive tics with a turn button down (capped)

    @staticmethod
    def at(xy, heading) -> "Pose":
        """A player standing still at ``xy`` facing ``heading`` (radians; rounded to Doom's
        nearest angle unit, 0.0055 deg). Works on traced values."""
        angle = angle_units(heading)
        return Pose(
            jnp.asarray(xy, jnp.float32).reshape(2), heading_of(angle), jnp.zeros(2, jnp.float32),
            angle, jnp.int32(0),
        )


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


def tic(pose: Pose, action: jnp.ndarray, boxes: jnp.ndarray, params: MotionParams) -> Pose:
    """One simulator tic of the action."""
    turning = (action == TURN_LEFT) | (action == TURN_RIGHT)
    turn_tics = jnp.where(turning, jnp.minimum(pose.turn_tics + 1, params.slow_turn_tics), 0)
    rate = jnp.where(turn_tics < params.slow_turn_tics, params.slow_turn_units_per_tic, params.turn_units_per_tic)
    sign = jnp.where(action == TURN_LEFT, 1, jnp.where(action == TURN_RIGHT, -1, 0))
    angle = jnp.mod(pose.angle + sign * rate, ANGLE_UNITS).astype(jnp.int32)

    walking = action == FORWARD
    vel = pose.vel + jnp.where(walking, params.thrust, 0.0) * _fine_direction(angle)
    try_x = pose.pos.at[0].add(vel[0])
    block_x = overlaps(boxes, try_x, params.radius)
    pos = jnp.where(block_x, pose.pos, try_x)
    try_y = pos.at[1].add(vel[1])
    block_y = overlaps(boxes, try_y, params.radius)
    pos = jnp.where(block_y, pos, try_y)
    vel = jnp.where(jnp.stack([block_x, block_y]), 0.0, vel)
    stopped = ~walking & jnp.all(jnp.abs(vel) < params.stop_speed)
    vel = jnp.where(stopped, 0.0, vel * params.friction)
    return Pose(pos, heading_of(angle), vel, angle, turn_tics.astype(jnp.int32))
