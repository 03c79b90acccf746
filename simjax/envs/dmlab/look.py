"""The DMLab worlds as DeepMind Lab draws them, on ``doom_render``'s textured renderer.

``doom_render`` draws textured walls (box-filtered across each output column, averaged exactly
down it), flat-coloured floor rows and sprites; a ``DoomLook`` holds the arrays. This module
fills one with DeepMind Lab's surfaces instead of Freedoom's, from
``assets/dmlab_looks.npz`` (made by ``tools/dmlab_assets.py`` from google-deepmind/lab at
b1db91a, CC BY 4.0: ``assets/DMLAB-ASSETS-LICENSE.txt``; that tool's docstring says how each
shader was composited). What a DMLab look is:

- Walls: each wall row's surface (a texture of 64 x 64 texels, each the mean of 16 x 16 of the
  1024 x 1024 original), placed as Quake 3 places a brush face's texture
  (``TextureAxisFromPlane``: a wall facing x takes s along +y, one facing y along +x, t down
  -z): ``s = coordinate / scale_s + offset_s``, ``t = -z / scale_t + offset_t`` in texels of
  the original, with the face's offsets and scales from the map (``Face``). Vertical offsets
  are rounded to whole stored texels.
- Floors: the floor surface's mean colour (as ``doom_render`` draws Doom's flats): one colour,
  or per floor cell where the world has a floor grid (``Layout.floor``; explore-goals' rooms
  and corridors differ).
- No ceiling: DMLab's levels have a sky (``skyparms``), drawn above the walls as its colour at
  each screen row's elevation, averaged round the horizon (``doom_render._sky_rows``).
- Items: each pickup's model from the side, one texel a unit, as a sprite (``raycaster``'s
  item looks GOAL, APPLE, LEMON, MELON are sprites 0-3) standing 19 units off the floor.
- No lighting: every surface at full brightness (DMLab's lightmaps left out), the same from
  every side and distance (``DoomLight``'s tables are all 1 here).
- The camera: DMLab's ``cg_fov`` 90 (horizontal) on a square screen (so 90 vertically too) at
  84 x 84, area-averaged to 42 x 42; the eye 50 units above the floor (the player's origin 24
  above its feet, ``MINS_Z``, plus ``DEFAULT_VIEWHEIGHT`` 26); no view bob.

What stands in for the textures no repository here holds (the fruit models' textures, the sky
``lg_sky_03``) is listed in the asset (``substitutions``) and in docs/paper-differences.md.
"""

from __future__ import annotations

import functools
import os
from collections.abc import Sequence
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from simjax.envs import raycaster
from simjax.envs.doom import doom_render

ASSET = os.path.join(os.path.dirname(os.path.abspath(__file__)), "assets", "dmlab_looks.npz")
FULL = 1024  # the originals' texels a side
LOOKS = ("dmlab", "invented")  # a DMLab world's look: DMLab's surfaces, or raycaster's invented looks
# the player's origin 24 above the floor (bg_public.h MINS_Z -24) plus DEFAULT_VIEWHEIGHT 26 (bg_public.h:50)
EYE_HEIGHT = 50.0
CAMERA = doom_render.DoomCamera(width=42, height=42, screen_width=84, screen_height=84, fov_deg=90.0,
                                eye_height=EYE_HEIGHT, pixel_aspect=1.0, horizon=42.0)
LIGHT = doom_render.DoomLight()  # its tables index a light_rgb of ones: no light

# MISHMASH (game_scripts/themes/texture_sets.lua:22-68), in its order; the first of each is the
# default variation's, which the corridors get (themes/themes.lua:32-41)
MISHMASH_FLOORS = tuple(f"map/lab_games/lg_style_{s}" for s in (
    "01_floor_orange", "01_floor_orange_bright", "01_floor_blue", "01_floor_blue_bright",
    "02_floor_blue", "02_floor_blue_bright", "02_floor_green", "02_floor_green_bright",
    "03_floor_green", "03_floor_green_bright", "03_floor_blue", "03_floor_blue_bright",
    "04_floor_blue", "04_floor_blue_bright", "04_floor_orange", "04_floor_orange_bright",
    "05_floor_blue", "05_floor_blue_bright", "05_floor_orange", "05_floor_orange_bright"))
MISHMASH_WALLS = tuple(f"map/lab_games/lg_style_{s}" for s in (
    "01_wall_green", "01_wall_green_bright", "01_wall_red", "01_wall_red_bright",
    "02_wall_yellow", "02_wall_yellow_bright", "02_wall_blue", "02_wall_blue_bright",
    "03_wall_orange", "03_wall_orange_bright", "03_wall_gray", "03_wall_gray_bright",
    "04_wall_green", "04_wall_green_bright", "04_wall_red", "04_wall_red_bright",
    "05_wall_red", "05_wall_red_bright", "05_wall_yellow", "05_wall_yellow_bright"))
