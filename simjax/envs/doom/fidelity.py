"""How close simjax's MyWayHome is to ViZDoom's: the same random walks in both worlds.

Each ViZDoom walk (``vizdoom_ref.random_walk``: a seeded start, uniform random actions) is
replayed in simjax from the same pose (``env.reset_to``) with the same actions, and compared:

- heading: |ours - ViZDoom's| at every step, degrees (both keep Doom's integer angle);
- position: distance between the two players after 25 and 100 steps;
- frames: simjax's 42x42 frame rendered at ViZDoom's pose against ViZDoom's 160x120 frame
  area-averaged to 42x42, mean absolute difference per pixel and channel (0-255);
- depth: simjax's perpendicular wall distance per screen column (160 rays) against ViZDoom's
  depth buffer on the horizon row, in depth-buffer levels (``DEPTH_UNITS_PER_LEVEL``).

Like ``vizdoom_ref`` it needs the vizdoom package; the tests and
``experiments/vizdoom_fidelity.py`` use it, the core does not.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from simjax.envs import raycaster
from simjax.envs.doom import motion, vizdoom_ref

# ViZDoom's 8-bit depth buffer against the perpendicular distance to the wall (160x120 screen,
# horizon row 59), a straight line fitted to 1,600 columns of one walk (seed 3, 40 steps):
# residual 0.4 levels
DEPTH_LEVELS_PER_UNIT = 0.139473
DEPTH_OFFSET = -0.7224
HORIZON_ROW = 59


def viz_walks(num_walks: int, steps: int, first_seed: int = 0) -> list[dict]:
    """``num_walks`` seeded ViZDoom random walks (seeds first_seed, first_seed + 1, ...) from
    the scenario's own random starts, all in one game process."""
    with vizdoom_ref.MyWayHome(seed=first_seed) as game:
        return [vizdoom_ref.random_walk(first_seed + i, steps, game=game) for i in range(num_walks)]


def replay(env, walks: list[dict]) -> dict:
    """Replay each walk's actions in ``env`` from its start pose; returns our ``xy`` (N, T+1, 2)
    and ``angle_deg`` (N, T+1), padded with the last pose after a walk that ended early."""
    steps = max(len(w["actions"]) for w in walks)
    acts = np.stack([np.pad(w["actions"], (0, steps - len(w["actions"])), constant_values=motion.NOOP)
                     for w in walks]).astype(np.int32)
    xy0 = np.stack([w["xy"][0] for w in walks]).astype(np.float32)
    head0 = np.radians(np.asarray([w["angle_deg"][0] for w in walks], np.float32))

    def one(xy, heading, actions):
        state = env.reset_to(jax.random.PRNGKey(0), xy, heading)

        def body(s, a):
            s = env.step(s, a)
            return s, (s.pipeline_state.pose.pos, s.pipeline_state.pose.angle)

        _, (pos, angle) = jax.lax.scan(body, state, actions)
        first = (state.pipeline_state.pose.pos[None], state.pipeline_state.pose.angle[None])
        return jnp.concatenate([first[0], pos]), jnp.concatenate([first[1], angle])

    pos, angle = jax.jit(jax.vmap(one))(jnp.asarray(xy0), jnp.asarray(head0), jnp.asarray(acts))
    return {"xy": np.asarray(pos), "angle_deg": np.asarray(angle) * 360.0 / motion.ANGLE_UNITS}


def motion_errors(walks: list[dict], ours: dict) -> dict:
    """Heading error (deg) at every step and position error (units) per step, over the steps
    each ViZDoom walk really took (NaN after a walk ended)."""
    n, t1 = ours["xy"].shape[:2]
    head = np.full((n, t1), np.nan)
    pos = np.full((n, t1), np.nan)
    for i, w in enumerate(walks):
        k = len(w["xy"])
        d = (ours["angle_deg"][i, :k] - w["angle_deg"]) % 360.0
        head[i, :k] = np.minimum(d, 360.0 - d)
        pos[i, :k] = np.linalg.norm(ours["xy"][i, :k] - w["xy"], axis=1)
    return {"heading_err_deg": head, "pos_err": pos}


def frame_and_depth_errors(env, walks: list[dict], every: int = 1) -> dict:
    """Per compared pose (every ``every``-th step of each walk): mean absolute difference of
    simjax's frame at ViZDoom's pose against ViZDoom's resized frame, and per screen column the
    depth difference in buffer levels where ViZDoom's buffer is not saturated."""
    poses = [(w["xy"][t], w["angle_deg"][t], w["frames"][t], w["depth"][t])
             for w in walks for t in range(0, len(w["frames"]), every)]
    xy = jnp.asarray(np.stack([p[0] for p in poses]), jnp.float32)
    heading = jnp.asarray(np.radians([p[1] for p in poses]), jnp.float32)
    screen = raycaster.Camera(width=160, fov_deg=90.0)  # one ray per ViZDoom screen column

    @jax.jit
    @jax.vmap
    def ours(p, h):
        frame = env.render(motion.Pose.at(p, h))
        depth = raycaster.cast_rays(env.layout.walls, p, motion.heading_of(motion.angle_units(h)), screen)[0]
        return frame, depth

    frames, depth = ours(xy, heading)
    theirs = np.stack([vizdoom_ref.resize42(p[2]) for p in poses]).astype(np.float64)
    pixel = np.abs(np.asarray(frames, np.float64) - theirs).mean(axis=(1, 2, 3))
    buf = np.stack([p[3][HORIZON_ROW] for p in poses]).astype(np.float64)
    level = np.asarray(depth, np.float64) * DEPTH_LEVELS_PER_UNIT + DEPTH_OFFSET
    valid = buf < 255
    return {"pixel_mae": pixel, "depth_err": np.abs(level - buf)[valid], "frames": np.asarray(frames),
            "theirs": theirs.round().astype(np.uint8), "poses": [(p[0], p[1]) for p in poses]}


def summary(walks, motion_err, frame_err) -> dict:
    """The numbers of the fidelity table (docs/worlds.md)."""
    pos, head = motion_err["pos_err"], motion_err["heading_err_deg"]
    at = lambda t: pos[:, t][np.isfinite(pos[:, t])]
    out = {
        "walks": len(walks),
        "heading_err_max_deg": float(np.nanmax(head)),
        "pixel_mae": float(frame_err["pixel_mae"].mean()),
        "depth_within_1.5": float((frame_err["depth_err"] <= 1.5).mean()),
    }
    for t in (25, 100):
        if pos.shape[1] > t and at(t).size:
            out[f"pos_err_median_{t}"] = float(np.median(at(t)))
            out[f"pos_err_p90_{t}"] = float(np.percentile(at(t), 90))
            out[f"pos_err_max_{t}"] = float(at(t).max())
            out[f"walks_at_{t}"] = int(at(t).size)
    return out
