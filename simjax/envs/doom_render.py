"""MyWayHome as ViZDoom draws it: Freedoom's textures and Doom's light, seen through ViZDoom's
160x120 screen and area-averaged to the agent's 42x42 frame.

The paper's 42x42x3 observations are ViZDoom's 160x120 frames resized (ICM's code: OpenCV's
area interpolation). Rendering all 19,200 pixels of that screen and then resizing would cost
more than the rest of an environment step many times over, so this renderer computes the
resized frame directly, exactly where it can:

- Columns: one ray per screen column of the 160 (Doom draws each screen column from one texel
  column of the wall it hits, ``u`` point-sampled like Doom); an output column is the area
  average of the 3.8 screen columns it covers (fixed weights, ``_area_weights``).
- Rows: along one screen column a wall's texels are stretched by depth / focal per screen row.
  The mean over an output row's span of screen rows is the integral of the texture column over
  the wall heights that span sees, read from per-column prefix sums (two lookups per row edge,
  linear in between), so a far wall's fine pattern averages out instead of aliasing. Screen
  rows above the wall show the ceiling, below it the floor: the flat's mean colour, lit by each
  row's distance, weighted by the share of the output row they cover.
- Light (``DoomLight``): ZDoom's software renderer picks one of 32 light levels per wall column
  from the sector's light (192), the wall's orientation ("fake contrast") and its distance, and
  per floor or ceiling row from the row's plane distance; each level darkens the palette colour
  by 1/32.
- Items are Doom sprites (the green armour for the goal): billboards whose screen columns map
  to sprite columns like a wall's, drawn over what they hide, with their transparent texels as
  partial coverage after averaging; a nearer wall hides them per screen column.
- MyWayHome's ViZDoom frames show no weapon (the scenario's player holds none) and no HUD.

Textures, palette and sprite come from Freedoom (``simjax/envs/assets``, converted from the
``freedoom2.wad`` that ViZDoom ships by ``tools/freedoom_assets.py``).
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
    """ZDoom's light as a function of distance: a column or row at distance ``d`` gets light
    level index ``clip(shade - vis / d, 0, 31)`` and its colour is multiplied by
    ``1 - index / 32``. ``shade`` follows from the sector light (192) and, for walls, the
    orientation; ``vis`` from the screen's size and r_visibility. Values: see the fit in
    ``experiments/vizdoom_light.py``."""

    wall_shade_x: float = 13.0  # walls running along x (horizontal on the map)
    wall_shade_y: float = 13.0  # walls running along y
    wall_vis: float = 1000.0
    plane_shade: float = 13.0
    plane_vis: float = 1000.0
    sprite_shade: float = 13.0
    max_index: float = 31.0


def light_factor(d, shade, vis, max_index=31.0, xp=jnp):
    """Colour multiplier for distance ``d`` (see ``DoomLight``); ``xp=np`` for constants."""
    index = xp.clip(shade - vis / xp.maximum(d, 1e-3), 0.0, max_index)
    return 1.0 - index / 32.0


class DoomLook(NamedTuple):
    """The arrays the renderer reads, built once per map by ``build_look``."""

    wall_prefix: jnp.ndarray  # (T * Wmax * 130, 3) per texture column, prefix sums down the wall
    tex_width: jnp.ndarray  # (T,) int32, texture widths (texture columns wrap around)
    tex_wmax: int  # Wmax: the stride of a texture in wall_prefix
    wall_offset: jnp.ndarray  # (S,) texture u at the start of each wall row
    wall_sign: jnp.ndarray  # (S,) +1 where u grows along the row, -1 where it runs the other way
    plane_rgb: jnp.ndarray  # (2, 3) mean colour of the ceiling and floor flat, 0..1
    sprite_prefix: jnp.ndarray  # (Ws, Hs + 1, 4) premultiplied RGBA prefix sums down each column
    sprite_size: tuple  # (Ws, Hs)
    sprite_offset: tuple  # (leftoffset, topoffset)


def _column_prefix(rgb: np.ndarray) -> np.ndarray:
    """(W, 130, 3) prefix sums of each texture column over the 128 texel rows a wall shows
    (the texture repeats downward if shorter), plus one repeated last entry so that a lookup at
    floor(t) + 1 never leaves the array."""
    h = rgb.shape[0]
    rows = np.arange(int(WALL_HEIGHT)) % h
    col = rgb[rows].transpose(1, 0, 2).astype(np.float64) / 255.0  # (W, 128, 3)
    prefix = np.concatenate([np.zeros_like(col[:, :1]), np.cumsum(col, axis=1)], axis=1)
    return np.concatenate([prefix, prefix[:, -1:]], axis=1)


def build_look(walls: raycaster.Walls, texture_names, offsets_x, reversed_, assets: dict | None = None) -> DoomLook:
    """The renderer's arrays for a map whose wall rows use ``texture_names`` (by index), with
    Doom's texture x-offset and u direction per row (from the map's sidedefs)."""
    from simjax.envs import doom_assets

    assets = doom_assets.load() if assets is None else assets
    textures = [assets[f"wall_{n}"] for n in texture_names]
    wmax = max(t.shape[1] for t in textures)
    prefix = np.zeros((len(textures), wmax, int(WALL_HEIGHT) + 2, 3), np.float32)
    for i, t in enumerate(textures):
        prefix[i, : t.shape[1]] = _column_prefix(t)
    start, end = np.asarray(walls.start), np.asarray(walls.end)
    length = np.abs(end - start).sum(1)
    reversed_ = np.asarray(reversed_, bool)
    # Doom's u runs from the linedef's first vertex; a row that runs the other way starts at
    # u = length (+ offset) and counts down
    offset = np.asarray(offsets_x, np.float32) + np.where(reversed_, length, 0.0)
    flat = assets["flat_FLAT1_1"].reshape(-1, 3).mean(0) / 255.0
    sprite = assets["sprite_ARM1A0"].astype(np.float64) / 255.0
    alpha = sprite[..., 3:]
    premul = np.concatenate([sprite[..., :3] * alpha, alpha], -1).transpose(1, 0, 2)  # (Ws, Hs, 4)
    sprite_prefix = np.concatenate([np.zeros_like(premul[:, :1]), np.cumsum(premul, axis=1)], axis=1)
    return DoomLook(
        wall_prefix=jnp.asarray(prefix.reshape(-1, 3)),
        tex_width=jnp.asarray([t.shape[1] for t in textures], jnp.int32),
        tex_wmax=wmax,
        wall_offset=jnp.asarray(offset, jnp.float32),
        wall_sign=jnp.asarray(np.where(reversed_, -1.0, 1.0), jnp.float32),
        plane_rgb=jnp.asarray(np.stack([flat, flat]), jnp.float32),
        sprite_prefix=jnp.asarray(sprite_prefix, jnp.float32),
        sprite_size=(sprite.shape[1], sprite.shape[0]),
        sprite_offset=tuple(int(v) for v in assets["sprite_ARM1A0_offset"]),
    )


def _area_matrix(n_in: int, n_out: int) -> np.ndarray:
    """(n_out, n_in) weights of an area-averaging resize: output pixel j averages the input span
    [j n_in / n_out, (j + 1) n_in / n_out), partial pixels weighted by their overlap."""
    edges = np.arange(n_out + 1) * n_in / n_out
    lo, hi = edges[:-1, None], edges[1:, None]
    px = np.arange(n_in)[None, :]
    overlap = np.clip(np.minimum(hi, px + 1) - np.maximum(lo, px), 0.0, None)
    return overlap / overlap.sum(1, keepdims=True)


def _area_band(n_in: int, n_out: int):
    """The area matrix as (n_out, k) indices and weights of its nonzero band."""
    m = _area_matrix(n_in, n_out)
    k = int((m > 0).sum(1).max())
    idx = np.stack([np.sort(np.argsort(-row)[:k]) for row in m])
    return idx.astype(np.int32), np.take_along_axis(m, idx, 1).astype(np.float32)


def _plane_rows(camera: DoomCamera, light: DoomLight, plane_rgb) -> tuple[np.ndarray, np.ndarray]:
    """(height, 3) mean colours of the ceiling and floor as each output row shows them: the
    mean over the row's span of screen rows of the flat's colour lit at that screen row's plane
    distance (a constant of the camera; rows the plane does not reach get weight where used)."""
    sub = 16  # samples per screen row
    y = (np.arange(camera.screen_height * sub) + 0.5) / sub - camera.horizon
    ceil_d = (WALL_HEIGHT - camera.eye_height) * camera.focal_y / np.maximum(-y, 1e-3)
    floor_d = camera.eye_height * camera.focal_y / np.maximum(y, 1e-3)
    lf = lambda d: light_factor(d, light.plane_shade, light.plane_vis, light.max_index, xp=np)
    ry = _area_matrix(camera.screen_height * sub, camera.height)
    ceil_w = ry * (y < 0)[None, :]
    floor_w = ry * (y > 0)[None, :]
    ceil = (ceil_w @ lf(ceil_d)) / np.maximum(ceil_w.sum(1), 1e-9)
    floor = (floor_w @ lf(floor_d)) / np.maximum(floor_w.sum(1), 1e-9)
    plane_rgb = np.asarray(plane_rgb)
    return ceil[:, None] * plane_rgb[0][None], floor[:, None] * plane_rgb[1][None]


def _screen_rays(heading, camera: DoomCamera):
    """(screen_width, 2) ray directions, one per screen column, scaled so that the ray
    parameter of a hit is the perpendicular depth."""
    forward = jnp.stack([jnp.cos(heading), jnp.sin(heading)])
    right = jnp.stack([jnp.sin(heading), -jnp.cos(heading)])
    x = (np.arange(camera.screen_width) + 0.5 - camera.screen_width / 2.0) / camera.focal
    return forward[None, :] + jnp.asarray(x, jnp.float32)[:, None] * right[None, :]


def _row_edges(camera: DoomCamera) -> np.ndarray:
    """(height + 1,) output row edges in screen rows from the horizon (down positive)."""
    return np.arange(camera.height + 1) * camera.screen_height / camera.height - camera.horizon


def _lerp_prefix(prefix, base, t, limit):
    """Prefix sums read at fractional positions ``t`` (clipped to [0, limit]): exact integrals of
    piecewise-constant texels. ``base`` indexes each column's first entry in ``prefix``."""
    t = jnp.clip(t, 0.0, limit)
    i = jnp.minimum(jnp.floor(t), limit - 1).astype(jnp.int32)
    frac = (t - i)[..., None]
    lo = jnp.take(prefix, base + i, axis=0)
    hi = jnp.take(prefix, base + i + 1, axis=0)
    return lo + (hi - lo) * frac