TEXT_LEVEL_SCALE = 100.0 / FULL  # text levels: one 1024-texel tile per 100-unit cell (text_level_exporter.cc:43-48, .h:49)


class Face(NamedTuple):
    """A brush face's texture fields as a Quake 3 .map gives them (in the original's texels)."""

    surface: str
    offset_s: float
    offset_t: float
    scale_s: float
    scale_t: float


def check_look(look: str) -> str:
    if look not in LOOKS:
        raise ValueError(f"look must be one of {LOOKS}, got {look!r}")
    return look


@functools.lru_cache(maxsize=2)
def load(path: str | os.PathLike | None = None) -> dict[str, np.ndarray]:
    """The asset's arrays by key (``tools/dmlab_assets.py`` says what each holds), read-only."""
    with np.load(path or ASSET, allow_pickle=False) as data:
        arrays = {key: data[key] for key in data.files}
    for array in arrays.values():
        array.flags.writeable = False
    return arrays


def surface(name: str, assets: dict | None = None) -> np.ndarray:
    """(64, 64, 3) uint8 texels of surface ``name`` (e.g. ``map/lab_games/lg_style_01_wall_blue``)."""
    assets = load() if assets is None else assets
    return assets["surfaces"][list(assets["surface_names"]).index(name)]


def surface_mean(name: str, assets: dict | None = None) -> np.ndarray:
    """(3,) the full-resolution surface's mean colour, 0..1."""
    assets = load() if assets is None else assets
    return assets["surface_mean"][list(assets["surface_names"]).index(name)]


def sky_table(name: str, assets: dict | None = None) -> np.ndarray:
    """(181, 3) sky ``name``'s colour by elevation, after the asset's substitutions."""
    assets = load() if assets is None else assets
    subst = {w: u for w, u, _ in assets["substitutions"]}
    name = subst.get(f"textures/{name}", f"textures/{name}").removeprefix("textures/")
    return assets["sky_elevation_rgb"][list(assets["sky_names"]).index(name)]


def _sprites(assets) -> tuple[np.ndarray, tuple, tuple]:
    """The items' sprites as ``doom_render`` reads them: prefix sums of every sprite's filtered
    columns, stacked; (Wp, Hs); per sprite (origin column + padding, top height)."""
    names = list(assets["sprite_names"])
    if names != ["goal", "apple", "lemon", "melon"]:  # raycaster.GOAL, APPLE, LEMON, MELON
        raise ValueError(f"the asset's sprites are {names}, not raycaster's item looks")
    rgba = np.asarray(assets["sprites"], np.float64) / 255.0  # (N, Hs, Ws, 4)
    alpha = rgba[..., 3:]
    premul = np.concatenate([rgba[..., :3] * alpha, alpha], -1).transpose(0, 2, 1, 3)  # (N, Ws, Hs, 4)
    pad = doom_render._SPRITE_PAD
    premul = np.pad(premul, ((0, 0), (pad, pad), (0, 0), (0, 0)))
    hs = premul.shape[2]
    prefix = np.stack([doom_render._prefix_down(doom_render._box_levels(p, wrap=False), hs) for p in premul])
    offsets = tuple((float(left) + pad, float(top)) for left, top in np.asarray(assets["sprite_offsets"]))
    return prefix.reshape(-1, 4), (premul.shape[1], hs), offsets


