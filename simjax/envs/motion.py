"""Doom-like player motion: turning, thrust with momentum and friction, box collision with sliding.

Facts from the MyWayHome scenario (shared/reference/my_way_home_map.json): a keyboard turn is
7.03 degrees per tic; walking thrust adds 0.78 units/tic to the momentum and friction then
multiplies it by 0.90625, so the player walks at about 8 units per tic; the player is a square
box of half-size 16 (Doom's "radius"). One agent step repeats its action for 4 tics.

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


class MotionParams(NamedTuple):
    turn_rad_per_tic: float = math.radians(7.03)
    thrust: float = 0.78
    friction: float = 0.90625
    radius: float = 16.0
    tics_per_step: int = 4


class Pose(NamedTuple):
    pos: jnp.ndarray  # (2,) float32
    heading: jnp.ndarray  # () float32, radians
    vel: jnp.ndarray  # (2,) float32, momentum in units/tic


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
    turn = jnp.where(action == TURN_LEFT, 1.0, jnp.where(action == TURN_RIGHT, -1.0, 0.0))
    heading = pose.heading + turn * params.turn_rad_per_tic
    heading = jnp.mod(heading + math.pi, 2.0 * math.pi) - math.pi
    thrust = jnp.where(action == FORWARD, params.thrust, 0.0)
    vel = pose.vel + thrust * jnp.stack([jnp.cos(heading), jnp.sin(heading)])

    try_x = pose.pos.at[0].add(vel[0])
    block_x = overlaps(boxes, try_x, params.radius)
    pos = jnp.where(block_x, pose.pos, try_x)
    try_y = pos.at[1].add(vel[1])
    block_y = overlaps(boxes, try_y, params.radius)
    pos = jnp.where(block_y, pos, try_y)
    vel = jnp.where(jnp.stack([block_x, block_y]), 0.0, vel) * params.friction
    return Pose(pos, heading, vel)
