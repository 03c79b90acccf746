"""``make bench``: renderer and training-loop throughput, written to BENCHMARKS.md.

Measures, each as the median of several calls of one compiled program (compile time apart):
- the environment alone (Doom's motion, 4 tics, plus one render per agent step, random
  actions, auto-reset) at 16 and 48 environments (what a run of 1 and 3 seeds steps), 256,
  1024 and 4096, as agent steps per second; at 1024 environments the same MyWayHome task drawn
  with the invented looks instead of the Freedoom textures, and ``melon`` and ``explore-goals``;
- maze generation alone, as mazes per second: ``explore-goals``' DMLab maze (11x11 text cells:
  rooms, depth-first corridors, connections, dead-end and horseshoe removal, spawn and goal
  cells, looks, walls and boxes) with its share of the ``explore-goals`` env's time (one maze
  per env per 1350-step episode: the env generates only on steps where an episode ends, see
  ``explore_goals.regenerate_where_done``), and ``explore-goals-paper``'s spanning-tree maze for
  9x9 and 11x11 cells;
- the full A2C training loop (rollout + loss + gradient + Adam, K updates in one call) for one
  seed, as agent steps per second, with XLA's own FLOP count per agent step and the share of
  the machine's measured float32 matmul peak that gives;
- the same loop with each novelty model (SIM at H=10, L=3, the paper's sizes; RND; ICM; EC with
  its ResNet-18 and 200-slot memories, its network fixed as after pretraining), with the novelty
  model's FLOPs added, and the novelty model's forward+backward on one rollout (EC's forward:
  its network is not trained during the run), timed alone, against the whole update;
- the training loop exactly as ``make train`` runs it (``bench_loop``): 1, 2, 3 and 4 seeds of
  16 envs each for SIM, RND, ICM, EC and A2C, with its share of the matmul peak;
- where one update's time goes, per method (``bench_parts``): env steps, acting, the rollout,
  the novelty model's and the A2C loss's forward+backward, the optimiser, each timed alone;
- EC's pretraining alone: Adam updates of its reachability network on batches of 64 pairs;
- a sweep's padding overhead: SIM's loop for L = 1..5 (H = 10) as one 5-member program with
  windows laid out for L = 5, against the 5 programs built each for its own L, run one after
  the other (what 5 separate runs do).
- Gymnasium's API (``bench_gymnasium``): simjax's vector env (``simjax.gymnasium_env``, N envs
  in one jitted call, numpy in and out, next-step autoreset) at 1, 16 and 256 envs, against
  ViZDoom's own Gymnasium env ``VizdoomMyWayHome-v1`` at the same 4 tics per agent step, one env
  and one per core (``AsyncVectorEnv``), random actions, in the same run.
``--only devices`` compares 2 SIM seeds on one CPU device with the same sharded over two
(``--xla_force_host_platform_device_count=2``), each in a fresh process. ``--only compile``
times the compiles of the two programs a run starts with, the seed-vmapped ``init`` and the
chunk, for each method at 16 envs and 3 seeds. ``--only ec`` runs EC's two costs alone: its
loop at 3 seeds (what its runs train) and its pretraining's updates. ``--only loop`` runs the
training loop's rows alone, for the seed counts in ``--seeds`` (e.g. ``1,16,48`` on a GPU).

Everything runs at ``--precision`` (a run's default unless given; ``simjax.runtime``), and each
section names the machine's devices, the JAX version and that precision, so a GPU's sections sit
beside the CPU's.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp

from simjax import runtime
from simjax.agents import TrainConfig, make_trainer
from simjax.envs import TASK_NAMES, make


def time_call(fn, *args, repeats: int = 5):
    """(compile seconds, median seconds per call, all timings) of a jitted ``fn(*args)``."""
    t0 = time.perf_counter()
    compiled = jax.jit(fn).lower(*args).compile()
    compile_s = time.perf_counter() - t0
    jax.block_until_ready(compiled(*args))  # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(compiled(*args))
        times.append(time.perf_counter() - t0)
    return compile_s, statistics.median(times), times


def machine_line(peak: float, precision: str) -> str:
    """What the numbers were measured on: cores, devices, JAX, the matmul precision, the peak."""
    devices = jax.devices()
    kinds = ", ".join(sorted({d.device_kind for d in devices}))
    return (f"Machine: {os.cpu_count()} cores, {platform.machine()}; {len(devices)} {jax.default_backend()} "
            f"device(s): {kinds}; jax {jax.__version__}; matmul precision {precision}; "
            f"float32 2048x2048 matmul peak measured now at that precision: {peak / 1e9:.0f} GFLOP/s.")


def matmul_peak(n: int = 2048, repeats: int = 5) -> float:
    a = jax.random.normal(jax.random.PRNGKey(0), (n, n), jnp.float32)
    _, med, _ = time_call(lambda x: x @ x, a, repeats=repeats)
    return 2 * n**3 / med


def bench_env(task, num_envs: int, steps: int = 64) -> dict:
    """``task``: a task name or an env."""
    env = make(task) if isinstance(task, str) else task
    state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), num_envs))

    def run(state, key):
        def body(s, k):
            s = jax.vmap(env.step)(s, jax.random.randint(k, (num_envs,), 0, env.action_size))
            return s, None
        return jax.lax.scan(body, state, jax.random.split(key, steps))[0]

    compile_s, med, _ = time_call(run, state, jax.random.PRNGKey(1))
    return {"envs": num_envs, "steps_per_s": num_envs * steps / med, "compile_s": compile_s}


def bench_maze_generation(cells: int | None, num: int = 1024) -> dict:
    """``cells`` None: explore-goals' DMLab maze; else the paper variant's maze of cells x cells."""
    from simjax.envs.dmlab.explore_goals import DMLabMazeGenerator, MazeGenerator

    gen = DMLabMazeGenerator() if cells is None else MazeGenerator(cells=cells)
    keys = jax.random.split(jax.random.PRNGKey(0), num)
    compile_s, med, _ = time_call(jax.vmap(gen.generate), keys)
    return {"cells": cells, "mazes_per_s": num / med, "compile_s": compile_s}


def _xla_flops(fn, *args) -> float:
    cost = jax.jit(fn).lower(*args).compile().cost_analysis()
    cost = cost[0] if isinstance(cost, (list, tuple)) else cost
    return float(cost.get("flops", float("nan")))


def flops_per_agent_step(trainer, runner, config) -> float:
    """XLA's FLOP count per agent step of the training loop.

    XLA's cost analysis counts a while-loop body once, and the rollout and the LSTM are
    scans, so a whole update undercounts. A network step on a (1, N) batch has one-iteration
    loops and is counted exactly: each agent step costs one forward (acting) plus (T+1)/T
    forward+backward passes (learning on T frames and the bootstrap frame). The n-step
    return scan and Adam add well under 1% and are left out.
    """
    net = trainer.network
    obs, reset = runner.env_state.obs[None], jnp.zeros((1, config.num_envs), bool)
    carry = net.initial_carry(config.num_envs)

    def forward(params):
        _, logits, value = net.apply(params, carry, obs, reset)
        return logits.sum() + value.sum()

    policy = runner.params["policy"]
    fwd = _xla_flops(forward, policy) / config.num_envs
    fwd_bwd = _xla_flops(jax.grad(forward), policy) / config.num_envs
    return fwd + fwd_bwd * (config.rollout_len + 1) / config.rollout_len


def bench_train(task: str, num_envs: int, updates: int = 8) -> dict:
    config = TrainConfig(env=task, num_envs=num_envs, total_steps=num_envs * 20 * updates,
                         log_every=num_envs * 20 * updates)
    trainer = make_trainer(config)
    runner = jax.jit(trainer.init)(jax.random.PRNGKey(0))
    compile_s, med, _ = time_call(trainer.run_chunk, runner, repeats=3)
    steps = config.updates_per_log * config.steps_per_update
    return {"envs": num_envs, "steps_per_s": steps / med, "compile_s": compile_s,
            "flops_per_step": flops_per_agent_step(trainer, runner, config)}


def _lstm_step_flops(batch: int, inputs: int, hidden: int) -> float:
    """Forward FLOPs of one LSTM step (4 gates, matmuls only)."""
    return 2.0 * batch * (inputs + hidden) * 4 * hidden


def novelty_flops_per_agent_step(trainer, runner, config, batch) -> float:
    """XLA's FLOP count of the novelty model's forward+backward on one rollout, per agent step.

    SIM's two LSTMs are scans, which XLA's cost analysis counts once; the H-1 and L-1 steps it
    misses are added from the LSTM's matmul count (forward + backward = 3x forward).
    """
    novelty, params = trainer.novelty, runner.params["novelty"]

    def loss(p):
        return novelty.loss_and_bonus(p, runner.novelty, *batch)[0]

    flops = _xla_flops(jax.grad(loss), params)
    if config.algo == "sim" and config.sim_sequence == "lstm":
        # the input projections run once per frame, outside the scans; only h W_hh is inside
        windows = config.rollout_len * config.num_envs
        missed = (config.obs_len - 1 + config.act_len - 1) * _lstm_step_flops(windows, 0, 256)
        flops += 3.0 * missed
    return flops / config.steps_per_update


def ec_flops_per_agent_step(trainer, runner, config, batch) -> float:
    """XLA's FLOP count of EC's bonus on one rollout (every frame embedded once, then compared
    with the memory step by step), per agent step. The memory comparison is a scan over T that
    XLA's cost analysis counts once; the T-1 steps it misses are added from their count: per
    environment and slot, the add and ReLU of the split first fc (2 hidden) and the fc 2
    (4 hidden)."""
    novelty, params = trainer.novelty, runner.params["novelty"]

    def bonus(p):
        return novelty.loss_and_bonus(p, runner.novelty, *batch)[1][0].sum()

    missed = (config.rollout_len - 1) * config.num_envs * config.ec_memory * 6.0 * config.ec_embed
    return (_xla_flops(bonus, params) + missed) / config.steps_per_update


def bench_novelty(task: str, algo: str, num_envs: int = 16, updates: int = 8, **settings) -> dict:
    if algo == "ec":  # the policy's training loop, after pretraining (timed alone: bench_ec_pretraining)
        settings = {"ec_pretrain_steps": 0, **settings}
    config = TrainConfig(env=task, algo=algo, num_envs=num_envs, total_steps=num_envs * 20 * updates,
                         log_every=num_envs * 20 * updates, **settings)
    trainer = make_trainer(config)
    runner = jax.jit(trainer.init)(jax.random.PRNGKey(0))
    compile_s, med, _ = time_call(trainer.run_chunk, runner, repeats=3)
    steps = config.updates_per_log * config.steps_per_update
    # one rollout's worth of frames for the novelty model alone
    T, N = config.rollout_len, num_envs
    obs = jnp.broadcast_to(runner.env_state.obs, (T,) + runner.env_state.obs.shape)
    actions = jax.random.randint(jax.random.PRNGKey(1), (T, N), 0, 4)
    batch = (obs, jnp.zeros((T, N), bool), actions, runner.env_state.obs, jnp.zeros((N,), bool))
    if algo == "ec" and not config.ec_online:  # fixed network: the bonus's forward is all it costs
        work = lambda p: trainer.novelty.loss_and_bonus(p, runner.novelty, *batch)[1][0]
        nov_flops = ec_flops_per_agent_step(trainer, runner, config, batch)
    else:
        work = jax.grad(lambda p: trainer.novelty.loss_and_bonus(p, runner.novelty, *batch)[0])
        nov_flops = novelty_flops_per_agent_step(trainer, runner, config, batch)
    _, novelty_s, _ = time_call(work, runner.params["novelty"])
    a2c_flops = flops_per_agent_step(trainer, runner, config)
    return {"algo": algo, "envs": num_envs, "steps_per_s": steps / med, "compile_s": compile_s,
            "flops_per_step": a2c_flops + nov_flops, "novelty_share": novelty_s / (med / config.updates_per_log)}


def bench_parts(task: str, algo: str, seeds: int = 1, num_envs: int = 16, updates: int = 8) -> dict:
    """Where one update's time goes, for ``seeds`` seeds vmapped as the commands run them: each
    part run ``updates`` times in a ``lax.scan`` inside one compiled call (the context it has in
    the training loop), timed apart, against the whole update (``run_chunk``):
    env (N envs stepped T times, random actions), acting (the policy's forward on one frame per
    env, T times), rollout (both, as ``collect``), novelty (the novelty model's loss and bonus,
    forward+backward; EC's bonus forward), a2c (the A2C loss alone, forward+backward), optimizer
    (clipping and Adam on the gradients). Seconds per update, and XLA's FLOPs per update for the
    parts that hold no loop."""
    extra = {"ec_pretrain_steps": 0} if algo == "ec" else {}
    config = TrainConfig(env=task, algo=algo, num_envs=num_envs, num_seeds=seeds, total_steps=num_envs * 20 * updates,
                         log_every=num_envs * 20 * updates, **extra)
    from simjax.agents import a2c_loss
    from simjax.envs.episodes import starts_episode
    from simjax.runs.grid import batch_inputs, grid_of

    trainer = make_trainer(config)
    env = make(task)
    T, N, K = config.rollout_len, num_envs, config.updates_per_log
    runners = jax.jit(jax.vmap(trainer.init))(*batch_inputs(config, grid_of({})))
    _, _, _, traj = jax.jit(jax.vmap(trainer.collect))(runners)
    last_obs, last_reset = runners.env_state.obs, starts_episode(runners.env_state)

    def scanned(part):  # part(runner, traj, i) -> pytree; K times in one scan, per member
        def run(r, tr, lo, lr):
            def body(acc, i):
                out = part(r, tr, lo, lr, i)
                return acc + sum(jnp.sum(x).astype(jnp.float32) for x in jax.tree.leaves(out)), None
            return jax.lax.scan(body, jnp.float32(0.0), jnp.arange(K))[0]
        return jax.vmap(run)

    def env_part(r, tr, lo, lr, i):
        def body(s, k):
            return jax.vmap(env.step)(s, jax.random.randint(k, (N,), 0, env.action_size)), None
        keys = jax.random.split(jax.random.fold_in(r.key, i), T)
        return jax.lax.scan(body, r.env_state, keys)[0].obs

    def acting_part(r, tr, lo, lr, i):
        def body(c, o):
            c, logits, _ = trainer.network.apply(r.params["policy"], c, o[None], jnp.zeros((1, N), bool))
            return c, logits
        return jax.lax.scan(body, r.carry, tr.obs + i.astype(jnp.uint8))[1]

    def rollout_part(r, tr, lo, lr, i):
        return trainer.collect(r._replace(key=jax.random.fold_in(r.key, i)))[3].reward

    def novelty_grad(p, r, tr, lo, lr):
        return trainer.novelty.loss_and_bonus(p, r.novelty, tr.obs, tr.reset, tr.action, lo, lr, r.hyper.novelty)

    def novelty_part(r, tr, lo, lr, i):
        if algo == "ec" and not config.ec_online:
            return novelty_grad(r.params["novelty"], r, tr, lo, lr)[1][0]
        return jax.grad(lambda p: novelty_grad(p, r, tr, lo, lr)[0])(r.params["novelty"])

    def a2c_part(r, tr, lo, lr, i):
        bonus = jnp.zeros(tr.reward.shape) + i.astype(jnp.float32)
        return jax.grad(lambda p: a2c_loss(p, trainer.network, r.carry, tr, lo, lr, bonus, config, r.hyper)[0])(
            r.params["policy"])

    def optimizer_part(r, tr, lo, lr, i):
        grads = jax.tree.map(lambda x: x + i.astype(x.dtype), r.params)
        return trainer.optimizer(r.hyper).update(grads, r.opt_state, r.params)

    args = (runners, traj, last_obs, last_reset)
    results = {}
    for name, part in (("env", env_part), ("acting", acting_part), ("rollout", rollout_part),
                       ("novelty", novelty_part), ("a2c", a2c_part), ("optimizer", optimizer_part)):
        if name == "novelty" and algo == "a2c":
            continue
        _, med, _ = time_call(scanned(part), *args, repeats=3)
        results[name] = med / K
    _, med, _ = time_call(jax.vmap(trainer.run_chunk), runners, repeats=3)
    results["update"] = med / K
    return {"algo": algo, "seeds": seeds, "envs": num_envs, "seconds": results,
            "agent_steps_per_s": seeds * config.steps_per_update / results["update"]}


def _sweep_chunk(config: TrainConfig, sweep: dict):
    """A jitted chunk of a sweep's members and the runner state it starts from."""
    from simjax.runs.grid import batch_inputs, check_sweep

    config, grid = check_sweep(dict(config.__dict__), sweep)
    trainer = make_trainer(config)
    runner = jax.jit(jax.vmap(trainer.init))(*batch_inputs(config, grid))
    return _members_chunk(trainer), runner


def _members_chunk(trainer):
    """The chunk of every member (``vmap``), with its metric summary, as the commands run it."""
    from simjax.agents import summarize

    return lambda r: jax.vmap(lambda x: (lambda out: (out[0], summarize(out[1])))(trainer.run_chunk(x)))(r)


def bench_sweep(task: str, values=(1, 2, 3, 4, 5), num_envs: int = 16, updates: int = 4) -> dict:
    """Agent steps/s of one program sweeping L over ``values`` against one program per L."""
    base = TrainConfig(env=task, algo="sim", num_envs=num_envs, total_steps=num_envs * 20 * updates,
                       log_every=num_envs * 20 * updates)
    steps = base.updates_per_log * base.steps_per_update
    chunk, runner = _sweep_chunk(base, {"act_len": list(values)})
    compile_s, med, _ = time_call(chunk, runner, repeats=3)
    separate_s, separate_compile = 0.0, 0.0
    for L in values:
        chunk, runner = _sweep_chunk(base, {"act_len": [L]})
        c, m, _ = time_call(chunk, runner, repeats=3)
        separate_s, separate_compile = separate_s + m, separate_compile + c
    n = len(values)
    return {"points": n, "envs": num_envs, "sweep_steps_per_s": n * steps / med, "sweep_compile_s": compile_s,
            "separate_steps_per_s": n * steps / separate_s, "separate_compile_s": separate_compile}


def bench_loop(task: str, algo: str, seeds: int, num_envs: int = 16, updates: int = 8) -> dict:
    """The training loop exactly as ``python -m simjax.train`` runs it: ``seeds`` seeds of N envs
    each, initialised by ``init_members``, one jitted ``vmap`` of the chunk (with its metric
    summary), on this process's devices; agent steps/s over all seeds. EC's row is its policy
    loop after pretraining."""
    extra = {"ec_pretrain_steps": 0} if algo == "ec" else {}
    config = TrainConfig(env=task, algo=algo, num_envs=num_envs, num_seeds=seeds,
                         total_steps=num_envs * 20 * updates, log_every=num_envs * 20 * updates, **extra)
    chunk, runner = _sweep_chunk(config, {})
    compile_s, med, _ = time_call(chunk, runner, repeats=3)
    steps = config.updates_per_log * config.steps_per_update * seeds
    return {"algo": algo, "seeds": seeds, "envs": num_envs, "steps_per_s": steps / med, "compile_s": compile_s}


def bench_compile(task: str, algo: str, seeds: int = 3, num_envs: int = 16) -> dict:
    """Compile seconds of the two programs ``python -m simjax.train`` compiles for a run: the
    seed-vmapped trainer ``init`` and the chunk (EC's policy loop; its pretraining is not here)."""
    from simjax.runs.grid import batch_inputs, grid_of

    extra = {"ec_pretrain_steps": 0} if algo == "ec" else {}
    config = TrainConfig(env=task, algo=algo, num_envs=num_envs, num_seeds=seeds,
                         total_steps=num_envs * 20 * 8, log_every=num_envs * 20 * 8, **extra)
    trainer = make_trainer(config)
    inputs = batch_inputs(config, grid_of({}))
    t0 = time.perf_counter()
    init = jax.jit(jax.vmap(trainer.init)).lower(*inputs).compile()
    init_s = time.perf_counter() - t0
    runner = init(*inputs)
    t0 = time.perf_counter()
    jax.jit(_members_chunk(trainer)).lower(runner).compile()
    return {"algo": algo, "seeds": seeds, "envs": num_envs, "init_s": init_s, "chunk_s": time.perf_counter() - t0}


def compile_lines(results: list[dict]) -> list[str]:
    lines = ["Compile seconds of what `make train` compiles for a run (16 envs per seed, 3 seeds, one "
             "process, no persistent cache; EC without its pretraining's programs):", "",
             "| method | init s | chunk s |", "|---|---:|---:|"]
    return lines + [f"| {r['algo'].upper()} | {r['init_s']:.1f} | {r['chunk_s']:.1f} |" for r in results]


def devices_probe(task: str, seeds: int = 2, num_envs: int = 16, updates: int = 4) -> dict:
    """In this process: SIM's loop for ``seeds`` seeds, sharded over every local device."""
    from simjax.runs.training import batch_sharding

    config = TrainConfig(env=task, algo="sim", num_envs=num_envs, num_seeds=seeds,
                         total_steps=num_envs * 20 * updates, log_every=num_envs * 20 * updates)
    chunk, runner = _sweep_chunk(config, {})
    sharding = batch_sharding(seeds)
    if sharding is not None:
        runner = jax.device_put(runner, sharding)
    compile_s, med, _ = time_call(chunk, runner, repeats=3)
    steps = config.updates_per_log * config.steps_per_update * seeds
    return {"devices": len(jax.local_devices()), "seeds": seeds, "steps_per_s": steps / med, "compile_s": compile_s}


def bench_devices(task: str, precision: str) -> list[dict]:
    """``devices_probe`` in fresh processes with one CPU device and with two."""
    results = []
    for n in (1, 2):
        env = os.environ | {"XLA_FLAGS": (os.environ.get("XLA_FLAGS", "")
                                          + f" --xla_force_host_platform_device_count={n}").strip()}
        out = subprocess.run([sys.executable, __file__, "--devices-probe", "--task", task, "--precision", precision],
                             env=env, check=True,
                             capture_output=True, text=True).stdout
        results.append(json.loads(out.strip().splitlines()[-1]))
    return results


def bench_ec_pretraining(task: str, num_envs: int = 16, updates: int = 4, **settings) -> dict:
    """EC's pretraining: Adam updates of the reachability network (batches of 64 pairs) on a
    chunk of random-policy frames, as pairs per second, and XLA's FLOPs per pair (the update
    scan's body, counted once, is one update)."""
    from simjax.novelty.ec_pretrain import Pretrainer
    from simjax.novelty.settings import PretrainPlan

    config = TrainConfig(env=task, algo="ec", num_envs=num_envs, **settings)
    trainer = make_trainer(config)
    runner = jax.jit(trainer.init)(jax.random.PRNGKey(0))
    plan = PretrainPlan(chunk_len=100, num_chunks=1, calls=1, updates_per_call=updates, num_envs=num_envs)
    pre = Pretrainer(make(task), trainer.novelty.model, plan)
    state = jax.jit(pre.collect)(jax.jit(pre.init)(jax.random.PRNGKey(1), runner.params["novelty"]))
    compile_s, med, _ = time_call(pre.train, state, repeats=3)
    return {"pairs_per_s": updates * pre.batch / med, "compile_s": compile_s,
            "flops_per_pair": _xla_flops(pre.train, state) / pre.batch}


def _gym_steps_per_s(step, num_envs: int, min_seconds: float, min_calls: int) -> float:
    """Agent steps/s of ``step()`` (one call steps ``num_envs`` envs), called for at least
    ``min_calls`` calls and ``min_seconds`` seconds."""
    calls, t0 = 0, time.perf_counter()
    while calls < min_calls or time.perf_counter() - t0 < min_seconds:
        step()
        calls += 1
    return num_envs * calls / (time.perf_counter() - t0)


def bench_gymnasium(task: str = "maze-dense", env_counts=(1, 16, 256), min_seconds: float = 5.0,
                    min_calls: int = 20) -> list[dict]:
    """Agent steps/s through Gymnasium's API, as a Gymnasium user steps: random actions drawn on
    the host each call, numpy in and out, episodes restarted as Gymnasium says.

    - simjax: ``gymnasium.make_vec(ID, num_envs=N)``, the vector env of ``simjax.gymnasium_env``
      (all N envs in one jitted call; next-step autoreset), for each N in ``env_counts``;
      ``compile_s`` is its first reset and step, compile included;
    - ViZDoom: its own Gymnasium env ``VizdoomMyWayHome-v1`` with ``frame_skip=4`` (simjax's 4
      tics per agent step), otherwise the scenario as shipped (320x240 screen, its 5 buttons as
      ``Discrete(6)``, 2100-tic episodes): one env (``gymnasium.make``, reset by hand at an
      episode's end), and one env per core in Gymnasium's ``AsyncVectorEnv`` (a process each).
    ``task`` picks simjax's task (a MyWayHome one; others fall back to ``maze-dense``)."""
    import gymnasium
    import numpy as np
    import vizdoom.gymnasium_wrapper  # noqa: F401  (registers VizdoomMyWayHome-v1)

    from simjax import gymnasium_env

    task = task if task in gymnasium_env.ENV_IDS else "maze-dense"
    rng = np.random.default_rng(0)
    rows = []
    for n in env_counts:
        envs = gymnasium.make_vec(gymnasium_env.ENV_IDS[task], num_envs=n)
        actions = lambda envs=envs, n=n: rng.integers(0, envs.single_action_space.n, size=n)
        t0 = time.perf_counter()
        envs.reset(seed=0)
        envs.step(actions())
        compile_s = time.perf_counter() - t0
        rate = _gym_steps_per_s(lambda envs=envs, a=actions: envs.step(a()), n, min_seconds, min_calls)
        rows.append({"what": f"simjax `{gymnasium_env.ENV_IDS[task]}`, vector env", "envs": n, "steps_per_s": rate,
                     "compile_s": compile_s})
        envs.close()

    env = gymnasium.make("VizdoomMyWayHome-v1", frame_skip=4)
    env.reset(seed=0)

    def vizdoom_step():
        _, _, terminated, truncated, _ = env.step(int(rng.integers(0, env.action_space.n)))
        if terminated or truncated:
            env.reset()

    rows.append({"what": "ViZDoom `VizdoomMyWayHome-v1`, frame_skip=4", "envs": 1,
                 "steps_per_s": _gym_steps_per_s(vizdoom_step, 1, min_seconds, min_calls), "compile_s": None})
    env.close()
    n = os.cpu_count() or 1
    # spawned, not forked: this process runs JAX's threads
    envs = gymnasium.make_vec("VizdoomMyWayHome-v1", num_envs=n, vectorization_mode="async",
                              vector_kwargs={"context": "spawn"}, frame_skip=4)
    envs.reset(seed=0)
    step = lambda: envs.step(rng.integers(0, envs.single_action_space.n, size=n))
    rows.append({"what": "ViZDoom `VizdoomMyWayHome-v1`, frame_skip=4, `AsyncVectorEnv` (a process per env)", "envs": n,
                 "steps_per_s": _gym_steps_per_s(step, n, min_seconds, min_calls), "compile_s": None})
    envs.close()
    return rows


def gymnasium_lines(rows: list[dict]) -> list[str]:
    """``bench_gymnasium``'s rows: one table, simjax's vector env and ViZDoom side by side."""
    vizdoom = next(r for r in rows if r["what"].startswith("ViZDoom") and r["envs"] == 1)["steps_per_s"]
    lines = ["Through Gymnasium's API (`bench_gymnasium`: random actions drawn on the host each call, numpy in and out, "
             "episodes restarted as Gymnasium says; 4 tics per agent step in both):", "",
             "| env | envs | agent steps/s | x one ViZDoom env | compile s |", "|---|---:|---:|---:|---:|"]
    for r in rows:
        compile_s = "" if r["compile_s"] is None else f"{r['compile_s']:.1f}"
        lines.append(f"| {r['what']} | {r['envs']} | {r['steps_per_s']:,.0f} | {r['steps_per_s'] / vizdoom:.1f} | {compile_s} |")
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", type=Path, default=None, help="Markdown file to append the results to")
    parser.add_argument("--task", default="maze-dense")
    parser.add_argument("--devices-probe", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--only", choices=("sweep", "devices", "gymnasium", "compile", "ec", "loop", "precision"),
                        default=None,
                        help="run only the sweep-overhead, the device-count, the Gymnasium, the compile-time, "
                             "EC's rows (its loop at 3 seeds, its pretraining's updates), the training loop's, or "
                             "the training loop's at highest and at bfloat16 side by side (precision)")
    parser.add_argument("--seeds", default="1,2,3,4", help="--only loop, precision: the seed counts (default 1,2,3,4)")
    parser.add_argument("--algos", default=",".join(LOOP_ALGOS), help="--only precision: the methods")
    parser.add_argument("--precision", choices=tuple(runtime.MATMUL_PRECISIONS), default=TrainConfig.precision,
                        help=f"float32 matmul precision, as simjax.train's (default: {TrainConfig.precision})")
    args = parser.parse_args(argv)
    with runtime.matmul_precision(args.precision):
        if args.devices_probe:
            print(json.dumps(devices_probe(args.task)))
            return 0
        if args.only:
            return report_only(args)
        return report_all(args)


def report_all(args) -> int:
    """Every measurement, as one section."""

    started = time.time()
    peak = matmul_peak()
    envs = [bench_env(args.task, n) for n in (16, 48, 256, 1024, 4096)]  # 16 per seed: what a run steps
    invented = None
    if f"{args.task}-invented-looks" in TASK_NAMES:
        # the same task drawn with raycaster's invented looks, as before the Freedoom textures
        invented = bench_env(f"{args.task}-invented-looks", 1024)
    worlds = {task: bench_env(task, 1024) for task in ("melon", "explore-goals")}
    world_trains = {task: bench_train(task, 16) for task in ("melon", "explore-goals")}
    mazes = [bench_maze_generation(c) for c in (None, 9, 11)]
    trains = [bench_train(args.task, 16)]
    novelties = [bench_novelty(args.task, algo) for algo in ("sim", "rnd", "icm", "ec")]
    ec_pretraining = bench_ec_pretraining(args.task)
    sweep = bench_sweep(args.task)
    loops = [bench_loop(args.task, algo, seeds) for algo in LOOP_ALGOS for seeds in (1, 2, 3, 4)]
    parts = [bench_parts(args.task, algo) for algo in LOOP_ALGOS]
    gym_rows = bench_gymnasium(args.task)
    lines = [
        f"## {dt.date.today().isoformat()}: `make bench` ({args.task})",
        "",
        machine_line(peak, args.precision),
        "",
        "| what | envs | agent steps/s | compile s | FLOPs / agent step | share of matmul peak |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for r in envs:
        lines.append(f"| environment (motion + render) | {r['envs']} | {r['steps_per_s']:,.0f} | {r['compile_s']:.1f} | | |")
    if invented:
        r = invented
        lines.append(f"| environment, invented looks (no textures) | {r['envs']} | {r['steps_per_s']:,.0f} | {r['compile_s']:.1f} | | |")
    for task, r in worlds.items():
        lines.append(f"| environment, `{task}` | {r['envs']} | {r['steps_per_s']:,.0f} | {r['compile_s']:.1f} | | |")
    for r in trains:
        share = r["flops_per_step"] * r["steps_per_s"] / peak
        lines.append(
            f"| A2C training loop | {r['envs']} | {r['steps_per_s']:,.0f} | {r['compile_s']:.1f} | "
            f"{r['flops_per_step'] / 1e6:.1f} M | {100 * share:.0f}% |"
        )
    for task, r in world_trains.items():
        share = r["flops_per_step"] * r["steps_per_s"] / peak
        lines.append(
            f"| A2C training loop, `{task}` | {r['envs']} | {r['steps_per_s']:,.0f} | {r['compile_s']:.1f} | "
            f"{r['flops_per_step'] / 1e6:.1f} M | {100 * share:.0f}% |"
        )
    for r in novelties:
        share = r["flops_per_step"] * r["steps_per_s"] / peak
        lines.append(
            f"| {r['algo'].upper()} training loop | {r['envs']} | {r['steps_per_s']:,.0f} | {r['compile_s']:.1f} | "
            f"{r['flops_per_step'] / 1e6:.1f} M | {100 * share:.0f}% |"
        )
    lines += ["", "Where an update's time goes: the novelty model's forward+backward on one rollout, timed",
              "alone, as a share of one whole update (rollout, both losses, gradients, Adam):", ""]
    lines += [f"- {r['algo'].upper()} (N={r['envs']}, T=20{', H=10, L=3' if r['algo'] == 'sim' else ''}"
              f"{', forward only' if r['algo'] == 'ec' else ''}): {100 * r['novelty_share']:.0f}%" for r in novelties]
    r = ec_pretraining
    lines += ["", f"EC's pretraining alone (ResNet-18 pairs, batch 64, Adam): {r['pairs_per_s']:,.0f} pairs/s, "
              f"{r['flops_per_pair'] / 1e9:.2f} GFLOPs per pair ({100 * r['flops_per_pair'] * r['pairs_per_s'] / peak:.0f}% "
              "of the matmul peak); the paper's 0.6M steps at 10 passes of one pair per 4 steps are 1.5M pairs."]
    flops = {r["algo"]: r["flops_per_step"] for r in novelties} | {"a2c": trains[0]["flops_per_step"]}
    lines += ["", *loop_lines(loops, flops, peak), "", *parts_lines(parts, peak), "", *sweep_lines(sweep)]
    lines += ["", *gymnasium_lines(gym_rows)]
    per_step = 1.0 / worlds["explore-goals"]["steps_per_s"]
    lines += ["", "Maze generation alone (1024 mazes per call, `vmap`):", ""]
    lines += [(f"- `explore-goals-paper`, {r['cells']}x{r['cells']} cells: {r['mazes_per_s']:,.0f} mazes/s"
               if r["cells"] is not None else
               f"- `explore-goals`, DMLab's 11x11 maze: {r['mazes_per_s']:,.0f} mazes/s; one maze per 1350-step "
               f"episode is {100 * (1.0 / r['mazes_per_s']) / 1350 / per_step:.2f}% of the `explore-goals` env's time "
               "(the env steps above include no episode end)")
              for r in mazes]
    lines += [
        "",
        "FLOPs per agent step: XLA's cost analysis of one network step forward (acting) plus (T+1)/T",
        "forward+backward passes (learning); see `flops_per_agent_step` in experiments/bench.py.",
        "",
        f"Command: `make bench` (`python experiments/bench.py`); took {time.time() - started:.0f} s.",
        "",
    ]
    text = "\n".join(lines)
    print(text)
    if args.out:
        header = "" if args.out.exists() else (
            "# Benchmarks\n\nEach section is one run of the command it names, on this project's 2-core CPU machine.\n\n")
        with open(args.out, "a") as f:
            f.write(header + text + "\n")
    return 0


LOOP_ALGOS = ("sim", "rnd", "icm", "ec", "e3b", "a2c")


def loop_lines(loops: list[dict], flops: dict, peak: float) -> list[str]:
    """The training loop as the commands run it, a row per method and seed count."""
    lines = ["The training loop as `make train` runs it (N = 16 envs per seed, all seeds in one compiled "
             "program on one device), agent steps/s over all seeds:", "",
             "| method | seeds | agent steps/s | per seed | compile s | share of matmul peak |",
             "|---|---:|---:|---:|---:|---:|"]
    for r in loops:  # (--only loop counts no FLOPs: its share is left empty)
        share = f"{100 * flops[r['algo']] * r['steps_per_s'] / peak:.0f}%" if r["algo"] in flops else ""
        lines.append(f"| {r['algo'].upper()} | {r['seeds']} | {r['steps_per_s']:,.0f} | {r['steps_per_s'] / r['seeds']:,.0f} | "
                     f"{r['compile_s']:.1f} | {share} |")
    return lines


PARTS = ("env", "acting", "rollout", "novelty", "a2c", "optimizer")


def parts_lines(parts: list[dict], peak: float) -> list[str]:
    """Where one update's time goes (``bench_parts``), per method: ms per update and share."""
    lines = ["Where one update's time goes (1 seed, N = 16, T = 20; each part timed alone inside a "
             "`lax.scan`, see `bench_parts`), ms per update and share of the whole update:", "",
             "| part | " + " | ".join(r["algo"].upper() for r in parts) + " |",
             "|---|" + "---:|" * len(parts)]
    for name in PARTS + ("update",):
        cells = []
        for r in parts:
            t = r["seconds"].get(name)
            cells.append("" if t is None else f"{1000 * t:.1f} ({100 * t / r['seconds']['update']:.0f}%)")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    rest = [r["seconds"]["update"] - sum(r["seconds"].get(k, 0.0) for k in ("rollout", "novelty", "a2c", "optimizer"))
            for r in parts]
    lines.append("| update - (rollout + novelty + a2c + optimizer) | "
                 + " | ".join(f"{1000 * x:.1f} ({100 * x / r['seconds']['update']:.0f}%)" for x, r in zip(rest, parts))
                 + " |")
    return lines


def sweep_lines(r: dict) -> list[str]:
    return [f"A sweep of L = 1..{r['points']} (SIM, H=10, N={r['envs']}), one program with windows for L = "
            f"{r['points']}: {r['sweep_steps_per_s']:,.0f} agent steps/s (compiled in {r['sweep_compile_s']:.0f} s); "
            f"the {r['points']} programs built each for its L, run one after another: "
            f"{r['separate_steps_per_s']:,.0f} agent steps/s (compiled in {r['separate_compile_s']:.0f} s together); "
            f"padding overhead {100 * (r['separate_steps_per_s'] / r['sweep_steps_per_s'] - 1):+.0f}% time per agent step."]


def device_lines(results: list[dict]) -> list[str]:
    one, two = results
    return [f"SIM, {one['seeds']} seeds (N=16) as one program: {one['steps_per_s']:,.0f} agent steps/s on one CPU "
            f"device, {two['steps_per_s']:,.0f} sharded over two (one per core; fresh processes, "
            f"`--xla_force_host_platform_device_count`): x{two['steps_per_s'] / one['steps_per_s']:.2f}."]


def ec_lines(loop: dict, pre: dict) -> list[str]:
    """EC's two costs: its policy loop as a run trains it, and its pretraining's updates."""
    return [f"- EC's training loop as `make train` runs it, {loop['seeds']} seeds x {loop['envs']} envs: "
            f"{loop['steps_per_s']:,.0f} agent steps/s in total (chunk compiled in {loop['compile_s']:.1f} s)",
            f"- EC's pretraining alone (1 seed, batches of 64 pairs, Adam): {pre['pairs_per_s']:,.0f} pairs/s, "
            f"{pre['flops_per_pair'] / 1e9:.2f} GFLOPs per pair"]


def write_section(lines: list[str], started: float, out: Path | None) -> int:
    """Print a section (with how long it took) and append it to ``out`` if given."""
    text = "\n".join(lines + ["", f"Took {time.time() - started:.0f} s.", ""])
    print(text)
    if out:
        with open(out, "a") as f:
            f.write(text + "\n")
    return 0


def bf16_matmul_peak(n: int = 2048, repeats: int = 5) -> float:
    """FLOP/s of a 2048x2048 product with bfloat16 operands summed in float32 (``--precision
    bfloat16``'s products)."""
    a = jax.random.normal(jax.random.PRNGKey(0), (n, n), jnp.float32).astype(jnp.bfloat16)
    _, med, _ = time_call(lambda x: jax.lax.dot(x, x, preferred_element_type=jnp.float32), a, repeats=repeats)
    return 2 * n**3 / med


def report_precision(args) -> int:
    """The training loop (``bench_loop``) of each method at each seed count, at highest and at
    bfloat16 one after the other in this process, with both matmul peaks measured now."""
    started = time.time()
    peak, peak16 = matmul_peak(), bf16_matmul_peak()
    seeds = [int(n) for n in args.seeds.split(",")]
    algos = args.algos.split(",")
    command = f"python experiments/bench.py --only precision --seeds {args.seeds} --algos {args.algos}"
    lines = [f"## {dt.date.today().isoformat()}: `{command}` ({args.task})", "",
             machine_line(peak, "highest") + f" bfloat16 operands, float32 sums, same product: {peak16 / 1e9:.0f} "
             "GFLOP/s.", "",
             "The training loop as `make train` runs it (`bench_loop`: 16 envs a seed, 8 updates a call, median of 3 "
             "calls), agent steps/s over all seeds, each row's two precisions measured one after the other:", "",
             "| method | seeds | highest (float32) | bfloat16 | ratio |", "|---|---:|---:|---:|---:|"]
    for algo in algos:
        for n in seeds:
            rates = {}
            for precision in ("highest", "bfloat16"):
                with runtime.matmul_precision(precision):
                    rates[precision] = bench_loop(args.task, algo, n)["steps_per_s"]
            lines.append(f"| {algo.upper()} | {n} | {rates['highest']:.0f} | {rates['bfloat16']:.0f} | "
                         f"{rates['bfloat16'] / rates['highest']:.2f}x |")
            print(lines[-1], flush=True)
    return write_section(lines, started, args.out)


def report_only(args) -> int:
    """Only the sweep-overhead, device-count, Gymnasium, compile-time, EC or loop rows, as their own section."""
    if args.only == "precision":
        return report_precision(args)
    started = time.time()
    peak = matmul_peak()
    command = " ".join(["python experiments/bench.py --only", args.only] + (["--seeds", args.seeds] if args.only == "loop" else [])
                       + (["--precision", args.precision] if args.precision != TrainConfig.precision else []))
    lines = [f"## {dt.date.today().isoformat()}: `{command}` ({args.task})", "", machine_line(peak, args.precision), ""]
    if args.only == "sweep":
        lines += sweep_lines(bench_sweep(args.task))
    elif args.only == "devices":
        lines += device_lines(bench_devices(args.task, args.precision))
    elif args.only == "compile":
        lines += compile_lines([bench_compile(args.task, algo) for algo in ("a2c", "sim", "rnd", "icm", "ec")])
    elif args.only == "ec":
        lines += ec_lines(bench_loop(args.task, "ec", 3), bench_ec_pretraining(args.task))
    elif args.only == "loop":
        seeds = [int(n) for n in args.seeds.split(",")]
        lines += loop_lines([bench_loop(args.task, algo, n) for algo in LOOP_ALGOS for n in seeds], {}, peak)
    else:
        lines += gymnasium_lines(bench_gymnasium(args.task))
    return write_section(lines, started, args.out)


if __name__ == "__main__":
    sys.exit(main())