def build_look(walls: raycaster.Walls, surfaces: Sequence[str], faces: Sequence[Face], wall_height: float,
               floor_z: float, floors: Sequence[str], sky: str, floor_cell: float = 0.0,
               assets: dict | None = None) -> doom_render.DoomLook:
    """The renderer's arrays for a map whose wall rows use ``surfaces`` (by ``walls.texture``
    index), row ``i`` textured as ``faces[i]`` places it (a generated map: every row that may
    take surface ``k`` uses the same scales and offsets). The walls stand ``wall_height`` from a
    floor at world height ``floor_z`` (for the t offsets); ``floors``: the floor surfaces (the
    first the default, the others for a world with a floor grid of ``floor_cell`` cells)."""
    assets = load() if assets is None else assets
    faces = list(faces)
    start, end = np.asarray(walls.start, np.float64), np.asarray(walls.end, np.float64)
    if len(faces) != start.shape[0]:
        raise ValueError(f"{len(faces)} faces for {start.shape[0]} wall rows")
    size = assets["surfaces"].shape[1]
    k = size / FULL  # stored texels per original texel
    along_x = np.abs(end[:, 0] - start[:, 0]) > 0
    c0 = np.where(along_x, start[:, 0], start[:, 1])  # the row's start along its s axis (x or y)
    direction = np.sign(np.where(along_x, end[:, 0] - start[:, 0], end[:, 1] - start[:, 1]))
    off_s, scale_s = (np.asarray([getattr(f, a) for f in faces], np.float64) for a in ("offset_s", "scale_s"))
    offset = k * (c0 / scale_s + off_s)
    sign = k * direction / scale_s
    # t: one scale for the look, an offset per surface (where the texture meets the wall's top)
    tex = np.asarray(walls.texture)
    scale_t = {f.scale_t for f in faces}
    if len(scale_t) != 1 or min(scale_t) <= 0:
        raise ValueError(f"the faces need one positive t scale, got {sorted(scale_t)}")
    (scale_t,) = scale_t
    v_scale = k / scale_t
    look_rows = doom_render.texel_rows(wall_height, v_scale)
    top_t = {}
    for i, f in enumerate(faces):
        if f.surface != surfaces[tex[i]]:
            raise ValueError(f"row {i}: face of {f.surface}, texture {surfaces[tex[i]]}")
        t = int(np.round(k * (-(wall_height + floor_z) / scale_t + f.offset_t))) % size
        if top_t.setdefault(tex[i], t) != t:
            raise ValueError(f"surface {f.surface}: rows with different t offsets")
    textures = [np.asarray(surface(n, assets), np.float64) / 255.0 for n in surfaces]
    widths = np.array([t.shape[1] for t in textures])
    prefix = np.concatenate([doom_render._prefix_down(doom_render._box_levels(t.transpose(1, 0, 2), wrap=True),
                                                      look_rows, top_t.get(j, 0)) for j, t in enumerate(textures)],
                            axis=1)
    floor_rgb = np.asarray([surface_mean(n, assets) for n in floors], np.float64)
    sprite_prefix, sprite_size, sprite_offset = _sprites(assets)
    return doom_render.DoomLook(
        wall_prefix=jnp.asarray(prefix.reshape(-1, 3), jnp.float32),
        tex_start=jnp.asarray(np.concatenate([[0], np.cumsum(widths)[:-1]]), jnp.int32),
        tex_width=jnp.asarray(widths, jnp.int32),
        tex_columns=int(widths.sum()),
        wall_offset=jnp.asarray(offset, jnp.float32),
        wall_sign=jnp.asarray(sign, jnp.float32),
        light_rgb=jnp.ones((32, 3), jnp.float32),
        plane_rgb=jnp.asarray(np.broadcast_to(floor_rgb[0], (32, 3)), jnp.float32),
        sprite_prefix=jnp.asarray(sprite_prefix, jnp.float32),
        sprite_size=sprite_size,
        sprite_offset=sprite_offset,
        wall_height=float(wall_height),
        v_scale=float(v_scale),
        sky_rgb=np.asarray(sky_table(sky, assets)),
        floor_rgb=jnp.asarray(floor_rgb, jnp.float32) if floor_cell > 0 else None,
        floor_cell=float(floor_cell),
        wall_rgb=np.asarray([surface_mean(n, assets) for n in surfaces]),
    )


def text_level_faces(walls: raycaster.Walls, surfaces: Sequence[str]) -> list[Face]:
    """Faces of a text level's walls (DMLab's generated mazes): the tile of every surface spans
    one 100-unit cell, offsets 0 (``MapBuilderTexture``, text_level_exporter.cc:43-48). Row i
    takes the face of surface ``walls.texture[i]``'s template value; the scales and offsets are
    the same for every surface, so a maze drawing other surfaces on the rows is placed alike."""
    tex = np.asarray(walls.texture)
    return [Face(surfaces[t], 0.0, 0.0, TEXT_LEVEL_SCALE, TEXT_LEVEL_SCALE) for t in tex]


def text_level_look(walls: raycaster.Walls, floor_cell: float = 0.0) -> doom_render.DoomLook:
    """The look of a maze drawn in MISHMASH (explore-goals and its paper variant): its 20 walls
    by index, walls 100 high (one cell: ``ceiling_scale`` 1, text_level_exporter.cc:66-68), its
    20 floors, the sky ``lg_sky_03`` (common/make_map.lua:29); ``floor_cell`` > 0 for a world
    with a floor grid."""
    walls = walls._replace(texture=jnp.zeros_like(walls.texture))  # every surface is placed alike
    return build_look(walls, MISHMASH_WALLS, text_level_faces(walls, MISHMASH_WALLS), wall_height=100.0, floor_z=0.0,
                      floors=MISHMASH_FLOORS, sky="map/lab_games/sky/lg_sky_03", floor_cell=floor_cell)


__all__ = ["build_look", "text_level_look", "text_level_faces", "Face", "load", "surface", "surface_mean", "sky_table",
           "CAMERA", "LIGHT", "EYE_HEIGHT", "LOOKS", "MISHMASH_FLOORS", "MISHMASH_WALLS", "check_look"]
