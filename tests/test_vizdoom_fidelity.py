"""simjax's MyWayHome against real ViZDoom: 32 seeded random walks of 100 steps, replayed in
both worlds (simjax.envs.doom.fidelity). The bounds are the ones the world must keep: Doom's integer
heading exactly, positions within a player's width, the same wall distances, and frames that a
policy cannot tell apart by much (62 levels per pixel before the Freedoom textures and light)."""

import numpy as np
import pytest

from simjax.envs import make
from simjax.envs.doom import fidelity


@pytest.fixture(scope="module")
def measured():
    env = make("maze-dense")
    walks = fidelity.viz_walks(32, 100, first_seed=1000)
    motion_err = fidelity.motion_errors(walks, fidelity.replay(env, walks))
    frame_err = fidelity.frame_and_depth_errors(env, walks, every=10)
    return walks, motion_err, frame_err, fidelity.summary(walks, motion_err, frame_err)


def test_heading_is_exact_at_every_step(measured):
    _, motion_err, _, s = measured
    assert np.isfinite(motion_err["heading_err_deg"][:, :26]).all()  # every walk got that far
    assert s["heading_err_max_deg"] <= 0.05


def test_positions_stay_together(measured):
    _, _, _, s = measured
    assert s["walks_at_100"] >= 28  # a walk that reaches the goal early ends early
    assert s["pos_err_median_100"] <= 2.0
    assert s["pos_err_p90_100"] <= 24.0  # less than the player's width, 32


def test_wall_distances_match_the_depth_buffer(measured):
    _, _, frame_err, s = measured
    assert frame_err["depth_err"].size > 32 * 10 * 100
    assert s["depth_within_1.5"] >= 0.99


def test_frames_match_vizdoom_resized(measured):
    _, _, frame_err, s = measured
    assert s["pixel_mae"] <= 15.0
    # no pose is far off either: a wrong texture, offset or light would show on some pose
    assert np.percentile(frame_err["pixel_mae"], 95) <= 15.0
