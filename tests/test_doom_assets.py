"""The Freedoom texture asset (simjax/envs/doom/assets/freedoom_mywayhome.npz) against its source:
a fresh conversion of the installed vizdoom's WADs, and what ViZDoom itself draws."""

import os
import subprocess
import sys

import numpy as np
import pytest

from simjax.envs.doom import doom_assets, mywayhome_map

TOOL = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                    "tools", "freedoom_assets.py")
WALLS = np.array(mywayhome_map.WALLS, float)
EYE = 41.0  # Doom's view height above the floor (all floors are at 0, ceilings at 128)


@pytest.fixture(scope="module")
def asset():
    return doom_assets.load()


def test_keys_shapes_and_dtypes(asset):
    names = tuple(asset["texture_names"])
    assert names == mywayhome_map.TEXTURE_NAMES
    sizes = {"BIGDOOR2": (128, 128), "CRATE2": (128, 64), "SILVER2": (128, 64),
             "SFALL2": (128, 64), "BIGBRIK1": (128, 64)}  # the rest are 64x64 flats
    for name in names:
        index, rgb = asset[f"wall_{name}_index"], asset[f"wall_{name}"]
        assert index.dtype == rgb.dtype == np.uint8
        assert index.shape == sizes.get(name, (64, 64)) and rgb.shape == index.shape + (3,)
        np.testing.assert_array_equal(rgb, asset["playpal"][index])
    assert asset["flat_FLAT1_1_index"].shape == (64, 64)
    np.testing.assert_array_equal(asset["flat_FLAT1_1"],
                                  asset["playpal"][asset["flat_FLAT1_1_index"]])
    sprite = asset["sprite_ARM1A0"]
    assert sprite.dtype == np.uint8 and sprite.ndim == 3 and sprite.shape[2] == 4
    assert set(np.unique(sprite[..., 3])) == {0, 255}
    assert asset["sprite_ARM1A0_offset"].dtype == np.int32
    assert asset["sprite_ARM1A0_offset"].shape == (2,)
    assert asset["playpal"].shape == (256, 3) and asset["playpal"].dtype == np.uint8
    assert asset["colormap"].shape == (34, 256) and asset["colormap"].dtype == np.uint8
    n = len(mywayhome_map.WALLS)
    for key, dtype in (("wall_offset_x", np.float32), ("wall_offset_y", np.float32),
                       ("wall_u_reversed", np.bool_), ("wall_linedef", np.int32)):
        assert asset[key].shape == (n,) and asset[key].dtype == dtype, key
    assert len(set(asset["wall_linedef"])) == n
    assert os.path.getsize(doom_assets.ASSET) < 200_000


def test_packaged_asset_is_a_fresh_conversion(asset, tmp_path):
    pytest.importorskip("vizdoom")
    out = tmp_path / "fresh.npz"
    subprocess.run([sys.executable, TOOL, "--out", str(out), "--quiet"], check=True)
    with np.load(out) as fresh:
        assert sorted(fresh.files) == sorted(asset)
        for key in fresh.files:
            assert fresh[key].dtype == asset[key].dtype, key
            np.testing.assert_array_equal(fresh[key], asset[key], err_msg=key)


def _vizdoom_views(episodes=4, seed=1):
    """(screen, x, y, angle in radians) at the start of a few MyWayHome episodes, 320x240.
    Seed 1's second episode starts at spot 10 and sees a BIGDOOR2 wall with offsetx 112."""
    vzd = pytest.importorskip("vizdoom")
    game = vzd.DoomGame()
    game.load_config(os.path.join(vzd.scenarios_path, "my_way_home.cfg"))
    game.set_window_visible(False)
    game.set_screen_format(vzd.ScreenFormat.RGB24)
    game.set_screen_resolution(vzd.ScreenResolution.RES_320X240)
    game.set_available_game_variables([vzd.GameVariable.POSITION_X,
                                       vzd.GameVariable.POSITION_Y, vzd.GameVariable.ANGLE])
    game.set_seed(seed)
    game.init()
    try:
        views = []
        for _ in range(episodes):
            game.new_episode()
            state = game.get_state()
            x, y, angle = state.game_variables
            views.append((state.screen_buffer.astype(np.int64), x, y, np.deg2rad(angle)))
        return views
    finally:
        game.close()


