"""The uniform random policy's success on maze-dense in simjax and in real ViZDoom: a check of
the two worlds that involves no learning (starts, motion, the goal's touch rule, the timeout).

    python experiments/random_rates.py [SIMJAX_EPISODES] [VIZDOOM_EPISODES]

Writes experiments/results/vizdoom-fidelity/random-policy.json."""
import json
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from simjax.envs import make  # noqa: E402
from simjax.envs.doom import vizdoom_ref  # noqa: E402

n_sim = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
n_viz = int(sys.argv[2]) if len(sys.argv) > 2 else 600
env = make("maze-dense")
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
succ = np.asarray(jax.jit(jax.vmap(one))(jax.random.split(jax.random.PRNGKey(123), n_sim)))
print("simjax random", succ.mean(), n_sim, flush=True)
rng = np.random.default_rng(7)
wins = 0
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
