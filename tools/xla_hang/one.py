"""One trial: the seed-vmapped init + run_chunk that hung in tests/test_agents.py
(test_update_shapes_determinism_and_seeds_vmap), in a fresh process, with the XLA flags of its
environment (XLA's defaults unless XLA_FLAGS says otherwise).

usage: python tools/xla_hang/one.py ALGO ENV NUM_ENVS [SEEDS]   (prints one JSON line at the end; phases as it goes)
HANG_ORTHOGONAL=flax draws the orthogonal initialisers with flax's own (under the seed vmap,
each one batched LAPACK QR: the init that hung); the default is simjax's
(``simjax.networks.layers.orthogonal``: member by member).
HANG_HLO=1 also reports how many __ynn_fusion ops XLA put into the two compiled programs.
"""

import faulthandler
import json
import os
import signal
import sys
import time

T0 = time.perf_counter()
faulthandler.register(signal.SIGUSR1, all_threads=True)  # the driver asks for stacks before killing a hung trial


def phase(name):
    print(f"PHASE {name} {time.perf_counter() - T0:.1f}", flush=True)


phase("import")
import flax.linen  # noqa: E402
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

import simjax.networks.actor_critic  # noqa: E402
import simjax.novelty.networks  # noqa: E402
from simjax.agents import TrainConfig, make_trainer  # noqa: E402
from simjax.runs.grid import batch_inputs, grid_of  # noqa: E402

algo, env, num_envs = sys.argv[1], sys.argv[2], int(sys.argv[3])
seeds = int(sys.argv[4]) if len(sys.argv) > 4 else 2
mode = os.environ.get("HANG_ORTHOGONAL", "simjax")
if mode == "flax":  # the modules look the name up when a network is initialised
    simjax.networks.actor_critic.orthogonal = simjax.novelty.networks.orthogonal = flax.linen.initializers.orthogonal
config = TrainConfig(env=env, algo=algo, num_envs=num_envs, rollout_len=5, total_steps=80, log_every=40,
                     learning_rate=1e-3, num_seeds=seeds)
trainer = make_trainer(config)
keys, hypers = batch_inputs(config, grid_of({}))
init = jax.jit(jax.vmap(trainer.init))
chunk = jax.jit(jax.vmap(trainer.run_chunk))
t_import = time.perf_counter() - T0

phase("init")  # compile + run of the seed-vmapped init (the call that hung)
t = time.perf_counter()
runner = jax.block_until_ready(init(keys, hypers))
t_init = time.perf_counter() - t

phase("chunk")  # compile + run of one seed-vmapped training chunk
t = time.perf_counter()
after, metrics = jax.block_until_ready(chunk(runner))
t_chunk = time.perf_counter() - t

phase("again")  # the test's second pass: cached executables, run only
t = time.perf_counter()
again, metrics2 = jax.block_until_ready(chunk(init(keys, hypers)))
t_again = time.perf_counter() - t
same = all(bool(jnp.array_equal(a, b)) for a, b in zip(jax.tree.leaves(after.params), jax.tree.leaves(again.params)))

ynn = None
if os.environ.get("HANG_HLO"):
    phase("hlo")
    ynn = (init.lower(keys, hypers).compile().as_text().count("__ynn_fusion"),
           chunk.lower(runner).compile().as_text().count("__ynn_fusion"))

phase("done")
print(
    "RESULT "
    + json.dumps(
        dict(
            orthogonal=mode,
            seeds=seeds,
            xla_flags=os.environ.get("XLA_FLAGS", ""),
            async_dispatch=bool(jax.config.read("jax_cpu_enable_async_dispatch")),
            t_import=round(t_import, 2),
            t_init=round(t_init, 2),
            t_chunk=round(t_chunk, 2),
            t_again=round(t_again, 2),
            t_total=round(time.perf_counter() - T0, 2),
            deterministic=same,
            ynn_fusions=ynn,
            loss_finite=bool(jnp.all(jnp.isfinite(jnp.stack([jnp.asarray(v) for v in metrics.values()])))),
        )
    ),
    flush=True,
)
