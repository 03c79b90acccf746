"""``melon``: reward distraction, after DMLab's Stairway to Melon (paper section 3.3, appendix C).

The map is DeepMind Lab's ``assets/maps/stairway_to_melon.map`` (google-deepmind/lab; read, not
copied), made flat, in its own coordinates (one DMLab unit is one unit here). The player moves
and picks up fruit as DMLab's does (``simjax.envs.dmlab.pmove``: a box 30 wide, 8.448 degrees a
turn step, up to 20.48 units a forward step); ``motion="doom"`` gives the Doom motion and
pickup rule these worlds had before (a box 32 wide), for runs made with it:

- Outer walls enclose the square x, y in [-512, 512] (brushes 1, 3, 4, 5: 16-unit slabs at
  +-512); a solid block fills x, y in [-448, 448] (brush 2). What is left is a ring corridor
  64 units wide.
- The west side of the ring is a staircase: 14 steps 64 deep and 16 high (brushes 16-29,
  x in [-512, -448], from y = -448 up to y = 448, tops at z = 24 ... 232) up to a platform at
  z = 248 over the north-west corner and the north side as far as x = 0 (brush 30). Every
  other floor is at z = 8 (brushes 15, 31, 32). The platform's east edge, x = 0, is a 240-unit
  cliff above the north corridor: from the east the north corridor is a dead end.
  Flat here: the stairs are a corridor, and the cliff is a wall at x = 0 (DMLab's agent can
  drop off the platform into the dead end; here it cannot).
- Entities: the player start at (0, -480) with angle 90 (facing north, into the block);
  a lemon (``lemon_reward``) at (-128, -480), west of the start, on the way to the stairs;
  14 apples (``apple_reward``) the other way round: (128, 256, 384, 480) x -480 along the
  south side, 480 x (-320, -192, -64, 64, 192, 320, 480) up the east side, (384, 256, 128) x
  480 along the north side to the dead end; the melon (``watermelon_goal``) at (-40, 480) on
  the platform, just past the top of the stairs.
- Rewards (``game_scripts/common/pickups.lua``): apple +1, lemon -1, watermelon +20 (type GOAL).

So from the start facing the block the agent turns east to 14 apples (14 points) and a dead
end, or west through the lemon (-1) and up the stairs to the melon (+20); the lemon route
is 1,880 units long, the apple route 1,920 to the dead end.

Rules of ``melon``: the paper's (section 3.3, which states them): the melon ends the episode as
a success; 525 agent steps; 3 actions {turn left, turn right, forward}. ``melon-dmlab``
(``MelonLevelEnv``) has DMLab's own level's rules instead
(``game_scripts/levels/stairway_to_melon.lua`` -> ``factories/seek_avoid_factory.lua``):
60 s episodes (900 agent steps at 60 frames/s and 4 frames a step), and the melon, a GOAL
pickup, restarts the level (the agent back at the start, every fruit back) without ending the
episode (``docs/developers/reference/lua_api.md``).

Looks (``look``): "dmlab" (the default) draws the map as DMLab does (``simjax.envs.dmlab.look``):
every wall ``lg_style_01_wall_blue`` placed as its brush face places it (``FACES``), the cliff
face and every floor ``lg_style_01_floor_orange``, the sky ``lg_sky_01`` above walls 312 units
high (floor z = 8 to the walls' tops at 320), and the fruits as their models. "invented" is the
look these worlds had before 2026-12-07 (``raycaster``'s looks, one per part of the ring: the
south corridor brick, the apple side crates, the stair corridor orange, the platform blue, the
cliff face red), kept for the ``*-doom-motion`` tasks and the runs made with them.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp

from simjax.envs import raycaster
from simjax.envs.dmlab import look as dmlab_look
from simjax.envs.dmlab import pmove
from simjax.envs.maze import Layout, MazeEnv, MazeTask

BRICK, CRATE, RED, BLUE, ORANGE = 8, 2, 5, 7, 9  # the invented look's walls (raycaster.TEXTURE_LOOKS)
OUTER, INNER, CLIFF_X = 512.0, 448.0, 0.0

WALLS = (
    # south corridor (the start, the lemon to the west, the first apples to the east)
    (-OUTER, -OUTER, OUTER, -OUTER, BRICK), (INNER, -INNER, -INNER, -INNER, BRICK),
    (-OUTER, -INNER, -OUTER, -OUTER, BRICK), (OUTER, -OUTER, OUTER, -INNER, BRICK),
    # east side and the north side up to the cliff: the apples
    (OUTER, -INNER, OUTER, OUTER, CRATE), (INNER, INNER, INNER, -INNER, CRATE),
    (OUTER, OUTER, CLIFF_X, OUTER, CRATE), (CLIFF_X, INNER, INNER, INNER, CRATE),
    # the cliff at the platform's east edge: the apple side's dead end
    (CLIFF_X, OUTER, CLIFF_X, INNER, RED),
    # west side: the stairs, as a corridor
    (-OUTER, INNER, -OUTER, -INNER, ORANGE), (-INNER, -INNER, -INNER, INNER, ORANGE),
    # the platform over the north-west corner: the melon
    (CLIFF_X, OUTER, -OUTER, OUTER, BLUE), (-OUTER, OUTER, -OUTER, INNER, BLUE), (-INNER, INNER, CLIFF_X, INNER, BLUE),
)
START_XY = (0.0, -480.0)  # info_player_start origin "0 -480 32", angle 90
START_HEADING = math.pi / 2
LEMON_XY = (-128.0, -480.0)
APPLES_XY = (
    tuple((float(x), -480.0) for x in (128, 256, 384, 480))
    + tuple((480.0, float(y)) for y in (-320, -192, -64, 64, 192, 320, 480))
    + tuple((float(x), 480.0) for x in (384, 256, 128))
)
MELON_XY = (-40.0, 480.0)
APPLE_REWARD, LEMON_REWARD, MELON_REWARD = 1.0, -1.0, 20.0  # pickups.lua quantities


# DMLab's look: the map's surfaces, and the texture fields of the brush face each wall row is
# (assets/maps/src/stairway_to_melon.map, by line): the outer walls (brushes 1, 3-5, e.g. l.20,
# 38, 48, 56), the block's faces along x (brush 2, l.30, 32) and along y (l.31, 33), and the
# platform's east face, the cliff (brush 30, l.283)
SURFACES = ("map/lab_games/lg_style_01_wall_blue", "map/lab_games/lg_style_01_floor_orange")
OUTER_FACE = dmlab_look.Face(SURFACES[0], 3584.0, 52.0, -0.142857, 0.19)
BLOCK_FACE_ALONG_X = dmlab_look.Face(SURFACES[0], 3822.0, 52.0, -0.133929, 0.19)
BLOCK_FACE_ALONG_Y = dmlab_look.Face(SURFACES[0], 3584.0, 52.0, -0.125, 0.19)
CLIFF_FACE = dmlab_look.Face(SURFACES[1], 0.0, -128.0, 0.19, 0.19)
FLOOR_Z, WALL_TOP = 8.0, 320.0  # brushes 15, 31, 32 (the floors' tops); the walls' and the block's tops


def _face(row) -> dmlab_look.Face:
    x1, y1, x2, y2 = row[:4]
    if x1 == x2 == CLIFF_X:
        return CLIFF_FACE
    if max(abs(x1), abs(x2), abs(y1), abs(y2)) == OUTER and (abs(x1) == abs(x2) == OUTER or abs(y1) == abs(y2) == OUTER):
        return OUTER_FACE
    return BLOCK_FACE_ALONG_X if y1 == y2 else BLOCK_FACE_ALONG_Y


FACES = tuple(_face(row) for row in WALLS)


def melon_layout(look: str = "dmlab") -> Layout:
    """Items in order: the 14 apples, the lemon, the melon (the only one that ends). The wall
    rows' textures index ``SURFACES`` for the "dmlab" look, ``raycaster.TEXTURE_LOOKS`` for the
    "invented" one."""
    dmlab_look.check_look(look)
    rows = WALLS if look == "invented" else [(*row[:4], SURFACES.index(f.surface)) for row, f in zip(WALLS, FACES)]
    items = [(x, y, raycaster.APPLE, APPLE_REWARD, False) for x, y in APPLES_XY]
    items += [(*LEMON_XY, raycaster.LEMON, LEMON_REWARD, False), (*MELON_XY, raycaster.MELON, MELON_REWARD, True)]
    return Layout.build(rows, items, [START_XY])


def melon_look(layout: Layout):
    """DMLab's look of the map (a ``melon_layout("dmlab")``): walls from floor 8 to 320, the floor
    orange, the sky lg_sky_01 (stairway_to_melon.map brush 6; assets/scripts/lab_games.shader:2078-2090)."""
    return dmlab_look.build_look(layout.walls, SURFACES, FACES, wall_height=WALL_TOP - FLOOR_Z, floor_z=FLOOR_Z,
                                 floors=(SURFACES[1],), sky="map/lab_games/sky/lg_sky_01")


def _look_kwargs(look: str, layout: Layout, kwargs: dict) -> dict:
    """MazeEnv's look (a DoomLook, or None for the invented looks) and camera for ``look`` (a
    ``camera`` in ``kwargs`` wins)."""
    if look == "dmlab":
        kwargs.setdefault("camera", dmlab_look.CAMERA)
    return {**kwargs, "look": melon_look(layout) if look == "dmlab" else None}


MELON_TASK = MazeTask("melon", random_heading=False, heading=START_HEADING, max_steps=525, num_actions=3)
MELON_DMLAB_TASK = MazeTask("melon-dmlab", random_heading=False, heading=START_HEADING, max_steps=900, num_actions=3)
APPLES_TOTAL = APPLE_REWARD * len(APPLES_XY)


def melon_env(motion: str = "dmlab", look: str = "dmlab", **kwargs) -> MazeEnv:
    """``melon``: the map under the paper's rules, moving as ``motion`` ("dmlab" or "doom",
    ``pmove.params_for``) says, drawn in ``look`` ("dmlab" or "invented", the module docstring);
    a ``motion_params`` or ``camera`` in ``kwargs`` (MazeEnv's) wins."""
    kwargs.setdefault("motion_params", pmove.params_for(motion))
    layout = melon_layout(look)
    return MazeEnv(layout, MELON_TASK, **_look_kwargs(look, layout, kwargs))


class MelonLevelEnv(MazeEnv):
    """``melon-dmlab``: the same map under DMLab's level rules (module docstring): 900 steps, and
    the melon (+20) puts the agent back at the start facing north with every fruit back, the
    episode going on. An episode is a success if it reached the melon at least once, which is
    when its return exceeds the apples' 14: without the melon the return is at most 14, with
    k >= 1 melons at least 20k - (k + 1) >= 18 (a lemon per level at most)."""

    def __init__(self, motion: str = "dmlab", look: str = "dmlab", **kwargs):
        """``motion``: "dmlab" or "doom" (``pmove.params_for``); ``look``: "dmlab" or
        "invented"; a ``motion_params`` or ``camera`` in ``kwargs`` (MazeEnv's) wins."""
        layout = melon_layout(look)
        layout = layout._replace(items=layout.items._replace(ends=jnp.zeros_like(layout.items.ends)))
        kwargs.setdefault("motion_params", pmove.params_for(motion))
        super().__init__(layout, MELON_DMLAB_TASK, **_look_kwargs(look, layout, kwargs))

    def _on_touch(self, key, pose, world, collected):
        hit = collected[-1]  # the melon, the layout's last item
        pose = jax.tree.map(lambda n, o: jnp.where(hit, n, o), self._respawned(self._spawn(key), pose), pose)
        return pose, world, collected & ~hit

    def _success(self, reached, ep_return):
        return ep_return > APPLES_TOTAL
