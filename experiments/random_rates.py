"""The uniform random policy's success on a MyWayHome task in simjax and in real ViZDoom: a check
of the two worlds that involves no learning (starts, motion, the goal's touch rule, the
timeout), and the baseline a trained policy's success is set against.

    python experiments/random_rates.py [SIMJAX_EPISODES] [VIZDOOM_EPISODES] [--task TASK]

TASK is maze-dense (the default; its starts are the scenario's random spot and angle),
maze-sparse or maze-very-sparse (their fixed starts, placed in ViZDoom as
``simjax.envs.doom.vizdoom_ref.TASK_STARTS`` does). Writes
experiments/results/vizdoom-fidelity/random-policy.json for maze-dense and
random-policy-TASK.json for the others."""
import argparse
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from simjax.envs import make
from simjax.envs.doom import vizdoom_ref

parser = argparse.ArgumentParser()
parser.add_argument("n_sim", nargs="?", type=int, default=2000)
parser.add_argument("n_viz", nargs="?", type=int, default=600)
parser.add_argument("--task", default="maze-dense", choices=sorted(vizdoom_ref.TASK_STARTS))
args = parser.parse_args()
n_sim, n_viz, task = args.n_sim, args.n_viz, args.task
if n_sim < 1 or n_viz < 0:
    parser.error("SIMJAX_EPISODES must be positive and VIZDOOM_EPISODES not negative")
env = make(task)
CHUNK = 1000  # episodes per compiled batch: bounds the memory of the vmapped states


def one(key):
    k0, k1 = jax.random.split(key)
    s = env.reset(k0)
    acts = jax.random.randint(k1, (525,), 0, 4)

    def body(c, a):
        s, done, succ = c
        s = env.step(s, a)
        first = (s.metrics["episode_done"] > 0) & ~done
        return (s, done | first, jnp.where(first, s.metrics["episode_success"], succ)), None

    (s, done, succ), _ = jax.lax.scan(body, (s, jnp.bool_(False), jnp.float32(0)), acts)
    return succ


batch = jax.jit(jax.vmap(one))
keys = jax.random.split(jax.random.PRNGKey(123), n_sim)
succ = np.concatenate([np.asarray(batch(keys[i:i + CHUNK])) for i in range(0, n_sim, CHUNK)])
print(f"simjax random {task}: {succ.mean():.4f} ({int(succ.sum())} of {n_sim})", flush=True)

rng = np.random.default_rng(7)
wins = 0
start = vizdoom_ref.TASK_STARTS[task]
if n_viz:
    with vizdoom_ref.MyWayHome(seed=5, depth=False) as g:
        for i in range(n_viz):
            g.new_episode(start=start, seed=1000 + i)
            for _ in range(525):
                r, d = g.step(int(rng.integers(0, 4)))
                if d:
                    break
            wins += r > 0
    print(f"vizdoom random {task}: {wins / n_viz:.4f} ({int(wins)} of {n_viz})", flush=True)
name = "random-policy.json" if task == "maze-dense" else f"random-policy-{task}.json"
record = {"task": task, "simjax": {"episodes": n_sim, "successes": int(succ.sum()), "success_ratio": float(succ.mean())}}
if n_viz:
    record["vizdoom"] = {"episodes": n_viz, "successes": int(wins), "success_ratio": wins / n_viz}
command = f"python experiments/random_rates.py {n_sim} {n_viz}" + ("" if task == "maze-dense" else f" --task {task}")
out = Path(__file__).resolve().parent / "results" / "vizdoom-fidelity" / name
out.write_text(json.dumps(record | {"command": command, "date": time.strftime("%Y-%m-%d")}, indent=2) + "\n")