def render(
    walls: raycaster.Walls,
    pos: jnp.ndarray,
    heading: jnp.ndarray,
    sprites: raycaster.Sprites,
    look: DoomLook,
    camera: DoomCamera = DoomCamera(),
    light: DoomLight = DoomLight(),
    eye_height=None,
) -> jnp.ndarray:
    """The 42x42 RGB uint8 frame of ViZDoom's 160x120 screen at (pos, heading), area-averaged.
    ``eye_height`` (traced, optional) overrides the camera's, e.g. for Doom's view bob."""
    chex.assert_shape(pos, (2,))
    chex.assert_shape(heading, ())
    f, fy, dy = camera.focal, camera.focal_y, camera.screen_height / camera.height
    eye = jnp.float32(camera.eye_height if eye_height is None else eye_height)
    d = _screen_rays(heading, camera)
    depth, wall, u = raycaster.cast_rays_along(walls, pos, d)
    depth = jnp.maximum(depth, 1.0)

    # walls: per screen column, the texture column and its light
    tex = walls.texture[wall]
    u_doom = look.wall_offset[wall] + look.wall_sign[wall] * u
    tu = jnp.mod(jnp.floor(u_doom).astype(jnp.int32), look.tex_width[tex])
    base = (tex * look.tex_wmax + tu) * (int(WALL_HEIGHT) + 2)
    e = walls.end[wall] - walls.start[wall]
    along_x = jnp.abs(e[:, 0]) > jnp.abs(e[:, 1])
    shade = jnp.where(along_x, light.wall_shade_x, light.wall_shade_y)
    lit = light_factor(depth, shade, light.wall_vis, light.max_index)  # (C,)

    # per screen column and output row edge: the wall height seen, as a texel row from the top
    y_edge = jnp.asarray(_row_edges(camera), jnp.float32)  # (R + 1,)
    z = eye - y_edge[None, :] * (depth / fy)[:, None]  # (C, R + 1)
    cum = _lerp_prefix(look.wall_prefix, base[:, None], WALL_HEIGHT - z, WALL_HEIGHT)  # (C, R + 1, 3)
    wall_rgb = (cum[:, 1:] - cum[:, :-1]) * (lit * fy / depth / dy)[:, None, None]  # (C, R, 3)
    y_top = (eye - WALL_HEIGHT) * fy / depth  # screen rows above this show the ceiling
    y_bot = eye * fy / depth  # below this, the floor
    lo, hi = y_edge[None, :-1], y_edge[None, 1:]
    ceil_share = jnp.clip(jnp.minimum(hi, y_top[:, None]) - lo, 0.0, dy) / dy  # (C, R)
    floor_share = jnp.clip(hi - jnp.maximum(lo, y_bot[:, None]), 0.0, dy) / dy
    ceil_rgb, floor_rgb = (jnp.asarray(x, jnp.float32) for x in _plane_rows(camera, light, look.plane_rgb))
    rgb = wall_rgb + ceil_share[..., None] * ceil_rgb[None] + floor_share[..., None] * floor_rgb[None]

    rgb = _draw_sprites(rgb, depth, d, pos, heading, eye, sprites, look, camera, light)

    # output columns: the area average of the screen columns each covers
    idx, w = (jnp.asarray(a) for a in _area_band(camera.screen_width, camera.width))
    out = jnp.einsum("jk,jkrc->rjc", w, rgb[idx])  # (R, J, 3)
    return jnp.round(jnp.clip(out, 0.0, 1.0) * 255.0).astype(jnp.uint8)