def _cast(x, y, angles):
    """For rays from (x, y): (distance, wall row, distance along the row from its start)."""
    dx, dy = np.cos(angles)[:, None], np.sin(angles)[:, None]
    x1, y1, x2, y2 = WALLS[:, 0], WALLS[:, 1], WALLS[:, 2], WALLS[:, 3]
    ex, ey, qx, qy = x2 - x1, y2 - y1, x1 - x, y1 - y
    with np.errstate(divide="ignore", invalid="ignore"):
        den = dx * ey - dy * ex
        dist = (qx * ey - qy * ex) / den
        frac = (qx * dy - qy * dx) / den
    dist = np.where((dist > 0) & (frac >= 0) & (frac <= 1), dist, np.inf)
    row = dist.argmin(1)
    cols = np.arange(len(angles))
    return dist[cols, row], row, frac[cols, row] * np.hypot(ex, ey)[row]


def _lit_codes(asset):
    """Every palette index under each COLORMAP light level 0..31, as packed RGB: (32, 256)."""
    rgb = asset["playpal"].astype(np.int64)[asset["colormap"][:32]]
    return (rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]


def _match_view(asset, view, offset_x, u_reversed):
    """The fractions of wall and of floor pixels in a ViZDoom frame that show the texel our
    geometry predicts (or a neighbour, as sub-texel rounding differs), lit by some COLORMAP
    level (one level per wall column, as Doom lights a wall column)."""
    screen, x, y, angle = view
    codes = (screen[..., 0] << 16) | (screen[..., 1] << 8) | screen[..., 2]
    lit = _lit_codes(asset)
    # ZDoom at 320x240, FOV 90: column c looks atan((160 - c - 0.5) / 160) left of the
    # facing; row r shows height EYE - (r + 1 - 120) * depth / 192 (Doom's 1.2 pixel aspect).
    columns = np.arange(320)
    offsets = np.arctan((160 - columns - 0.5) / 160)
    dist, rows, along = _cast(x, y, angle + offsets)
    depth = dist * np.cos(offsets)
    screen_rows = np.arange(240)
    near = (-1, 0, 1)
    wall_hits = wall_total = floor_hits = floor_total = 0
    for c in columns:
        row = rows[c]
        name = mywayhome_map.TEXTURE_NAMES[int(WALLS[row, 4])]
        texture = asset[f"wall_{name}_index"]
        length = np.hypot(WALLS[row, 2] - WALLS[row, 0], WALLS[row, 3] - WALLS[row, 1])
        u = offset_x[row] + (length - along[c] if u_reversed[row] else along[c])
        v = (128 - EYE) + (screen_rows + 1 - 120) * depth[c] / 192
        on_wall = (v >= 1) & (v < 127)
        vi = np.floor(v[on_wall]).astype(int)
        h, w = texture.shape
        candidates = np.stack([texture[(vi + dv) % h, (int(np.floor(u)) + du) % w]
                               for dv in near for du in near])
        seen = codes[screen_rows[on_wall], c]
        wall_hits += (lit[:, candidates] == seen).any(1).sum(1).max()
        wall_total += on_wall.sum()
        # floor pixels nearer than the wall: the texel at map (x, y) is row -y, column x
        floor_rows = screen_rows[(screen_rows + 1 - 120) * depth[c] / 192 > EYE + 8]
        reach = EYE * 192 / (floor_rows + 1 - 120) / np.cos(offsets[c])
        fx = np.floor(x + reach * np.cos(angle + offsets[c])).astype(int)
        fy = np.floor(-(y + reach * np.sin(angle + offsets[c]))).astype(int)
        flat = asset["flat_FLAT1_1_index"]
        candidates = np.stack([flat[(fy + dv) % 64, (fx + du) % 64] for dv in near for du in near])
        seen = codes[floor_rows, c]
        floor_hits += (lit[:, candidates] == seen).any(1).any(0).sum()
        floor_total += len(floor_rows)
    return wall_hits / wall_total, floor_hits / floor_total


def test_vizdoom_draws_the_asset(asset):
    """ViZDoom's own frames show our textures where our map puts them: with the asset's
    texels, offsets and u direction nearly every wall and floor pixel is the predicted texel
    at some light level; a wrong texture, offset, direction or orientation drops that well
    below (about 0.85 for offsets dropped, 0.45-0.9 for u flipped, under 0.2 for the wrong
    texture, under 0.85 for the floor's rows flipped)."""
    views = _vizdoom_views()
    offset_x, u_reversed = asset["wall_offset_x"], asset["wall_u_reversed"]
    scores = [_match_view(asset, view, offset_x, u_reversed) for view in views]
    assert min(wall for wall, _ in scores) > 0.95, scores
    assert min(floor for _, floor in scores) > 0.97, scores
    # the views are ones where offsets and the u direction show, so the bound above has teeth
    no_offsets = [_match_view(asset, view, 0 * offset_x, u_reversed)[0] for view in views]
    flipped = [_match_view(asset, view, offset_x, ~u_reversed)[0] for view in views]
    assert min(no_offsets) < 0.92 and min(flipped) < 0.92, (no_offsets, flipped)
