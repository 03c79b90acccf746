"""Where a trained policy goes: one episode per environment from a run's checkpoint (or its
export/), drawn from above, with how much of the map it covers and how close it gets to the goal.

    python experiments/trajectories.py RUN_DIR [--envs 16] [--random]

Writes RUN_DIR/trajectories.png (the first seed's episodes) and prints, per seed: success
ratio, the mean over episodes of the number of 64x64-unit squares visited, and of the
closest approach to the goal (units), and on MyWayHome how many of the map's 17 spawn spots
(one per room or corridor) an episode passes within 64 units of, and where the episodes end:
how many end nearest each spot. ``--random`` adds the
uniform random policy for comparison. Tasks with a fixed map only (the maze-* tasks and melon).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from simjax.agents import sampling_policy
from simjax.envs import is_mywayhome, rollout, uniform_policy
from simjax.envs.doom import mywayhome_map
from simjax.evaluate import nearest_spots
from simjax.runs import restore
from simjax.runs.grid import grid_of


def episodes(env, network, params, key, num_envs: int):
    """Positions (T, N, 2) and whether each env reached the goal, one episode each
    (``params`` None: uniform random actions)."""
    k_reset, k_act = jax.random.split(key)
    state = jax.vmap(env.reset)(jax.random.split(k_reset, num_envs))
    act = uniform_policy(env.action_size, num_envs) if params is None else sampling_policy(network, params)

    def record(state, action, nxt):
        return state.pipeline_state.pose.pos, nxt.done > 0, nxt.metrics["episode_success"] > 0

    keys = jax.random.split(k_act, env.task.max_steps)
    _, _, (pos, done, success) = rollout(env, act, state, network.initial_carry(num_envs), keys, record)
    alive = jnp.cumsum(done, axis=0) == 0  # after each step: the first episode goes on
    first = jnp.concatenate([jnp.ones_like(alive[:1]), alive[:-1]])  # before each step: it is still on
    return pos, alive, (success & done & first).any(axis=0)


def first_episode(pos, alive, n: int) -> np.ndarray:
    """(K, 2): env ``n``'s position before each step it took in its first episode."""
    return pos[np.concatenate([[True], alive[:-1, n]]), n]


def coverage(pos, alive, goal, square: float = 64.0):
    """(squares visited, closest approach to the goal) per env, over its first episode."""
    squares, closest = [], []
    for n in range(pos.shape[1]):
        p = first_episode(pos, alive, n)
        squares.append(len({tuple(s) for s in np.floor(p / square).astype(int).tolist()}))
        closest.append(float(np.min(np.linalg.norm(p - goal, axis=1))))
    return np.asarray(squares), np.asarray(closest)


def spots_passed(pos, alive, spots: dict, radius: float = 64.0) -> np.ndarray:
    """(N,) how many of ``spots`` ({spot: (x, y)}) each env's first episode came within
    ``radius`` units of (MyWayHome's 17 spawn spots: one per room or corridor)."""
    at = np.asarray(list(spots.values()), np.float64)  # (S, 2)
    counts = []
    for n in range(pos.shape[1]):
        p = first_episode(pos, alive, n)
        near = np.linalg.norm(p[:, None, :] - at[None], axis=-1) <= radius  # (K, S)
        counts.append(int(near.any(axis=0).sum()))
    return np.asarray(counts)


def ends_near(pos, alive, spots: dict) -> dict:
    """{spot: how many first episodes end nearest to it}, most first."""
    return nearest_spots(np.stack([first_episode(pos, alive, n)[-1] for n in range(pos.shape[1])]), spots)


def member_name(restored, index: int) -> str:
    """"seed S", and in a sweep's folder the member's point first: "bonus_scale=1e-06, seed S"."""
    grid = grid_of(restored.sweep)  # [{}] for a plain run; members are point-major
    point = grid[index * len(grid) // len(restored.seeds)]
    return ", ".join([f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in point.items()]
                     + [f"seed {restored.seeds[index]}"])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", type=Path)
    parser.add_argument("--envs", type=int, default=16)
    parser.add_argument("--random", action="store_true", help="also the uniform random policy")
    args = parser.parse_args(argv)
    try:
        restored = restore(args.run)
    except FileNotFoundError as err:
        parser.error(str(err))
    env, network = restored.env, restored.network
    if getattr(env, "generator", None) is not None or not hasattr(env, "layout"):
        parser.error(f"{restored.config.env} has no fixed map to draw trajectories on")
    goal = np.asarray(env.layout.items.pos[np.asarray(env.layout.items.ends)][0])
    spots = mywayhome_map.SPAWN_SPOTS if is_mywayhome(restored.config.env) else None
    run = jax.jit(lambda p, k: episodes(env, network, p, k, args.envs))
    drawn = None
    # only the policy parameters: they read the same from checkpoints of older env states
    policies = [(member_name(restored, i), restored.policy(i)) for i in range(len(restored.seeds))]
    if args.random:
        run_random = jax.jit(lambda k: episodes(env, network, None, k, args.envs))
    print(f"{args.run.name} at {restored.env_steps:,} agent steps per seed, {args.envs} episodes each:")
    for name, params in policies + ([("random", None)] if args.random else []):
        key = jax.random.PRNGKey(123)
        pos, alive, success = jax.device_get(run_random(key) if params is None else run(params, key))
        squares, closest = coverage(np.asarray(pos), np.asarray(alive), goal)
        print(f"  {name}: success {np.mean(success):.2f}, squares visited {squares.mean():.1f} "
              f"(max {squares.max()}), closest to goal {closest.mean():.0f} units (min {closest.min():.0f})")
        if spots is not None:
            passed = spots_passed(np.asarray(pos), np.asarray(alive), spots)
            print(f"    spots passed within 64 units: {passed.mean():.1f} of {len(spots)} (max {passed.max()})")
            print("    episodes end nearest spot: " + ", ".join(
                f"{s} ({c})" for s, c in ends_near(np.asarray(pos), np.asarray(alive), spots).items()))
        if drawn is None and params is not None:
            drawn = (name, np.asarray(pos), np.asarray(alive))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from simjax.envs.topdown import draw_topdown, wall_colours

    name, pos, alive = drawn
    fig, ax = plt.subplots(figsize=(8, 6))
    draw_topdown(env.layout, ax=ax, title=f"{args.run.name}, {name}: {args.envs} episodes", colours=wall_colours(env))
    for n in range(pos.shape[1]):
        p = first_episode(pos, alive, n)
        ax.plot(p[:, 0], p[:, 1], linewidth=0.8, alpha=0.7)
    fig.tight_layout()
    out = args.run / "trajectories.png"
    fig.savefig(out, dpi=100)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
