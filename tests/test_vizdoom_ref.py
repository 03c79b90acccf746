"""The ViZDoom oracle (simjax.envs.doom.vizdoom_ref): determinism, the start-pose patch, the action
mapping against motion facts measured in ViZDoom (shared/reference/vizdoom_facts.md), and the
area resize. Skipped where vizdoom is not installed."""

import math
from fractions import Fraction

import numpy as np
import pytest

pytest.importorskip("vizdoom")

from simjax.envs.doom import vizdoom_ref as vr  # noqa: E402
from simjax.envs.doom.motion import FORWARD, NOOP, TURN_LEFT, TURN_RIGHT  # noqa: E402

# 640 angle units a tic at walking speed, 320 for the first 5 tics a turn button is held,
# in a 65536-unit turn: one step from rest (4 tics) turns 1280 units, the next 2240.
FIRST_TURN_DEG = 1280 * 360 / 65536  # 7.03125
SECOND_TURN_DEG = 2240 * 360 / 65536  # 12.3046875


@pytest.fixture(scope="module")
def game():
    with vr.MyWayHome(seed=0) as g:
        yield g


def test_buttons_are_mapped_by_name(game):
    names = game.button_names
    assert {"TURN_LEFT", "TURN_RIGHT", "MOVE_FORWARD"} <= set(names)
    for action, button in ((TURN_LEFT, "TURN_LEFT"), (TURN_RIGHT, "TURN_RIGHT"), (FORWARD, "MOVE_FORWARD")):
        vec = game._vectors[action]
        assert vec[names.index(button)] == 1 and sum(vec) == 1
    assert sum(game._vectors[NOOP]) == 0


def test_first_frame_shape_and_dtype(game):
    game.new_episode(seed=3)
    f, d = game.frame(), game.depth()
    assert f.shape == (120, 160, 3) and f.dtype == np.uint8
    assert d.shape == (120, 160) and d.dtype == np.uint8
    assert f.std() > 1 and d.std() > 1  # a rendered view, not a blank buffer
    assert game.game.get_episode_time() == game.start_time == 10


def test_same_seed_same_actions_same_episode(game):
    a = vr.random_walk(seed=11, steps=40, game=game)
    b = vr.random_walk(seed=11, steps=40)  # a fresh engine process
    assert a["length"] == b["length"] == 40
    assert a["xy"].shape == (41, 2) and a["frames"].shape == (41, 120, 160, 3)
    for key in ("actions", "xy", "angle_deg", "frames", "depth", "done"):
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    assert np.ptp(a["xy"], axis=0).max() > 10  # it did move
    c = vr.random_walk(seed=12, steps=40, game=game)
    assert not np.array_equal(a["xy"], c["xy"])


def test_patch_changes_nothing_else(game):
    """The patched wad (one more ACS script) plays a seed exactly like the shipped one."""
    actions = np.random.default_rng(0).integers(0, 4, 25)
    with vr.MyWayHome(seed=0, patched=False) as shipped:
        for seed in (1, 2):
            a = vr.random_walk(seed, 0, actions, game=game)
            b = vr.random_walk(seed, 0, actions, game=shipped)
            np.testing.assert_array_equal(a["xy"], b["xy"])
            np.testing.assert_array_equal(a["angle_deg"], b["angle_deg"])
            np.testing.assert_array_equal(a["frames"], b["frames"])


@pytest.mark.parametrize("task", ["maze-spot16-east", "maze-spot10-east"])
def test_task_start_lands_exactly(game, task):
    x, y, angle = vr.TASK_SCENARIOS[task][1]
    game.new_episode(start=(x, y, angle), seed=5)
    px, py, pa = game.pose()
    assert (round(px * 65536), round(py * 65536)) == (round(x * 65536), round(y * 65536))
    assert abs(px - x) <= 0.5 / 65536 and abs(py - y) <= 0.5 / 65536 and pa == angle == 0.0
    assert game.game.get_episode_time() == 10  # the same clock as a natural start


def test_placed_start_is_a_natural_start(game):
    """Placing the player at the pose a seed's ENTER script chose gives the same frame, depth
    and motion: the placement is exact, and the first frame is rendered after the teleport."""
    actions = [FORWARD, FORWARD, TURN_LEFT, TURN_LEFT, FORWARD, TURN_RIGHT, FORWARD, NOOP, FORWARD]
    natural = vr.random_walk(21, 0, actions, game=game)
    start = (*natural["xy"][0], natural["angle_deg"][0])
    placed = vr.random_walk(99, 0, actions, start=start, game=game)
    for key in ("xy", "angle_deg", "frames", "depth"):
        np.testing.assert_array_equal(natural[key], placed[key], err_msg=key)


def test_placed_episode_times_out_like_the_scenario(game):
    for start in (None, vr.TASK_SCENARIOS["maze-spot16-east"][1]):
        game.new_episode(start=start, seed=4)
        n, done = 0, False
        while not done:
            reward, done = game.step(NOOP)
            n += 1
        assert (n, reward, game.succeeded) == (525, 0.0, False)


