"""The uniform random policy's level on the DMLab worlds, moving as DeepMind Lab does and as
Doom does (their ``-doom-motion`` tasks): the score a trained policy is set against, and what
the motion does to it.

    python experiments/random_level.py [--tasks melon,melon-doom-motion,...] [--envs 1024] [--episodes 4] [--seed 0]

Each of ``--envs`` envs plays ``--episodes`` episodes with uniformly random actions, in one
compiled scan of ``--episodes`` x the task's step limit per task; only each env's first
``--episodes`` episodes are counted, so every one is whole and short ones are not favoured.
No frame is drawn (the policy does not look; the step's render is dead code). Prints, per
task, a row of: episodes; the success ratio (``episode_success``: the melon reached, or for
explore-goals at least one goal) with its 95% Wilson interval; the mean return with its 95%
interval (mean +- 1.96 standard errors); for tasks with a goal reward (explore-goals) the goals
an episode (return / goal reward) with the same interval.
"""

from __future__ import annotations

import argparse
import math

import jax
import jax.numpy as jnp
import numpy as np

from simjax.envs import check_name, make
from simjax.evaluate import wilson

TASKS = ("melon", "melon-doom-motion", "explore-goals", "explore-goals-doom-motion")
Z = 1.959964


def random_episodes(env, num_envs: int, episodes: int, seed: int) -> dict:
    """Sums over each env's first ``episodes`` episodes of uniform random play: episodes,
    successes, return and return squared (per env, summed on the host)."""
    steps = episodes * env.task.max_steps  # time enough for every env to end that many
    step = jax.vmap(env.step)

    def body(carry, key):
        state, ended, sums = carry
        after = step(state, jax.random.randint(key, (num_envs,), 0, env.action_size))
        after = after.replace(obs=state.obs)  # no frame: nothing reads it
        m = after.metrics
        counted = (m["episode_done"] > 0) & (ended < episodes)
        ret = m["episode_return"]
        sums = {"episodes": sums["episodes"] + counted, "successes": sums["successes"] + counted * m["episode_success"],
                "return": sums["return"] + counted * ret, "return2": sums["return2"] + counted * ret * ret}
        return (after, ended + (m["episode_done"] > 0), sums), None

    @jax.jit
    def run(key):
        k_reset, k_act = jax.random.split(key)
        state = jax.vmap(env.reset)(jax.random.split(k_reset, num_envs))
        zeros = jnp.zeros(num_envs, jnp.float32)
        sums = {name: zeros for name in ("episodes", "successes", "return", "return2")}
        carry = (state, jnp.zeros(num_envs, jnp.int32), sums)
        (_, _, sums), _ = jax.lax.scan(body, carry, jax.random.split(k_act, steps))
        return sums

    return {name: float(np.asarray(v, np.float64).sum()) for name, v in run(jax.random.PRNGKey(seed)).items()}


def mean_interval(total: float, total2: float, n: int) -> tuple[float, float, float]:
    """(mean, low, high): the mean of n values from their sum and sum of squares, +- Z standard errors."""
    mean = total / n
    var = max(total2 / n - mean * mean, 0.0) * n / max(n - 1, 1)
    half = Z * math.sqrt(var / n)
    return mean, mean - half, mean + half


def row(task: str, env, sums: dict) -> str:
    n = int(round(sums["episodes"]))
    successes = int(round(sums["successes"]))
    low, high = wilson(successes, n)
    ret = mean_interval(sums["return"], sums["return2"], n)
    cells = [f"`{task}`", f"{n:,}", f"{successes / n:.4f} [{low:.4f}, {high:.4f}]", "{:.3f} [{:.3f}, {:.3f}]".format(*ret)]
    goal = getattr(env, "goal_reward", None)
    cells.append("{:.4f} [{:.4f}, {:.4f}]".format(*(v / goal for v in ret)) if goal else "")
    return "| " + " | ".join(cells) + " |"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--tasks", default=",".join(TASKS), help="comma-separated maze tasks")
    parser.add_argument("--envs", type=int, default=1024)
    parser.add_argument("--episodes", type=int, default=4, help="episodes counted per env")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    tasks = [t for t in args.tasks.split(",") if t]
    for task in tasks:
        try:
            check_name(task)
        except ValueError as err:
            parser.error(str(err))
    if args.envs < 1 or args.episodes < 1:
        parser.error("--envs and --episodes must be at least 1")
    print(f"uniform random policy, {args.envs} envs x their first {args.episodes} episodes, seed {args.seed}\n")
    print("| task | episodes | success ratio [95%] | mean return [95%] | goals an episode [95%] |\n|---|---:|---|---|---|")
    for task in tasks:
        env = make(task)
        if not hasattr(env, "task"):
            parser.error(f"{task}: a maze task (its step limit sets the scan's length)")
        print(row(task, env, random_episodes(env, args.envs, args.episodes, args.seed)), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
