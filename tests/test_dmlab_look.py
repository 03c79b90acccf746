"""The DMLab worlds drawn as DeepMind Lab draws them (``simjax.envs.dmlab.look``, its asset made
by ``tools/dmlab_assets.py``), and the ``*-doom-motion`` tasks still drawn as before."""

import importlib.util
import math
import os
import re

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from simjax.envs import make, raycaster
from simjax.envs.dmlab import look as dmlab_look
from simjax.envs.dmlab import melon
from simjax.envs.dmlab.dmlab_maze import DMLabMazeGenerator
from simjax.envs.doom import doom_render

TOOL = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tools", "dmlab_assets.py")


def _tool():
    """tools/dmlab_assets.py, loaded from its file (numpy only at import)."""
    spec = importlib.util.spec_from_file_location("dmlab_assets", TOOL)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _pose(env, x, y, degrees):
    return env.motion_model.Pose.at(jnp.array([x, y], jnp.float32), jnp.float32(math.radians(degrees)))


# ---- the asset --------------------------------------------------------------------------------
def test_asset_is_small_licensed_and_names_its_sources():
    assets = dmlab_look.load()
    assert os.path.getsize(dmlab_look.ASSET) < 1_000_000
    licence = open(os.path.join(os.path.dirname(dmlab_look.ASSET), "DMLAB-ASSETS-LICENSE.txt")).read()
    assert "Creative Commons Attribution 4.0" in licence and "tomosii/Miniworld" in licence
    tool = _tool()
    # the npz holds the look's surfaces in MISHMASH's order, then melon's wall
    assert list(assets["surface_names"]) == list(dmlab_look.MISHMASH_FLOORS + dmlab_look.MISHMASH_WALLS
                                                  + melon.SURFACES[:1])
    assert str(assets["lab_commit"]) == tool.LAB_COMMIT and int(assets["miniworld_checked"]) > 0
    # every texture a surface was composited from is a source with a blob id
    blobs = dict(zip(assets["source_names"], assets["source_blobs"]))
    assert all(re.fullmatch(r"[0-9a-f]{40}", b) for b in blobs.values())
    for stages in assets["surface_sources"]:
        assert set(stages.split(";")) <= set(blobs)
    # the substitutions are the tool's, one per texture neither repository holds
    assert {w: u for w, u, _ in assets["substitutions"]} == {w: u for w, (u, _) in tool.SUBSTITUTES.items()}
    assert "textures/model/goal_colours_d" in blobs  # the goal's texture exists: drawn, not substituted


def test_stored_surfaces_are_box_filtered_from_their_full_resolution_composites():
    assets = dmlab_look.load()
    surfaces = np.asarray(assets["surfaces"], np.float64) / 255.0
    chex.assert_shape(surfaces, (len(assets["surface_names"]), 64, 64, 3))
    assert assets["surfaces"].dtype == np.uint8
    # a box filter of whole 16 x 16 blocks keeps the mean: within the uint8 rounding (1/510)
    np.testing.assert_allclose(surfaces.mean((1, 2)), assets["surface_mean"], atol=0.5 / 255 + 1e-9)
    # and keeps detail: no surface is flat
    assert (surfaces.std((1, 2)).max(-1) > 0.02).all()


def test_tool_box_filter_and_sky_table():
    tool = _tool()
    image = np.arange(32 * 32 * 3, dtype=np.float64).reshape(32, 32, 3)
    down = tool.box_down(image, 4)
    np.testing.assert_allclose(down[1, 2], image[8:16, 16:24].mean((0, 1)))
    # a cube with a red top and blue sides: blue round the horizon, red straight up
    red, blue = np.zeros((8, 8, 3)), np.zeros((8, 8, 3))
    red[..., 0], blue[..., 2] = 1.0, 1.0
    table = tool.sky_elevation_table({"up": red, "lf": blue, "rt": blue, "ft": blue, "bk": blue}, azimuths=64)
    np.testing.assert_allclose(table[90 + 90], [1, 0, 0])
    np.testing.assert_allclose(table[90 + 0], [0, 0, 1])
    np.testing.assert_allclose(table[0], [0, 0, 1])  # below the horizon: the side faces' lowest row
    assert tool.wave_mean(["sin", "1.0", "1.0", "0.0", "0.5"]) == pytest.approx(0.5 + 0.5 * (1 - 2 / math.pi), abs=1e-4)


def test_packaged_sky_table_is_its_faces():
    assets = dmlab_look.load()
    faces = {f: np.asarray(assets["sky_faces"][0, i], np.float64) / 255.0 for i, f in enumerate(assets["sky_face_names"])}
    table = _tool().sky_elevation_table(faces, azimuths=90)
    # the table was made from the full-resolution faces: the 64 x 64 ones give it within a few
    # levels at the elevations a 90-degree view can show above a floor (-40 to 60 degrees; the
    # table's ends are single texels: the face's bottom row, the top face's centre)
    np.testing.assert_allclose(table[50:151], assets["sky_elevation_rgb"][0][50:151], atol=4 / 255)
    # lg_sky_01 is blue, brighter overhead than at the horizon
    sky = assets["sky_elevation_rgb"][0]
    assert (sky[:, 2] > sky[:, 0]).all() and sky[180].sum() > sky[90].sum()