def test_blocked_start_is_refused(game):
    with pytest.raises(ValueError):
        game.new_episode(start=(160.0, -176.0, 0.0))  # on the west wall of the start room


def test_forward_step_from_rest(game):
    game.new_episode(start=vr.TASK_SCENARIOS["maze-spot10-east"][1])
    game.step(FORWARD)
    x, y, _ = game.pose()
    assert (x - 240.0) == pytest.approx(7.1, abs=0.05) and y == -176.0
    game.new_episode(seed=8)  # a random spot and angle: the step goes along the facing
    x0, y0, a0 = game.pose()
    game.step(FORWARD)
    x1, y1, a1 = game.pose()
    assert a1 == a0
    assert math.hypot(x1 - x0, y1 - y0) == pytest.approx(7.1, abs=0.05)
    # sideways drift: Doom's thrust uses a sine table of 8192 angles (0.044 deg), up to 0.0055 here
    sideways = (x1 - x0) * math.sin(math.radians(a0)) - (y1 - y0) * math.cos(math.radians(a0))
    assert abs(sideways) < 0.01


@pytest.mark.parametrize("action,sign", [(TURN_LEFT, 1.0), (TURN_RIGHT, -1.0)])
def test_turn_steps_from_rest(game, action, sign):
    game.new_episode(start=(240.0, -176.0, 90.0))
    angles = [game.pose()[2]]
    for _ in range(2):
        game.step(action)
        angles.append(game.pose()[2])
    turns = [((b - a + 180.0) % 360.0) - 180.0 for a, b in zip(angles, angles[1:])]
    assert turns == [sign * FIRST_TURN_DEG, sign * SECOND_TURN_DEG]
    assert game.pose()[:2] == (240.0, -176.0)


def test_touching_the_armour_is_the_goal(game):
    """Facing the armour from 72 units: the third forward step touches it; reward 1.0 then
    (ViZDoom's own step reward would be 0.9996), and random_walk stops there."""
    walk = vr.random_walk(0, 0, [FORWARD] * 6, start=(1040.0, -280.0, 270.0), game=game)
    assert walk["length"] == 3 and walk["reached_goal"]
    np.testing.assert_array_equal(walk["done"], [False, False, True])
    assert walk["xy"].shape == (4, 2) and walk["frames"].shape == (3, 120, 160, 3)
    game.new_episode(start=(1040.0, -280.0, 270.0))
    assert [game.step(FORWARD) for _ in range(3)] == [(0.0, False), (0.0, False), (1.0, True)]
    assert game.succeeded
    with pytest.raises(RuntimeError):
        game.frame()


def _slow_area_resize(img, out_h, out_w):
    """Direct definition: each output pixel is the overlap-weighted mean of the source pixels
    its footprint [i*s, (i+1)*s) x [j*t, (j+1)*t) covers (exact rational footprints)."""
    h, w = img.shape[:2]
    sy, sx = Fraction(h, out_h), Fraction(w, out_w)
    out = np.zeros((out_h, out_w) + img.shape[2:])
    for i in range(out_h):
        y0, y1 = i * sy, (i + 1) * sy
        for j in range(out_w):
            x0, x1 = j * sx, (j + 1) * sx
            acc = 0.0
            for r in range(math.floor(y0), math.ceil(y1)):
                wy = min(y1, r + 1) - max(y0, r)
                for c in range(math.floor(x0), math.ceil(x1)):
                    wx = min(x1, c + 1) - max(x0, c)
                    acc = acc + float(wy * wx) * img[r, c].astype(np.float64)
            out[i, j] = acc / float(sy * sx)
    return out


def test_resize42_matches_the_direct_area_average():
    img = np.random.default_rng(0).integers(0, 256, (120, 160, 3), dtype=np.uint8)
    ref = _slow_area_resize(img, 42, 42)
    np.testing.assert_allclose(vr.resize_area(img, 42, 42), ref, rtol=0, atol=1e-9)
    got = vr.resize42(img)
    assert got.shape == (42, 42, 3) and got.dtype == np.uint8
    tie = np.abs(ref - np.floor(ref) - 0.5) < 1e-6
    assert np.all(got[~tie] == np.rint(ref[~tie]))
    assert np.all(np.abs(got.astype(float) - ref) <= 0.5 + 1e-6)


def test_resize42_keeps_a_constant_image_and_block_means():
    const = np.full((120, 160, 3), 137, np.uint8)
    assert np.all(vr.resize42(const) == 137)
    block = np.arange(16.0).reshape(4, 4)
    np.testing.assert_allclose(vr.resize_area(block, 2, 2), [[2.5, 4.5], [10.5, 12.5]])
    np.testing.assert_allclose(vr.area_weights(160, 42).sum(axis=1), 1.0)
