"""Training into a run folder: ``run(config, out)`` (``python -m simjax.train`` calls it).

Each compiled call trains ``config.updates_per_log`` updates of every seed (``jax.vmap``); its
metrics become one row per seed in metrics.csv, and the checkpoint is rewritten to match the
last row on disk, so a run stopped by Ctrl-C, killed, or stalled (``simjax.runs.stall``) goes
on from there bit for bit with ``resume``. A run whose losses, gradient norm or parameters
stop being finite ends at that row (``Diverged``), keeping the last finite checkpoint.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import jax
import numpy as np

from simjax.agents import TrainConfig
from simjax.runs.folder import (
    METRIC_COLUMNS,
    MetricsLog,
    load_checkpoint,
    rows_up_to,
    runner_template,
    seed_keys,
    write_checkpoint,
    write_config,
)
from simjax.runs.progress import Progress, mean_over_seeds
from simjax.runs.stall import StallWatchdog

# the learnt quantities of a row: none of them is NaN or infinite in a sound run (a row's
# success ratio or episode length is NaN where no episode ended; that is no fault)
FINITE_TERMS = ("policy_loss", "value_loss", "entropy", "value_mean", "grad_norm", "bonus_mean",
                "forward_loss", "inverse_loss")


class Diverged(RuntimeError):
    """Training produced a non-finite loss, gradient norm or parameter; nothing of that update
    was written."""


def non_finite(metrics: dict, params, seeds: list[int]) -> list[str]:
    """What in one chunk's ``metrics`` and the ``params`` after it (leading axis: seed) is NaN
    or infinite, one line per seed that has any: 'seed S: term value, ..., GROUP parameters'."""
    found = []
    for i, seed in enumerate(seeds):
        bad = [f"{k} {float(np.asarray(metrics[k])[i]):.6g}" for k in FINITE_TERMS
               if k in metrics and not np.isfinite(np.asarray(metrics[k])[i])]
        bad += [f"{group} parameters" for group, tree in params.items()
                if not all(np.isfinite(np.asarray(leaf)[i]).all() for leaf in jax.tree.leaves(tree))]
        if bad:
            found.append(f"seed {seed}: {', '.join(bad)}")
    return found


def run(config: TrainConfig, out: Path, quiet: bool = False, resume: bool = False,
        stall_limit: float | None = None, tensorboard: bool = False) -> Path:
    """Train ``config`` into the run folder ``out``; with ``resume``, go on from its checkpoint
    (bit for bit the run it would have been). ``stall_limit``: see ``StallWatchdog``;
    ``tensorboard``: also write the metrics as TensorBoard scalars (``MetricsLog``).
    Raises ``Diverged`` at the first row with a non-finite loss, gradient norm or parameter."""
    from simjax import plotting, runtime
    from simjax.agents import make_trainer, summarize

    runtime.enable_compilation_cache()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    versions = {m: __import__(m).__version__ for m in ("jax", "flax", "optax", "brax")}
    write_config(out, config, versions)  # on resume: the config read from it, with this process's versions

    trainer = make_trainer(config)
    seeds = [config.seed + i for i in range(config.num_seeds)]
    done_steps, wall_before = 0, 0.0
    rows = [list(METRIC_COLUMNS)]
    watchdog = StallWatchdog(stall_limit) if stall_limit else None
    if watchdog:
        watchdog.begin()
    if resume and (out / "checkpoint.msgpack").exists():
        ckpt = load_checkpoint(out, runner_template(trainer, config))
        runner, done_steps = jax.device_put(ckpt["runner"]), int(ckpt["env_steps"])
        rows = rows_up_to(out / "metrics.csv", done_steps)
        wall_before = float(rows[-1][-1]) if len(rows) > 1 else 0.0
    else:
        runner = jax.jit(jax.vmap(trainer.init))(seed_keys(config))

    def chunk_and_summarize(r):
        r, metrics = trainer.run_chunk(r)
        return r, summarize(metrics)

    # no buffer donation: a Ctrl-C must leave the last finished runner intact to be saved
    chunk = jax.jit(jax.vmap(chunk_and_summarize))

    steps_per_chunk = config.updates_per_log * config.steps_per_update
    total = config.num_logs * steps_per_chunk
    progress = Progress(total, quiet, config.num_seeds)
    if not quiet:
        what = f"resuming at {done_steps:,} steps" if done_steps else "compiling"
        print(f"{what}: {config.algo} on {config.env} ({config.num_seeds} seed(s), "
              f"{config.num_envs} envs each); run folder {out}", file=sys.stderr, flush=True)
    write_checkpoint(out, runner, done_steps, seeds)
    if watchdog:
        watchdog.end(record=False)
    compiled = chunk.lower(runner).compile()  # compiling is not watched, only running
    start = time.perf_counter() - wall_before
    log = MetricsLog(out, rows, tensorboard)
    try:
        last = time.perf_counter()
        while done_steps < total:
            if watchdog:
                watchdog.begin()
            next_runner, metrics = compiled(runner)
            metrics = jax.device_get(metrics)
            if watchdog:
                watchdog.end()
            now = time.perf_counter()
            steps = done_steps + steps_per_chunk
            bad = non_finite(metrics, jax.device_get(next_runner.params), seeds)
            if bad:  # neither this row nor its runner is written: the checkpoint stays finite
                raise Diverged(
                    f"training diverged in the updates up to {steps:,} agent steps per seed: "
                    f"{'; '.join(bad)}. {out} keeps its rows and checkpoint up to {done_steps:,} steps; "
                    "a smaller --learning-rate or --max-grad-norm may help")
            rate = steps_per_chunk * config.num_seeds / (now - last)
            last = now
            for i, seed in enumerate(seeds):
                values = {k: float(np.asarray(v)[i]) for k, v in metrics.items()}
                log.append(steps, seed, values | {"steps_per_s": rate, "wall_s": now - start})
            log.flush()
            # the checkpoint always matches the last row on disk, even if the process is killed
            runner, done_steps = next_runner, steps
            write_checkpoint(out, runner, done_steps, seeds)
            progress.update(done_steps, rate, mean_over_seeds(metrics["success_ratio"]),
                            mean_over_seeds(metrics["mean_episode_length"]))
    except KeyboardInterrupt:
        print(f"\nstopped at {done_steps:,} steps; saving what the run has", file=sys.stderr)
        write_checkpoint(out, runner, done_steps, seeds)
    finally:
        log.close()
        progress.close()
        if done_steps:
            plotting.plot_run(out)
    return out
