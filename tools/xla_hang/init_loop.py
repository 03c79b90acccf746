"""The hang experiment of issue 22, in one process: a seed-vmapped ``init`` called again and again.

    python tools/xla_hang/init_loop.py ALGO SEEDS CALLS [TIMEOUT_S]

HANG_ORTHOGONAL=flax draws the orthogonal initialisers with flax's own (each one batched LAPACK
QR under the vmap: the init that hung); the default is simjax's, member by member. Each call
gets new keys, so each runs the program again, with the XLA flags of the environment. Prints
one JSON line: the calls done, and whether one of them made no progress for TIMEOUT_S seconds
(then the process ends itself with status 3, a deadlock).
"""

import json
import os
import sys
import threading
import time

import flax.linen
import jax
import numpy as np

import simjax.networks.actor_critic
import simjax.novelty.networks
from simjax.agents import TrainConfig, make_trainer
from simjax.runs.grid import batch_inputs, grid_of

algo, seeds, calls = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
timeout = float(sys.argv[4]) if len(sys.argv) > 4 else 60.0
mode = os.environ.get("HANG_ORTHOGONAL", "simjax")
if mode == "flax":  # the modules look the name up when a network is initialised
    simjax.networks.actor_critic.orthogonal = simjax.novelty.networks.orthogonal = flax.linen.initializers.orthogonal
config = TrainConfig(env="maze-very-sparse", algo=algo, num_seeds=seeds)
trainer = make_trainer(config)
keys, hypers = batch_inputs(config, grid_of({}))
init = jax.jit(jax.vmap(trainer.init))
state = {"call": -1, "since": time.time()}


def watch():
    while True:
        time.sleep(1.0)
        if time.time() - state["since"] > timeout:
            print(json.dumps({"orthogonal": mode, "algo": algo, "seeds": seeds, "calls_done": state["call"],
                              "hung": True, "flags": os.environ.get("XLA_FLAGS", "")}), flush=True)
            os._exit(3)


threading.Thread(target=watch, daemon=True).start()
started = time.time()
for i in range(calls):
    state["call"], state["since"] = i, time.time()
    fresh = keys + np.uint32(i * seeds)  # other keys each call: the program runs again
    jax.block_until_ready(init(fresh, hypers))
print(json.dumps({"orthogonal": mode, "algo": algo, "seeds": seeds, "calls_done": calls, "hung": False,
                  "seconds": round(time.time() - started, 1), "flags": os.environ.get("XLA_FLAGS", "")}), flush=True)