def test_sprites_are_the_item_models_standing_off_the_floor():
    assets = dmlab_look.load()
    sprites, sizes, offsets = assets["sprites"], assets["sprite_sizes"], assets["sprite_offsets"]
    assert list(assets["sprite_names"]) == ["goal", "apple", "lemon", "melon"]  # raycaster.GOAL..MELON
    for k, (h, w) in enumerate(sizes):
        alpha = sprites[k, :h, :w, 3]
        assert 20 <= h <= 40 and 20 <= w <= 40 and alpha.mean() > 100  # about 25-35 units, mostly covered
        assert (sprites[k, h:, :, 3] == 0).all() and (sprites[k, :, w:, 3] == 0).all()  # padding is clear
        assert offsets[k, 1] == pytest.approx(h + 19, abs=1.0)  # the model's base 19 units off the floor
    # the goal shows its texture's colours; the fruit their substitutes' flat colour
    goal = sprites[0][sprites[0, ..., 3] == 255][:, :3]
    assert len(np.unique(goal, axis=0)) > 5
    apple = sprites[1][sprites[1, ..., 3] == 255][:, :3]
    np.testing.assert_array_equal(np.unique(apple, axis=0), [[217, 20, 20]])  # rgb 0.85 0.08 0.08


# ---- placing textures ----------------------------------------------------------------------
def test_wall_texture_is_placed_as_quake_3_places_the_brush_face():
    look = melon.melon_look(melon.melon_layout())
    walls = melon.melon_layout().walls
    start, end = np.asarray(walls.start), np.asarray(walls.end)
    row = int(np.flatnonzero((start[:, 1] == -512) & (end[:, 1] == -512))[0])  # the south outer wall, from x = -512 east
    np.testing.assert_allclose(start[row], [-512, -512])
    # s = x / -0.142857 + 3584 texels of 1024; 64 stored: / 16
    assert float(look.wall_offset[row]) == pytest.approx((-512 / -0.142857 + 3584) / 16, rel=1e-6)
    assert float(look.wall_sign[row]) == pytest.approx(1 / -0.142857 / 16, rel=1e-6)
    # t runs down from the walls' top at z = 320: rows of 1 / 0.19 texels a unit, / 16
    assert look.v_scale == pytest.approx(1 / 0.19 / 16) and look.wall_height == 312.0
    assert look.wall_prefix.shape == (doom_render.LEVELS * look.tex_columns * (math.ceil(312 / 0.19 / 16) + 2), 3)


# ---- frames ------------------------------------------------------------------------------------
def test_melon_first_frame_is_the_blue_block_and_the_corridor_has_orange_floor_and_sky():
    env = make("melon")
    assert env.look is not None and env.camera == dmlab_look.CAMERA
    blue = dmlab_look.surface_mean(melon.SURFACES[0])
    orange = dmlab_look.surface_mean(melon.SURFACES[1])
    first = np.asarray(jax.jit(env.reset)(jax.random.PRNGKey(0)).obs, np.float64) / 255.0
    chex.assert_shape(first, (42, 42, 3))
    # facing the block 32 units away, eye 50 up: the view is wall, top to bottom, in the blue's colours
    np.testing.assert_allclose(first.mean((0, 1)), blue, atol=0.03)
    assert (first[..., 2] > first[..., 0]).mean() > 0.95
    east = np.asarray(jax.jit(env.render)(_pose(env, 40.0, -480.0, 0.0)), np.float64) / 255.0
    # down the south corridor: the floor (its mean colour, unlit) fills the bottom rows' middle
    np.testing.assert_allclose(east[-1, 15:27], np.broadcast_to(orange, (12, 3)), atol=1 / 255)
    # the sky above the far walls: lg_sky_01's colour at that elevation
    top = east[0, 20]
    sky = np.asarray(dmlab_look.sky_table("map/lab_games/sky/lg_sky_01"))
    elevation = math.degrees(math.atan2(42 - 1.0, 42))  # output row 0 spans screen rows 0-1
    np.testing.assert_allclose(top, sky[90 + round(elevation)], atol=0.02)  # the blue wall is 0.13 less red


