"""The paper's MyWayHome starts (simjax.envs.doom.icm_scenarios): the vendored ICM wads, the start
rules read out of their compiled ENTER scripts, simjax's tasks drawing those starts, and real
ViZDoom running the wads themselves as the judge (the player's position, the angle's range over
many episodes, the first frame). Needs nothing outside the project: the wads are vendored."""

import hashlib
import math
from pathlib import Path

import jax
import numpy as np
import pytest

from simjax.envs import make, mywayhome_base
from simjax.envs.doom import icm_scenarios as icm
from simjax.envs.doom import mywayhome_map
from simjax.envs.doom.wad import Wad

# sha256 of the ICM code's files (pathak22/noreward-rl, doomFiles/wads/, commit 3e220c2)
ICM_SHA256 = {
    "dense": "76c3f7f8d45368532ad2101b65ddcfd314c34448cd89806dde2a0587b3c45fd1",
    "sparse": "fcfd3480b8e813636ce7f2a9cea890217924742abf196b073a4cb983f33f67be",
    "very-sparse": "c2039800af77c3b720f4e5cdc6c058b09b1dea6ab43be13de02410093fb4cb90",
}
SHARED = Path(__file__).resolve().parents[2] / "shared" / "reference" / "icm-wads"
TASKS = {"maze-sparse": icm.SPARSE, "maze-very-sparse": icm.VERY_SPARSE}
# the first frames' mean difference from ViZDoom's, measured 3.6-4.3 grey levels (sparse) and 1.7-2.1
# (very sparse, a small plain room); turned 10 degrees off they are 25 and 6.2, turned round 14 and 8
FIRST_FRAME_BOUND = {"maze-sparse": 5.5, "maze-very-sparse": 3.0}


def test_the_vendored_wads_are_the_icm_codes_files_with_their_licence():
    for setting, digest in ICM_SHA256.items():
        data = icm.wad_path(setting).read_bytes()
        assert hashlib.sha256(data).hexdigest() == digest, setting
        if SHARED.exists():  # the reference copy, where this checkout has one
            assert data == (SHARED / icm.WAD_FILES[setting]).read_bytes()
    assert "Deepak Pathak" in (icm.ASSETS / "LICENSE.noreward-rl").read_text()


def test_the_start_rules_are_the_ones_the_wads_compiled_enter_scripts_run():
    for setting, rule in icm.STARTS.items():
        assert icm.wad_start(icm.wad_path(setting)) == rule, setting
    # ACC's fixed point: random(0.49, 0.51) of a turn is 176.4-183.6 degrees, random(0.0, 0.01) 0-3.6
    lo, hi = icm.degrees(icm.VERY_SPARSE.angles)
    assert 176.39 < lo < 176.41 and 183.59 < hi < 183.61
    assert icm.degrees(icm.SPARSE.angles) == (0.0, pytest.approx(3.598, abs=1e-3))


def test_the_reader_refuses_a_script_it_does_not_understand():
    behavior = bytearray(Wad.load(str(icm.wad_path("sparse"))).find("BEHAVIOR"))
    enter = behavior.index(bytes([0x1D, 0x02, 0x19, 0x00])) + 2  # target_id = map_point_start_id: ASSIGNSCRIPTVAR 0
    behavior[enter] = 0x5A  # a p-code the start rule never uses
    with pytest.raises(ValueError, match="p-code"):
        icm.enter_start(bytes(behavior))


@pytest.fixture(scope="module")
def starts():
    """16,384 first poses of each task (and of its variants), drawn by simjax's resets."""
    keys = jax.random.split(jax.random.PRNGKey(0), 16384)
    names = ["maze-sparse", "maze-very-sparse", "maze-very-sparse-invented-looks", "maze-sparse-flat-SILVER2",
             "maze-spot10-east", "maze-spot16-east"]
    out = {}
    for name in names:
        env = make(name)
        start = jax.jit(jax.vmap(env._spawn))(keys)  # the start rule alone: no frame rendered
        out[name] = np.asarray(start.pos), np.asarray(start.angle)
    return out


@pytest.mark.parametrize("task", list(TASKS))
def test_simjax_draws_each_episodes_start_as_the_wad_does(starts, task):
    rule = TASKS[task]
    pos, angle = starts[task]
    np.testing.assert_array_equal(pos, np.broadcast_to(np.float32(mywayhome_map.SPAWN_SPOTS[rule.spots[0]]), pos.shape))
    lo, hi = rule.angles
    assert angle.min() == lo and angle.max() == hi  # 16,384 draws reach both ends of the range
    values = np.bincount(angle - lo, minlength=hi - lo + 1)
    assert values.size == hi - lo + 1 and (values > 0).mean() > 0.9  # spread over the whole range
    assert abs(angle.mean() - (lo + hi) / 2) < 0.03 * (hi - lo)  # uniformly


def test_the_looks_follow_their_task_and_the_old_starts_stand_still(starts):
    for variant in ("maze-very-sparse-invented-looks", "maze-sparse-flat-SILVER2"):
        np.testing.assert_array_equal(starts[variant][0], starts[mywayhome_base(variant)][0])
        np.testing.assert_array_equal(starts[variant][1], starts[mywayhome_base(variant)][1])
    for task, spot in (("maze-spot10-east", 10), ("maze-spot16-east", 16)):
        pos, angle = starts[task]
        np.testing.assert_allclose(pos, np.broadcast_to(mywayhome_map.SPAWN_SPOTS[spot], pos.shape), rtol=1e-6)
        assert np.all(angle == 0)


@pytest.mark.parametrize("task", list(TASKS))
def test_vizdoom_on_the_icm_wad_starts_where_simjax_does_and_shows_the_same_first_frame(task):
    vr = pytest.importorskip("simjax.envs.doom.vizdoom_ref")
    rule = TASKS[task]
    game, start = vr.open_task(task, seed=0, depth=False)
    assert start is None and game.scenario == task.removeprefix("maze-")  # the wad places the player
    spot = mywayhome_map.SPAWN_SPOTS[rule.spots[0]]
    units, firsts = [], []
    with game:
        for episode in range(100):
            game.new_episode(seed=300 + episode)
            x, y, angle_deg = game.pose()
            assert (round(x * 65536), round(y * 65536)) == (round(spot[0] * 65536), round(spot[1] * 65536))
            assert game.game.get_episode_time() == game.start_time
            units.append(round(angle_deg / 360 * icm.ANGLE_UNITS))
            if episode < 4:
                firsts.append(((x, y, angle_deg), vr.resize42(game.frame())))
    lo, hi = rule.angles
    assert lo <= min(units) and max(units) <= hi  # ZDoom's random(lo, hi), inclusive
    assert max(units) - min(units) > 0.8 * (hi - lo)  # and it does range over the interval
    env = make(task)
    reset_to = jax.jit(env.reset_to)
    for (x, y, angle_deg), view in firsts:
        ours = reset_to(jax.random.PRNGKey(0), np.array([x, y], np.float32), math.radians(angle_deg))
        assert int(ours.pipeline_state.pose.angle) == round(angle_deg / 360 * icm.ANGLE_UNITS)
        assert np.abs(view.astype(int) - np.asarray(ours.obs, int)).mean() < FIRST_FRAME_BOUND[task]
