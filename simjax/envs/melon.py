"""``melon``: reward distraction, after DMLab's Stairway to Melon (paper section 3.3, appendix C).

From the start room a corridor leads north to a junction. West: a row of six apples (+1 each,
once per episode) and a dead end. East: a lemon (-1, once) and, round a corner to the north,
out of sight from the junction, the melon (+20; success, the episode ends). 525 agent steps,
3 actions {turn left, turn right, forward}. The apples pay at once; the melon pays 20 for
walking past a penalty and round a corner, which a myopic or apple-greedy policy never does.

Geometry in Doom units (corridors 128 wide), y up::

                                 +--+  y = 1152
                                 |M |  melon (704, 1056)
    +----------------------------+  |  y = 512
    |D  a  a  a  a  a  a    |  L    |  apples y = 448; lemon (352, 448)
    +----------------------+ +------+  y = 384
    x = -1024             | |      x = 768
                          |S|  start (0, 64), facing north
                          +-+  y = 0
"""

from __future__ import annotations

import math

from simjax.envs import raycaster
from simjax.envs.maze import Layout, MazeTask

BRICK, CRATE, GREEN, RED, BLUE = 8, 2, 3, 5, 7  # wall looks (raycaster.TEXTURE_LOOKS)

WALLS = (
    # start corridor
    (-64, 0, 64, 0, BRICK), (64, 0, 64, 384, BRICK), (-64, 384, -64, 0, BRICK),
    # east arm to the corner, then the melon's corridor north
    (64, 384, 768, 384, GREEN), (768, 384, 768, 512, GREEN), (768, 512, 768, 1152, BLUE),
    (768, 1152, 640, 1152, BLUE), (640, 1152, 640, 512, BLUE), (640, 512, 0, 512, GREEN),
    # west arm: the apples, ending in a dead end
    (0, 512, -1024, 512, CRATE), (-1024, 512, -1024, 384, RED), (-1024, 384, -64, 384, CRATE),
)
START_XY = (0.0, 64.0)
APPLES_XY = tuple((float(x), 448.0) for x in (-224, -352, -480, -608, -736, -864))
LEMON_XY = (352.0, 448.0)
MELON_XY = (704.0, 1056.0)
APPLE_REWARD, LEMON_REWARD, MELON_REWARD = 1.0, -1.0, 20.0


def melon_layout() -> Layout:
    items = [(x, y, raycaster.APPLE, APPLE_REWARD, False) for x, y in APPLES_XY]
    items += [(*LEMON_XY, raycaster.LEMON, LEMON_REWARD, False), (*MELON_XY, raycaster.MELON, MELON_REWARD, True)]
    return Layout.build(WALLS, items, [START_XY])


MELON_TASK = MazeTask("melon", random_heading=False, heading=math.pi / 2, max_steps=525, num_actions=3)
