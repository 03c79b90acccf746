"""The pieces of the ViZDoom-look renderer that the comparison with ViZDoom cannot isolate."""

import math

import chex
import jax
import jax.numpy as jnp
import numpy as np

from simjax.envs import make
from simjax.envs.doom import doom_render


def test_zdoom_light_indices():
    light = doom_render.DoomLight()
    idx = lambda shade, d: int(doom_render.light_index(shade, light.vis / d, light.max_vis))
    # walls along y (constant x) are 16 light levels brighter than walls along x
    assert idx(light.wall_shade_along_y, 100.0) == 0 and idx(light.wall_shade_along_x, 100.0) == 4
    assert idx(light.wall_shade_along_y, 1000.0) == 7 and idx(light.wall_shade_along_x, 1000.0) == 15
    assert idx(light.wall_shade_along_x, 1e6) == 16  # the far limit: LIGHT2SHADE(176) = 17, floored
    assert idx(light.wall_shade_along_x, 1.0) == 0  # max_vis caps the brightening, index clips at 0
    look = make("maze-dense").look
    factors = np.asarray(look.light_rgb)
    chex.assert_shape(factors, (32, 3))
    np.testing.assert_allclose(factors[0], 1.0)
    assert np.all(np.diff(factors.mean(1)) < 0)  # each table darker than the one before
    np.testing.assert_allclose(factors[16].mean(), 0.5, atol=0.03)  # about 1 - k / 32


def test_box_levels_and_prefix_sums_are_exact_averages():
    rng = np.random.default_rng(0)
    tex = rng.random((8, 5, 3))  # 8 columns of 5 texels
    levels = doom_render._box_levels(tex, wrap=True)
    np.testing.assert_allclose(levels[0], tex)
    np.testing.assert_allclose(levels[3], np.broadcast_to(tex.mean(0), tex.shape))  # 8 columns: the mean
    np.testing.assert_allclose(levels[1][3], (tex[2] + tex[3]) / 2)
    prefix = doom_render._prefix_down(tex, 10)  # the 5 texels repeat down 10 rows
    flat = jnp.asarray(prefix.reshape(-1, 3), jnp.float32)
    rows = prefix.shape[1]
    # the integral from row 1.5 to row 7.25 of column 2, read back from two lookups
    a, b = doom_render._lerp_prefix(flat, jnp.int32(2 * rows), jnp.float32([1.5, 7.25]), 10.0)
    col = np.concatenate([tex[2], tex[2]])
    want = 0.5 * col[1] + col[2:7].sum(0) + 0.25 * col[7]
    np.testing.assert_allclose(np.asarray(b - a), want, rtol=1e-5)


def test_area_matrix_averages():
    m = doom_render.area_matrix(160, 42)
    np.testing.assert_allclose(m.sum(1), 1.0)
    assert (m > 0).sum(1).max() <= 5  # 3.8 screen columns per output column
    np.testing.assert_allclose(m.sum(0) * 160 / 42, 1.0)  # every screen column counts once


def _silver_box():
    """A 1000 x 1000 room of SILVER2 walls (x in [0, 1000], y in [-500, 500]) with its one item
    hidden: (layout, look, sprites)."""
    from simjax.envs.doom import mywayhome_map
    from simjax.envs.maze import Layout, goal_item

    silver = mywayhome_map.TEXTURE_NAMES.index("SILVER2")
    rows = [(0, -500, 1000, -500, silver), (1000, -500, 1000, 500, silver),
            (1000, 500, 0, 500, silver), (0, 500, 0, -500, silver)]
    layout = Layout.build(rows, [goal_item((-50.0, 0.0))], [(100.0, 0.0)])
    look = doom_render.build_look(layout.walls, mywayhome_map.TEXTURE_NAMES, np.zeros(4), np.zeros(4, bool))
    hidden = doom_render.raycaster.Sprites(layout.items.pos, layout.items.look, jnp.zeros((1,), bool))
    return layout, look, hidden


def test_a_far_wall_shows_its_texture_averaged_and_does_not_flicker():
    # a 1000x1000 room of SILVER2 (a 64-wide texture of fine panels); the far wall, 900 units
    # ahead, covers about 3 texels a screen column: its pixels must be the texture's average
    # under its light (index 7 for a wall along y at 900: floor(9 - 1280 / 900)), and a step of
    # 2 units sideways must barely change them (point sampling flickers there)
    from simjax.envs.doom import doom_assets

    layout, look, hidden = _silver_box()
    frame = jax.jit(lambda y: doom_render.render(layout.walls, jnp.stack([jnp.float32(100.0), y]), jnp.float32(0.0),
                                                 hidden, look))
    a, b = np.asarray(frame(jnp.float32(0.0)), float), np.asarray(frame(jnp.float32(2.0)), float)
    band = a[18:22, 8:34]  # rows and columns that see only the far wall
    texture = doom_assets.load()["wall_SILVER2"].reshape(-1, 3).mean(0)
    want = texture * np.asarray(look.light_rgb)[7]
    np.testing.assert_allclose(band.reshape(-1, 3).mean(0), want, rtol=0.08)
    assert np.abs(a[18:22, 8:34] - b[18:22, 8:34]).mean() < 2.0


def test_eye_height_sets_the_row_where_the_floor_begins():
    """Facing a wall 100 units away, the floor shows below screen row horizon + eye * focal_y /
    100, so a higher eye pushes it down: every output row wholly below that is the floor's colour."""
    layout, look, hidden = _silver_box()
    camera = doom_render.DoomCamera()
    frame = jax.jit(lambda eye: doom_render.render(layout.walls, jnp.array([900.0, 0.0]), jnp.float32(0.0), hidden,
                                                   look, eye_height=eye))
    floor = np.round(doom_render._plane_rows(camera, doom_render.DoomLight(), look.plane_rgb)[1] * 255.0)
    first = {}
    for eye in (33.0, 41.0, 49.0):
        picture = np.asarray(frame(jnp.float32(eye)), float)
        chex.assert_shape(picture, (camera.height, camera.width, 3))
        is_floor = np.all(np.abs(picture - floor[:, None, :]) <= 1.0, axis=(1, 2))
        want = math.ceil((camera.horizon + eye * camera.focal_y / 100.0) / (camera.screen_height / camera.height))
        np.testing.assert_array_equal(is_floor, np.arange(camera.height) >= want)
        first[eye] = want
    assert first[33.0] < first[41.0] < first[49.0]
