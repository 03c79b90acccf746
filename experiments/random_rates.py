"""The uniform random policy's success on maze-dense in simjax and in real ViZDoom: a check of
the two worlds that involves no learning (starts, motion, the goal's touch rule, the timeout).

    python experiments/random_rates.py [SIMJAX_EPISODES] [VIZDOOM_EPISODES] [--task TASK]

Writes experiments/results/vizdoom-fidelity/random-policy.json. With ``--task`` another
MyWayHome task is measured in simjax only (the ViZDoom reference spawns as maze-dense does),
written to random-policy-TASK.json: the baseline a trained policy's success is set against."""
import argparse
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from simjax.envs import make  # noqa: E402
from simjax.envs.doom import vizdoom_ref  # noqa: E402

parser = argparse.ArgumentParser()
parser.add_argument("n_sim", nargs="?", type=int, default=2000)
parser.add_argument("n_viz", nargs="?", type=int, default=600)
parser.add_argument("--task", default="maze-dense")
args = parser.parse_args()
n_sim, n_viz, task = args.n_sim, args.n_viz, args.task
if n_sim < 1 or n_viz < 0:
    parser.error("SIMJAX_EPISODES must be positive and VIZDOOM_EPISODES not negative")
if task != "maze-dense" and n_viz:
    parser.error(f"the ViZDoom reference runs maze-dense only; give VIZDOOM_EPISODES 0 for {task}")
env = make(task)
CHUNK = 1000  # episodes per compiled batch: bounds the memory of the vmapped frames
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
print("simjax random", task, succ.mean(), f"({int(succ.sum())} of {n_sim})", flush=True)
rng = np.random.default_rng(7)
wins = 0
if task != "maze-dense":
    out = Path(__file__).resolve().parent / "results" / "vizdoom-fidelity" / f"random-policy-{task}.json"
    out.write_text(json.dumps({
        "task": task, "simjax": {"episodes": n_sim, "successes": int(succ.sum()),
                                 "success_ratio": float(succ.mean())},
        "command": f"python experiments/random_rates.py {n_sim} 0 --task {task}",
        "date": time.strftime("%Y-%m-%d"),
    }, indent=2) + "\n")
    raise SystemExit(0)
with vizdoom_ref.MyWayHome(seed=5, depth=False) as g:
    for i in range(n_viz):
        g.new_episode(seed=1000 + i)
        for _ in range(525):
            r, d = g.step(int(rng.integers(0, 4)))
            if d:
                break
        wins += r > 0
print("vizdoom random", wins / n_viz, n_viz, flush=True)
out = Path(__file__).resolve().parent / "results" / "vizdoom-fidelity" / "random-policy.json"
out.write_text(json.dumps({
    "task": "maze-dense", "simjax": {"episodes": n_sim, "success_ratio": float(succ.mean())},
    "vizdoom": {"episodes": n_viz, "success_ratio": wins / n_viz},
    "command": f"python experiments/random_rates.py {n_sim} {n_viz}", "date": time.strftime("%Y-%m-%d"),
}, indent=2) + "\n")