def _draw_sprites(rgb, depth, rays, pos, heading, eye, sprites: raycaster.Sprites, look: DoomLook, camera, light):
    """Composite every visible sprite over the (C, R, 3) columns, farthest first, where it is
    nearer than the column's wall. A sprite's screen column x shows its texel column
    ``leftoffset + (x - centre) * depth / focal``; its top row stands ``topoffset`` above the
    floor (Doom's placement of a thing's sprite)."""
    f, fy, dy = camera.focal, camera.focal_y, camera.screen_height / camera.height
    ws, hs = look.sprite_size
    left, top = look.sprite_offset
    forward = jnp.stack([jnp.cos(heading), jnp.sin(heading)])
    right = jnp.stack([jnp.sin(heading), -jnp.cos(heading)])
    rel = sprites.pos - pos[None, :]  # (K, 2)
    s_depth = rel @ forward
    s_near = jnp.maximum(s_depth, 1.0)
    centre = camera.screen_width / 2.0 + f * (rel @ right) / s_near  # (K,) screen x
    x = jnp.asarray(np.arange(camera.screen_width) + 0.5, jnp.float32)
    col = jnp.floor(left + (x[None, :] - centre[:, None]) * (s_near / f)[:, None]).astype(jnp.int32)  # (K, C)
    shown = (sprites.visible[:, None] & (s_depth[:, None] > 1.0) & (col >= 0) & (col < ws)
             & (s_depth[:, None] < depth[None, :]))
    y_edge = jnp.asarray(_row_edges(camera), jnp.float32)
    z = eye - y_edge[None, :] * (s_near / fy)[:, None]  # (K, R + 1)
    base = jnp.clip(col, 0, ws - 1) * (hs + 1)  # (K, C)
    prefix = look.sprite_prefix.reshape(-1, 4)
    cum = _lerp_prefix(prefix, base[:, :, None], (top - z)[:, None, :], float(hs))  # (K, C, R + 1, 4)
    lit = light_factor(s_near, light.sprite_shade, light.wall_vis, light.max_index)  # (K,)
    cover = (cum[:, :, 1:] - cum[:, :, :-1]) * (fy / s_near / dy)[:, None, None, None]  # (K, C, R, 4)
    cover = jnp.where(shown[:, :, None, None], cover, 0.0)
    order = jnp.argsort(-s_depth)
    for i in range(sprites.pos.shape[0]):
        k = order[i]
        c = cover[k]
        rgb = c[..., :3] * lit[k] + (1.0 - c[..., 3:]) * rgb
    return rgb