def test_explore_goals_rooms_and_corridors_have_their_own_walls_and_floors():
    env = make("explore-goals")
    gen = env.generator
    assert gen.look == "dmlab" and env.camera == dmlab_look.CAMERA
    key = jax.random.PRNGKey(5)
    state = jax.jit(env.reset)(key)
    world = state.pipeline_state.world
    k_maze = jax.random.split(jax.random.split(jax.random.split(key)[1])[0], 3)[0]  # reset -> _start -> generate
    maze = jax.jit(gen.maze)(k_maze)
    room = np.asarray(maze["room"])[::-1]  # world rows: y up
    floor = np.asarray(world.floor)
    chex.assert_shape(floor, (gen.height, gen.width))
    assert (floor[~room] == 0).all() and len(np.unique(floor[room])) == 1  # corridors: MISHMASH's first floor
    room_floor = int(floor[room][0])
    walls = np.asarray(world.walls.texture)[world.walls.standing()]
    assert set(walls.tolist()) <= {0, *range(len(dmlab_look.MISHMASH_WALLS))} and 0 in walls
    # standing in a room cell, looking down the floor 51 units ahead: the room's floor colour
    iy, ix = np.argwhere(room)[0]
    x, y = (ix + 0.5) * 100, (iy + 0.5) * 100
    for heading in (0.0, 90.0, 180.0, 270.0):  # the cell's centre minus 30 units: the point lies inside it
        h = math.radians(heading)
        frame = np.asarray(jax.jit(env.render)(_pose(env, x - 30 * math.cos(h), y - 30 * math.sin(h), heading), world),
                           np.float64) / 255.0
        want = dmlab_look.surface_mean(dmlab_look.MISHMASH_FLOORS[room_floor])
        np.testing.assert_allclose(frame[-1, 21], want, atol=1 / 255)


def test_items_are_drawn_in_their_models_colours():
    env = make("melon")
    render = jax.jit(env.render)
    every = jnp.ones((env.num_items,), bool)
    for (x, y, deg), item, colour in (((40.0, -480.0, 0.0), raycaster.APPLE, (217, 20, 20)),
                                      ((-40.0, -480.0, 180.0), raycaster.LEMON, (250, 235, 38))):
        pose = _pose(env, x, y, deg)
        shown, gone = np.asarray(render(pose)), np.asarray(render(pose, None, every))
        covered = np.all(np.abs(shown.astype(int) - colour) <= 2, -1) & np.any(shown != gone, -1)
        assert covered.sum() >= 4, item  # whole pixels of the fruit's flat colour
        assert not np.any(np.all(np.abs(gone.astype(int) - colour) <= 2, -1))
    # the goal: its texture's colours where it stands, nothing once collected
    goal_env = make("explore-goals")
    state = jax.jit(goal_env.reset)(jax.random.PRNGKey(0))
    world = state.pipeline_state.world
    gx, gy = (float(v) for v in world.items.pos[0])
    pose = _pose(goal_env, gx - 45.0, gy, 0.0)
    shown = np.asarray(jax.jit(goal_env.render)(pose, world))
    gone = np.asarray(jax.jit(goal_env.render)(pose, world, jnp.ones((1,), bool)))
    changed = np.any(shown != gone, -1)
    assert changed.sum() >= 20
    sprite = dmlab_look.load()["sprites"][raycaster.GOAL]
    opaque = sprite[sprite[..., 3] == 255][:, :3].astype(np.float64)
    np.testing.assert_allclose(shown[changed].mean(0), opaque.mean(0), atol=40)


# ---- the worlds as they were ---------------------------------------------------------------------
@pytest.mark.parametrize("name", ["melon-doom-motion", "melon-dmlab-doom-motion", "explore-goals-doom-motion",
                                  "explore-goals-paper-doom-motion"])
def test_doom_motion_tasks_keep_the_invented_look(name):
    env = make(name)
    assert env.look is None and env.camera == raycaster.Camera() and env.motion_name == "doom"
    state = jax.jit(env.reset)(jax.random.PRNGKey(2))
    world = env.world(state.pipeline_state)
    assert world.floor is None
    if name.startswith("melon"):  # the walls' invented looks as they were
        np.testing.assert_array_equal(np.asarray(world.walls.texture), [row[4] for row in melon.WALLS])
    else:
        assert env.generator.look == "invented"
    if name == "explore-goals-doom-motion":  # the generator's invented draws: rooms, corridors, "decals"
        key = jax.random.split(jax.random.split(jax.random.PRNGKey(2))[1])[0]  # reset -> _start -> generate
        chex.assert_trees_all_equal(jax.jit(DMLabMazeGenerator(look="invented").generate)(key).walls, world.walls)
    # the frame is the invented renderer's, bit for bit
    ms = state.pipeline_state
    sprites = raycaster.Sprites(world.items.pos, world.items.look, ~ms.collected)
    want = jax.jit(raycaster.render, static_argnums=4)(world.walls, ms.pose.pos, ms.pose.heading, sprites, raycaster.Camera())
    got = jax.jit(env.render)(ms.pose, world, ms.collected)
    np.testing.assert_array_equal(np.asarray(got), np.asarray(want))


def test_look_names_are_checked():
    with pytest.raises(ValueError, match="look"):
        melon.melon_env(look="doom")
    with pytest.raises(ValueError, match="look"):
        DMLabMazeGenerator(look="shiny")
