"""The uniform random policy's success on MyWayHome's tasks in simjax and in real ViZDoom: a check
of the two worlds that involves no learning (starts, motion, the goal's touch rule, the timeout),
and the baseline a trained policy's success is set against.

    python experiments/random_rates.py [SIMJAX_EPISODES] [VIZDOOM_EPISODES] [--tasks T1,T2,...]

Each task (default: the paper's three, maze-dense, maze-sparse and maze-very-sparse; any
MyWayHome task in ViZDoom's look) is played SIMJAX_EPISODES times in simjax and VIZDOOM_EPISODES
times in ViZDoom, each episode to the goal or the 525-step limit with uniformly random actions.
ViZDoom plays the paper's tasks on the ICM code's own scenario files, whose ENTER scripts place
the player (``vizdoom_ref.open_task``); the starts that no scenario has are placed by the patched
wad. Prints and writes, per task, the successes, the ratio with its 95% Wilson interval and the
two-sided Fisher exact test of the two worlds' ratios being equal, to
experiments/results/vizdoom-fidelity/random-policy-TASK.json."""
import argparse
import json
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent / "paper"))

from protocol import fisher_exact  # noqa: E402

from simjax.envs import make  # noqa: E402
from simjax.envs.doom import vizdoom_ref  # noqa: E402
from simjax.evaluate import wilson  # noqa: E402

CHUNK = 1000  # episodes per compiled batch: bounds the memory of the vmapped states
OUT = Path(__file__).resolve().parent / "results" / "vizdoom-fidelity"


def simjax_successes(task: str, episodes: int, seed: int = 123) -> int:
    """Successes of ``episodes`` uniform random episodes of ``task`` in simjax, each from its own
    reset (the env's start rule) to its end."""
    env = make(task)

    def one(key):
        k0, k1 = jax.random.split(key)
        s = env.reset(k0)
        acts = jax.random.randint(k1, (env.task.max_steps,), 0, env.action_size)

        def body(c, a):
            s, done, succ = c
            s = env.step(s, a)
            first = (s.metrics["episode_done"] > 0) & ~done
            return (s, done | first, jnp.where(first, s.metrics["episode_success"], succ)), None

        (_, _, succ), _ = jax.lax.scan(body, (s, jnp.bool_(False), jnp.float32(0)), acts)
        return succ

    batch = jax.jit(jax.vmap(one))
    keys = jax.random.split(jax.random.PRNGKey(seed), episodes)
    return int(sum(np.asarray(batch(keys[i:i + CHUNK])).sum() for i in range(0, episodes, CHUNK)))


def vizdoom_successes(task: str, episodes: int, seed: int = 7) -> int:
    """Successes of ``episodes`` uniform random episodes of ``task`` in ViZDoom (episode i seeded
    1000 + i, actions from ``numpy.random.default_rng(seed)``)."""
    rng = np.random.default_rng(seed)
    wins = 0
    game, start = vizdoom_ref.open_task(task, seed=5, depth=False)
    with game:
        for i in range(episodes):
            game.new_episode(start=start, seed=1000 + i)
            done = False
            while not done:
                reward, done = game.step(int(rng.integers(0, 4)))
            wins += reward > 0
    return int(wins)


def world(successes: int, episodes: int) -> dict:
    low, high = wilson(successes, episodes)
    return {"episodes": episodes, "successes": successes, "success_ratio": successes / episodes,
            "wilson_95": [low, high]}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("n_sim", nargs="?", type=int, default=2000)
    parser.add_argument("n_viz", nargs="?", type=int, default=600)
    parser.add_argument("--tasks", default="maze-dense,maze-sparse,maze-very-sparse",
                        help=f"comma-separated, of {', '.join(vizdoom_ref.TASK_SCENARIOS)}")
    args = parser.parse_args(argv)
    tasks = args.tasks.split(",")
    unknown = [t for t in tasks if t not in vizdoom_ref.TASK_SCENARIOS]
    if unknown:
        parser.error(f"unknown task(s) {', '.join(unknown)}; known: {', '.join(vizdoom_ref.TASK_SCENARIOS)}")
    if args.n_sim < 1 or args.n_viz < 0:
        parser.error("SIMJAX_EPISODES must be positive and VIZDOOM_EPISODES not negative")
    for task in tasks:
        began = time.time()
        record = {"task": task, "simjax": world(simjax_successes(task, args.n_sim), args.n_sim)}
        print(f"simjax random {task}: {record['simjax']}", flush=True)
        if args.n_viz:
            record["vizdoom"] = world(vizdoom_successes(task, args.n_viz), args.n_viz)
            record["fisher_p"] = fisher_exact(record["simjax"]["successes"], args.n_sim,
                                              record["vizdoom"]["successes"], args.n_viz)
            scenario = vizdoom_ref.TASK_SCENARIOS[task][0]
            record["vizdoom_scenario"] = (f"ICM wad {scenario}" if scenario else "ViZDoom's my_way_home.wad, placed")
            print(f"vizdoom random {task}: {record['vizdoom']}; Fisher p = {record['fisher_p']:.3g}", flush=True)
        record |= {"command": f"python experiments/random_rates.py {args.n_sim} {args.n_viz} --tasks {task}",
                   "date": time.strftime("%Y-%m-%d"), "wall_s": round(time.time() - began, 1)}
        (OUT / f"random-policy-{task}.json").write_text(json.dumps(record, indent=2) + "\n")


if __name__ == "__main__":
    main()
