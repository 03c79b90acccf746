"""MyWayHome as ViZDoom draws it: Freedoom's textures and Doom's light, seen through ViZDoom's
160x120 screen and area-averaged to the agent's 42x42 frame.

The paper's 42x42x3 observations are made from ViZDoom's 160x120 frames; here, as in
``vizdoom_ref.resize42`` that the tests compare against, by area-averaging. (ICM's own code
took a greyscale, bilinear route; the paper's frames are RGB.) Rendering all 19,200 pixels of
that screen and then resizing would cost more than the rest of an environment step many times
over, so this renderer computes the averaged frame directly, exactly where it can:

- Columns: one ray per output column, through its centre. The 3.8 screen columns an output
  column averages show texel columns across a footprint of ``du`` texels (the change of u to
  the neighbouring output column on the same wall); the texture box-filtered across the
  nearest power of two of texels (``_box_levels``, 1 to 64) stands in for them. This is the
  one approximation of the averaging that is not exact: a column that straddles two walls
  shows only the one its centre sees.
- Rows: along one screen column a wall's texels are stretched by depth / focal per screen row.
  The mean over an output row's span of screen rows is the integral of the texture column over
  the wall heights that span sees, read from per-column prefix sums (two lookups per row edge,
  linear in between), so a far wall's fine pattern averages out instead of aliasing. Screen
  rows above the wall show the ceiling, below it the floor: the flat's mean colour, lit by each
  row's distance, weighted by the share of the output row they cover.
- Light (``DoomLight``): ZDoom's software renderer picks one of 32 light tables per wall column
  from the sector's light (192), the wall's orientation ("fake contrast") and its distance, and
  per floor or ceiling row from the row's plane distance; each table darkens the palette
  colours by about 1/32 more than the one before.
- Items are Doom sprites (the green armour for the goal): billboards whose screen columns map
  to sprite columns like a wall's (filtered the same way), drawn over what they hide, with their
  transparent texels as partial coverage after averaging; a nearer wall hides them per column.
- MyWayHome's ViZDoom frames show no weapon (the scenario's player holds none) and no HUD.

Textures, palette and sprite come from Freedoom (``simjax/envs/doom/assets``, converted from the
``freedoom2.wad`` that ViZDoom ships by ``tools/freedoom_assets.py``).

The DMLab worlds are drawn by the same code with a ``DoomLook`` of DeepMind Lab's surfaces
(``simjax.envs.dmlab.look``): its optional fields set walls of another height and texel scale,
a sky in place of the ceiling, floors per cell of a world's floor grid, one sprite per item
look, and light tables of ones (no light). Their defaults are Doom's, which they leave as it was.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import chex
import jax
import jax.numpy as jnp
import numpy as np

from simjax.envs import raycaster

SCREEN_W, SCREEN_H = 160, 120  # ViZDoom's RES_160X120, the resolution ICM's code and the paper used
WALL_HEIGHT = 128.0  # every MyWayHome sector: floor 0, ceiling 128


class DoomCamera(NamedTuple):
    """ViZDoom's screen (4:3, horizontal FOV 90 degrees) and the frame size it is resized to;
    Python numbers (compile-time)."""

    width: int = 42
    height: int = 42
    screen_width: int = SCREEN_W
    screen_height: int = SCREEN_H
    fov_deg: float = 90.0
    eye_height: float = 41.0  # Doom's player view height above the floor
    # Doom's pixels are 1.2 times taller than wide (320x200 on a 4:3 screen); ZDoom keeps that
    # stretch on a 4:3 screen, so heights are projected with focal * 1.2 (vertical FOV 64 deg)
    pixel_aspect: float = 1.2
    horizon: float = 59.5  # the screen row (continuous, from the top) at eye height

    @property
    def focal(self) -> float:
        """Horizontal, in screen pixels."""
        return (self.screen_width / 2.0) / math.tan(math.radians(self.fov_deg) / 2.0)

    @property
    def focal_y(self) -> float:
        return self.focal * self.pixel_aspect


class DoomLight(NamedTuple):
    """ZDoom 2.8's software-renderer light (ViZDoom's engine), for sector light 192.

    A wall column at perpendicular depth ``d`` is drawn with light table (COLORMAP) index
    ``clip(floor(shade - min(max_vis, vis / d)), 0, 31)``: ``shade`` is LIGHT2SHADE of the
    light level, 64 - (level + 12) / 4, with the fake contrast of +16 levels for walls along
    y (constant x, brighter) and -16 for walls along x, so 9 and 17 (13 without contrast);
    ``vis`` is r_WallVisibility for a 160-wide screen with a 90-degree FOV at r_visibility 8
    (83885864 / 65536). Sprites use the same visibility and shade 13. A floor or ceiling row
    uses ``plane_vis * |horizon row - row| / h`` (h: the plane's height from the eye) in place
    of ``vis / d``. Table index k darkens a colour by ``DoomLook.light_rgb[k]``, the ratio of
    the colormapped to the plain palette colours over the map's texels (about 1 - k / 32)."""

    wall_shade_along_x: float = 17.0
    wall_shade_along_y: float = 9.0
    sprite_shade: float = 13.0
    plane_shade: float = 13.0
    vis: float = 1279.9967
    plane_vis: float = 13.33336
    max_vis: float = 24.0


def light_index(shade, vis_term, max_vis: float, xp=jnp):
    """ZDoom's GETPALOOKUP: the light table index (int32) for a visibility term ``vis / d``."""
    return xp.clip(xp.floor(shade - xp.minimum(max_vis, vis_term)), 0, 31).astype(xp.int32)


class DoomLook(NamedTuple):
    """The arrays the renderer reads, built once per map by ``build_look``."""

    wall_prefix: jnp.ndarray  # (LEVELS * columns * 130, 3) per filtered texture column, prefix sums down the wall
    tex_start: jnp.ndarray  # (T,) int32, each texture's first column in wall_prefix's columns
    tex_width: jnp.ndarray  # (T,) int32, texture widths (texture columns wrap around)
    tex_columns: int  # all textures' columns together: the stride of a level in wall_prefix
    wall_offset: jnp.ndarray  # (S,) texture u at the start of each wall row
    wall_sign: jnp.ndarray  # (S,) +1 where u grows along the row, -1 where it runs the other way
    light_rgb: jnp.ndarray  # (32, 3) colour multiplier of each light table index
    plane_rgb: jnp.ndarray  # (32, 3) mean colour of the floor and ceiling flat at each index, 0..1
    sprite_prefix: jnp.ndarray  # (N * LEVELS * Wp * (Hs + 2), 4) the same for the sprites' premultiplied RGBA
    sprite_size: tuple  # (Wp, Hs): padded width, height
    # (leftoffset + padding, topoffset) of the one sprite every item shows (Doom's), or a tuple
    # of N of them: item look k (``raycaster.Sprites.look``) shows sprite k
    sprite_offset: tuple
    # the rest serve other engines' looks (``simjax.envs.dmlab.look``); the defaults are Doom's
    wall_height: float = WALL_HEIGHT  # floor to the top of every wall, world units
    v_scale: float = 1.0  # texel rows per world unit down a wall; wall_prefix has texel_rows(wall_height, v_scale) + 2 rows
    sky_rgb: np.ndarray | None = None  # (181, 3) sky colour at elevations -90..90 degrees, drawn for the ceiling
    floor_rgb: jnp.ndarray | None = None  # (F, 3) colour of each floor of a world with a floor grid
    floor_cell: float = 0.0  # that grid's cell size, world units
    wall_rgb: np.ndarray | None = None  # (T, 3) each texture's mean colour (for maps), 0..1


LEVELS = 7  # box filters of 1, 2, 4, ..., 64 texel columns: a 64-wide texture's whole width
_SPRITE_PAD = 32  # transparent columns either side of the sprite, so wide filters fade its edges


def texel_rows(wall_height: float, v_scale: float) -> int:
    """Texel rows from the top of a wall to the floor (128 for Doom: one a unit)."""
    return math.ceil(wall_height * v_scale - 1e-9)


def _box_levels(columns: np.ndarray, wrap: bool) -> np.ndarray:
    """(LEVELS, W, ...) the texture's columns box-filtered across 1, 2, 4, ... columns (level
    l averages columns c - 2^l/2 ... c + 2^l/2 - 1), wrapping around or not."""
    w = columns.shape[0]
    out = []
    for level in range(LEVELS):
        n = 2**level
        ks = np.arange(n) - n // 2
        idx = np.arange(w)[:, None] + ks[None, :]
        if wrap:
            out.append(columns[idx % w].mean(1))
        else:
            valid = (idx >= 0) & (idx < w)
            taken = columns[np.clip(idx, 0, w - 1)] * valid.reshape(valid.shape + (1,) * (columns.ndim - 1))
            out.append(taken.sum(1) / n)
    return np.stack(out)


def _prefix_down(columns: np.ndarray, rows: int, start: int = 0) -> np.ndarray:
    """(..., rows + 2, C) prefix sums down each column of (..., H, C) texels repeated to ``rows``
    rows from texel row ``start``, plus one repeated last entry so that a lookup at floor(t) + 1
    stays inside."""
    h = columns.shape[-2]
    col = np.take(columns, (np.arange(rows) + start) % h, axis=-2).astype(np.float64)
    zero = np.zeros_like(col[..., :1, :])
    prefix = np.concatenate([zero, np.cumsum(col, axis=-2)], axis=-2)
    return np.concatenate([prefix, prefix[..., -1:, :]], axis=-2)


def build_look(walls: raycaster.Walls, texture_names, offsets_x, reversed_, assets: dict | None = None) -> DoomLook:
    """The renderer's arrays for a map whose wall rows use ``texture_names`` (by index), with
    Doom's texture x-offset and u direction per row (from the map's sidedefs)."""
    from simjax.envs.doom import doom_assets

    assets = doom_assets.load() if assets is None else assets
    textures = [assets[f"wall_{n}"] for n in texture_names]
    widths = np.array([t.shape[1] for t in textures])
    # (LEVELS, columns, 130, 3): every texture's columns side by side, at every filter width
    prefix = np.concatenate([_prefix_down(_box_levels(t.transpose(1, 0, 2) / 255.0, wrap=True), int(WALL_HEIGHT))
                             for t in textures], axis=1)
    start, end = np.asarray(walls.start), np.asarray(walls.end)
    length = np.abs(end - start).sum(1)
    reversed_ = np.asarray(reversed_, bool)
    # Doom's u runs from the linedef's first vertex; a row that runs the other way starts at
    # u = length (+ offset) and counts down
    offset = np.asarray(offsets_x, np.float32) + np.where(reversed_, length, 0.0)
    palette, colormap = assets["playpal"].astype(np.float64), assets["colormap"][:32]
    texels = np.concatenate([assets[f"wall_{n}_index"].ravel() for n in texture_names])
    light_rgb = palette[colormap[:, texels]].sum(1) / np.maximum(palette[texels].sum(0), 1e-9)
    flat = palette[colormap[:, assets["flat_FLAT1_1_index"].ravel()]].mean(1) / 255.0  # (32, 3)
    sprite = assets["sprite_ARM1A0"].astype(np.float64) / 255.0
    alpha = sprite[..., 3:]
    premul = np.concatenate([sprite[..., :3] * alpha, alpha], -1).transpose(1, 0, 2)  # (Ws, Hs, 4)
    premul = np.pad(premul, ((_SPRITE_PAD, _SPRITE_PAD), (0, 0), (0, 0)))
    sprite_prefix = _prefix_down(_box_levels(premul, wrap=False), premul.shape[1])
    return DoomLook(
        wall_prefix=jnp.asarray(prefix.reshape(-1, 3), jnp.float32),
        tex_start=jnp.asarray(np.concatenate([[0], np.cumsum(widths)[:-1]]), jnp.int32),
        tex_width=jnp.asarray(widths, jnp.int32),
        tex_columns=int(widths.sum()),
        wall_offset=jnp.asarray(offset, jnp.float32),
        wall_sign=jnp.asarray(np.where(reversed_, -1.0, 1.0), jnp.float32),
        light_rgb=jnp.asarray(light_rgb, jnp.float32),
        plane_rgb=jnp.asarray(flat, jnp.float32),
        sprite_prefix=jnp.asarray(sprite_prefix.reshape(-1, 4), jnp.float32),
        sprite_size=(premul.shape[0], premul.shape[1]),
        sprite_offset=(int(assets["sprite_ARM1A0_offset"][0]) + _SPRITE_PAD, int(assets["sprite_ARM1A0_offset"][1])),
    )


def area_matrix(n_in: int, n_out: int) -> np.ndarray:
    """(n_out, n_in) weights of an area-averaging resize: output pixel j averages the input span
    [j n_in / n_out, (j + 1) n_in / n_out), partial pixels weighted by their overlap."""
    edges = np.arange(n_out + 1) * n_in / n_out
    lo, hi = edges[:-1, None], edges[1:, None]
    px = np.arange(n_in)[None, :]
    overlap = np.clip(np.minimum(hi, px + 1) - np.maximum(lo, px), 0.0, None)
    return overlap / overlap.sum(1, keepdims=True)


def _plane_rows(camera: DoomCamera, light: DoomLight, plane_rgb,
                wall_height: float = WALL_HEIGHT) -> tuple[np.ndarray, np.ndarray]:
    """(height, 3) colours of the ceiling and the floor as each output row shows them: the
    flat's mean colour at each screen row's light index, averaged over the output row's span
    of screen rows (a constant of the camera)."""
    rows = np.arange(camera.screen_height)
    centre = rows + 0.5 - camera.horizon  # the screen row's centre, below the horizon > 0
    # ZDoom lights a plane row by its whole-row distance from the horizon row
    away = np.abs(np.floor(camera.horizon + 0.5) - rows)
    ry = area_matrix(camera.screen_height, camera.height)
    out = []
    for h, side in ((wall_height - camera.eye_height, centre < 0), (camera.eye_height, centre > 0)):
        k = light_index(light.plane_shade, light.plane_vis * away / h, light.max_vis, xp=np)
        w = ry * side[None, :]
        out.append((w @ np.asarray(plane_rgb)[k]) / np.maximum(w.sum(1, keepdims=True), 1e-9))
    return out[0], out[1]


def _sky_rows(camera: DoomCamera, sky_rgb) -> np.ndarray:
    """(height, 3) the sky each output row shows: per screen row the colour of ``sky_rgb`` (one
    per degree of elevation, -90..90) at the elevation of the row's centre, linearly
    interpolated, averaged over the output row's span of screen rows (a constant of the camera;
    the sky is at infinity and the same round the horizon)."""
    rows = np.arange(camera.screen_height)
    elevation = np.degrees(np.arctan2(camera.horizon - (rows + 0.5), camera.focal_y))
    table = np.asarray(sky_rgb, np.float64)
    grid = np.arange(-90.0, 91.0)
    per_row = np.stack([np.interp(elevation, grid, table[:, c]) for c in range(3)], -1)
    return area_matrix(camera.screen_height, camera.height) @ per_row


def _floor_cells(floor, floor_rgb, cell: float, pos, rays, eye, camera: DoomCamera):
    """(W, R, 3) the floor colour each output pixel shows where the world has a floor grid
    (``floor`` (ny, nx) int: cell (iy, ix) covers x in [ix, ix + 1) * cell, y in [iy, iy + 1) *
    cell): the colour of the cell under the point the pixel's centre sees on the floor."""
    fy, dy = camera.focal_y, camera.screen_height / camera.height
    below = jnp.asarray((np.arange(camera.height) + 0.5) * dy - camera.horizon, jnp.float32)  # (R,)
    dist = eye * fy / jnp.maximum(below, 1e-3)  # perpendicular distance of the floor point
    point = pos[None, None, :] + dist[None, :, None] * rays[:, None, :]  # (W, R, 2)
    ny, nx = floor.shape
    ix = jnp.clip(jnp.floor(point[..., 0] / cell).astype(jnp.int32), 0, nx - 1)
    iy = jnp.clip(jnp.floor(point[..., 1] / cell).astype(jnp.int32), 0, ny - 1)
    return floor_rgb[floor[iy, ix]]


def _row_edges(camera: DoomCamera) -> np.ndarray:
    """(height + 1,) output row edges in screen rows from the horizon (down positive)."""
    return np.arange(camera.height + 1) * camera.screen_height / camera.height - camera.horizon


def _lerp_prefix(prefix, base, t, limit, rows=None):
    """Prefix sums read at fractional positions ``t`` (clipped to [0, limit]): exact integrals of
    piecewise-constant texels. ``base`` indexes each column's first entry in ``prefix``, which
    holds ``rows`` texels (default ``limit``) before its two extra entries."""
    t = jnp.clip(t, 0.0, limit)
    i = jnp.minimum(jnp.floor(t), (limit if rows is None else rows) - 1).astype(jnp.int32)
    frac = (t - i)[..., None]
    # the barrier keeps XLA from fusing the index arithmetic into the gathers, where it is
    # recomputed per gathered element (1.6x slower measured)
    row = jax.lax.optimization_barrier(base + i)
    lo = jnp.take(prefix, row, axis=0, mode="clip")
    hi = jnp.take(prefix, row + 1, axis=0, mode="clip")
    return lo + (hi - lo) * frac


def _level(footprint):
    """The box-filter level whose width (1, 2, 4, ... texels) is nearest a pixel's footprint."""
    return jnp.clip(jnp.round(jnp.log2(jnp.maximum(footprint, 1.0))), 0, LEVELS - 1).astype(jnp.int32)


def render(
    walls: raycaster.Walls,
    pos: jnp.ndarray,
    heading: jnp.ndarray,
    sprites: raycaster.Sprites,
    look: DoomLook,
    camera: DoomCamera = DoomCamera(),
    light: DoomLight = DoomLight(),
    eye_height=None,
    floor=None,
) -> jnp.ndarray:
    """The 42x42 RGB uint8 frame of ViZDoom's 160x120 screen at (pos, heading), area-averaged.
    ``eye_height`` (traced, optional) overrides the camera's, e.g. for Doom's view bob.
    ``floor`` (optional, a world's floor grid, for a look with ``floor_rgb``): floor pixels
    take the colour of the grid cell they see, instead of one colour per row. A look with
    ``sky_rgb`` draws that sky where Doom draws the ceiling.

    One ray per output column, through its centre. The screen columns an output column
    averages show texel columns across a footprint of ``du`` texels (the change of u to the
    neighbouring column on the same wall); the texture box-filtered across the nearest power of
    two stands in for them. Down the column the average is exact, from prefix sums."""
    chex.assert_shape(pos, (2,))
    chex.assert_shape(heading, ())
    f, fy, dy = camera.focal, camera.focal_y, camera.screen_height / camera.height
    per_column = camera.screen_width / camera.width  # screen columns per output column
    eye = jnp.float32(camera.eye_height if eye_height is None else eye_height)
    rays = raycaster.ray_directions(heading, raycaster.Camera(width=camera.width, fov_deg=camera.fov_deg))
    depth, wall, u = raycaster.cast_rays_along(walls, pos, rays)
    depth = jnp.maximum(depth, 1.0)

    # walls: per column, the filtered texture column and its light. u_doom in texels:
    # wall_sign is +-1 for Doom's one texel a unit, +-texels a unit for other looks
    height, v_scale = look.wall_height, look.v_scale
    texels = texel_rows(height, v_scale)
    tex = walls.texture[wall]
    sign = look.wall_sign[wall]
    u_doom = look.wall_offset[wall] + sign * u
    tu = jnp.mod(jnp.floor(u_doom).astype(jnp.int32), look.tex_width[tex])
    level = _level(raycaster._footprint_along(u, wall, depth * per_column / f) * jnp.abs(sign))
    rows = texels + 2
    base = (level * look.tex_columns + look.tex_start[tex] + tu) * rows
    e = walls.end[wall] - walls.start[wall]
    along_x = jnp.abs(e[:, 0]) > jnp.abs(e[:, 1])
    shade = jnp.where(along_x, light.wall_shade_along_x, light.wall_shade_along_y)
    lit = look.light_rgb[light_index(shade, light.vis / depth, light.max_vis)]  # (W, 3)

    # per column and output row edge: the wall height seen, as a texel row from the top
    y_edge = jnp.asarray(_row_edges(camera), jnp.float32)  # (R + 1,)
    z = eye - y_edge[None, :] * (depth / fy)[:, None]  # (W, R + 1)
    cum = _lerp_prefix(look.wall_prefix, base[:, None], (height - z) * v_scale, height * v_scale,
                       texels)  # (W, R + 1, 3)
    wall_rgb = (cum[:, 1:] - cum[:, :-1]) * (lit * (fy / depth / dy / v_scale)[:, None])[:, None, :]  # (W, R, 3)
    y_top = (eye - height) * fy / depth  # screen rows above this show the ceiling
    y_bot = eye * fy / depth  # below this, the floor
    lo, hi = y_edge[None, :-1], y_edge[None, 1:]
    ceil_share = jnp.clip(jnp.minimum(hi, y_top[:, None]) - lo, 0.0, dy) / dy  # (W, R)
    floor_share = jnp.clip(hi - jnp.maximum(lo, y_bot[:, None]), 0.0, dy) / dy
    ceil_rgb, floor_rgb = (jnp.asarray(x, jnp.float32) for x in _plane_rows(camera, light, look.plane_rgb, height))
    if look.sky_rgb is not None:
        ceil_rgb = jnp.asarray(_sky_rows(camera, look.sky_rgb), jnp.float32)
    if floor is not None and look.floor_rgb is not None:
        floor_px = _floor_cells(floor, look.floor_rgb, look.floor_cell, pos, rays, eye, camera)  # (W, R, 3)
        rgb = wall_rgb + ceil_share[..., None] * ceil_rgb[None] + floor_share[..., None] * floor_px
    else:
        rgb = wall_rgb + ceil_share[..., None] * ceil_rgb[None] + floor_share[..., None] * floor_rgb[None]

    rgb = _draw_sprites(rgb, depth, pos, heading, eye, sprites, look, camera, light)
    return jnp.round(jnp.clip(rgb.transpose(1, 0, 2), 0.0, 1.0) * 255.0).astype(jnp.uint8)


def _draw_sprites(rgb, depth, pos, heading, eye, sprites: raycaster.Sprites, look: DoomLook, camera, light):
    """Composite every visible sprite over the (W, R, 3) columns, farthest first, where it is
    nearer than the column's wall. A sprite's screen column x shows its texel column
    ``leftoffset + (x - centre) * depth / focal`` (filtered across the output column's
    footprint); its top row stands ``topoffset`` above the floor (Doom's placement of a thing's
    sprite)."""
    f, fy, dy = camera.focal, camera.focal_y, camera.screen_height / camera.height
    per_column = camera.screen_width / camera.width
    wp, hs = look.sprite_size
    several = isinstance(look.sprite_offset[0], (tuple, list))
    if several:  # item look k shows sprite k
        offsets = np.asarray(look.sprite_offset, np.float32)
        sid = jnp.clip(sprites.look, 0, offsets.shape[0] - 1)  # (K,)
        left, top = jnp.asarray(offsets[:, 0])[sid][:, None], jnp.asarray(offsets[:, 1])[sid][:, None]
    else:
        left, top = look.sprite_offset
    forward = jnp.stack([jnp.cos(heading), jnp.sin(heading)])
    right = jnp.stack([jnp.sin(heading), -jnp.cos(heading)])
    rel = sprites.pos - pos[None, :]  # (K, 2)
    s_depth = rel @ forward
    s_near = jnp.maximum(s_depth, 1.0)
    centre = camera.screen_width / 2.0 + f * (rel @ right) / s_near  # (K,) screen x
    x = jnp.asarray((np.arange(camera.width) + 0.5) * per_column, jnp.float32)
    col = jnp.floor(left + (x[None, :] - centre[:, None]) * (s_near / f)[:, None]).astype(jnp.int32)  # (K, W)
    shown = (sprites.visible[:, None] & (s_depth[:, None] > 1.0) & (col >= 0) & (col < wp)
             & (s_depth[:, None] < depth[None, :]))
    level = _level(s_near * per_column / f)  # (K,)
    y_edge = jnp.asarray(_row_edges(camera), jnp.float32)
    z = eye - y_edge[None, :] * (s_near / fy)[:, None]  # (K, R + 1)
    if several:
        base = ((sid[:, None] * LEVELS + level[:, None]) * wp + jnp.clip(col, 0, wp - 1)) * (hs + 2)  # (K, W)
    else:
        base = (level[:, None] * wp + jnp.clip(col, 0, wp - 1)) * (hs + 2)  # (K, W)
    cum = _lerp_prefix(look.sprite_prefix, base[:, :, None], (top - z)[:, None, :], float(hs))  # (K, W, R + 1, 4)
    lit = look.light_rgb[light_index(light.sprite_shade, light.vis / s_near, light.max_vis)]  # (K, 3)
    cover = (cum[:, :, 1:] - cum[:, :, :-1]) * (fy / s_near / dy)[:, None, None, None]  # (K, W, R, 4)
    cover = jnp.where(shown[:, :, None, None], cover, 0.0)
    order = jnp.argsort(-s_depth)
    for i in range(sprites.pos.shape[0]):
        k = order[i]
        c = cover[k]
        rgb = c[..., :3] * lit[k] + (1.0 - c[..., 3:]) * rgb
    return rgb
