"""The Freedoom graphics ViZDoom draws MyWayHome with, as numpy arrays.

``assets/freedoom_mywayhome.npz`` is written by ``tools/freedoom_assets.py`` from the
``freedoom2.wad`` (Freedoom 0.13.0) and ``scenarios/my_way_home.wad`` that the vizdoom
package ships; Freedoom's licence is ``assets/FREEDOOM-LICENSE.txt``. Keys:

- ``wall_<NAME>`` (H, W, 3) uint8 RGB and ``wall_<NAME>_index`` (H, W) uint8 palette
  indices, for each name in ``texture_names``. Doom's texel layout: row 0 is the top of the
  texture, column 0 its left (u = 0). Built the way ZDoom looks a wall texture up: a
  TEXTURE1 composite (its PNAMES patches drawn at their origins) if one has the name, else
  a flat, which as a wall texture is 64x64. The index form lets a renderer apply
  ``colormap`` light levels exactly, as Doom does.
- ``flat_FLAT1_1`` (64, 64, 3) uint8 and ``flat_FLAT1_1_index`` (64, 64) uint8: every
  sector's floor and ceiling, tiled every 64 map units: the texel at map (x, y) is
  row ``-y mod 64``, column ``x mod 64`` (north up, as Doom's span drawer reads it).
- ``sprite_ARM1A0`` (H, W, 4) uint8 RGBA: the goal's GreenArmor, alpha 0 where the picture
  has no pixel; ``sprite_ARM1A0_offset`` int32 (leftoffset, topoffset): the texel column
  drawn at the thing's x and the texel row drawn at its floor height, as Doom places sprites.
- ``playpal`` (256, 3) uint8: PLAYPAL palette 0. ``colormap`` (34, 256) uint8: COLORMAP,
  rows 0 (brightest) to 31 (darkest) remap a palette index to a light level, 32 is the
  invulnerability map, 33 all black.
- ``texture_names`` (9,) str: the names in the order of ``mywayhome_map.TEXTURE_NAMES``.
- Per row of ``mywayhome_map.WALLS`` (76 rows, same order), from the map's UDMF TEXTMAP:
  ``wall_linedef`` int32 (the linedef the row is), ``wall_offset_x`` / ``wall_offset_y``
  float32 (its front sidedef's offsetx / offsety) and ``wall_u_reversed`` bool (the row runs
  from the linedef's v2 to v1). Doom's texture u at a point of a wall is offsetx plus the
  distance from v1, so from the row's start at distance t along a row of length L:
  ``u = offset_x + (L - t if u_reversed else t)`` (mod the texture width). Every wall is
  one-sided, floor 0 to ceiling 128, not lower-unpegged: texture row 0 is at the ceiling,
  so ``v = offset_y + (128 - z)``.

The arrays are read-only because one cached copy is shared by every caller.
"""

from __future__ import annotations

import functools
import os

import numpy as np

ASSET = os.path.join(os.path.dirname(os.path.abspath(__file__)), "assets",
                     "freedoom_mywayhome.npz")


@functools.lru_cache(maxsize=4)
def load(path: str | os.PathLike | None = None) -> dict[str, np.ndarray]:
    """The asset's arrays by key (see the module docstring); ``path`` defaults to the
    packaged file."""
    with np.load(path or ASSET, allow_pickle=False) as data:
        arrays = {key: data[key] for key in data.files}
    for array in arrays.values():
        array.flags.writeable = False
    return arrays
