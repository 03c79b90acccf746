"""Training into a run folder: ``run(config, out)`` (``python -m simjax.train`` calls it).

Each compiled call trains ``config.updates_per_log`` updates of every member of the batch, one
per sweep point and seed (``simjax.runs.grid``; a plain run's members are its seeds), as one
``jax.vmap``; its metrics become one row per member in metrics.csv. The checkpoint, every
member's whole state (42 MiB a SIM seed, two thirds of it Adam's moments), and beside it the
export (``folder.write_export``) are rewritten after a row once ``checkpoint_every`` seconds
have passed since the last (0: after every row), at the end, and when the run is stopped by
Ctrl-C or SIGTERM, so a stopped run goes on bit for bit with ``resume``; a killed one (SIGKILL,
a crash) goes on from its last checkpoint, the rows after it dropped and trained again, to the
same numbers. A run whose losses, gradient norm or parameters stop being finite ends at that
row (``Diverged``), its last finite state saved.

With several local devices (GPUs, or CPU devices made with
``--xla_force_host_platform_device_count``), the members are sharded over them (a
``jax.sharding.Mesh`` over the batch axis); the program, and every member's numbers, are the
same as on one device.

EC first pretrains its reachability network (``simjax.novelty.ec_pretrain``), call by call,
its loss and accuracy written to pretrain.csv; the checkpoint after it is at
``config.step_offset`` agent steps, where metrics.csv's rows begin. After each chunk the
pretraining's state is saved beside it (pretrain_state.msgpack: the network, Adam, the random
policy's environments and key; not the chunk's frames, which the next chunk replaces), so a run
stopped during the pretraining goes on from its last chunk, bit for bit, with ``resume``; the
file is removed once the checkpoint after the pretraining is written. The pretraining is done
once per seed, not once per member: it reads nothing a sweep varies (a random policy, EC's own
Adam), and every point's member of a seed starts from the same key (``grid.batch_inputs``), so
each member gets the network its seed's pretraining gives, the one it would have trained itself.
"""

from __future__ import annotations

import csv
import sys
import time
from pathlib import Path

import jax
import numpy as np

from simjax.agents import TrainConfig
from simjax.runs.folder import (
    MetricsLog,
    atomic_write,
    check_resumable,
    load_checkpoint,
    metric_columns,
    rows_up_to,
    runner_template,
    stops_deferred,
    write_checkpoint,
    write_config,
    write_export,
)
from simjax.runs.grid import batch_inputs, grid_of, members
from simjax.runs.progress import Progress, mean_over_seeds

# the learnt quantities of a row: none of them is NaN or infinite in a sound run (a row's
# success ratio or episode length is NaN where no episode ended; that is no fault)
FINITE_TERMS = ("policy_loss", "value_loss", "entropy", "value_mean", "grad_norm", "bonus_mean",
                "forward_loss", "inverse_loss")


# seconds between checkpoints (--checkpoint-every): at most this much training is lost to a kill
CHECKPOINT_EVERY = 600.0


def save_state(out: Path, runner, steps: int, seeds: list[int]) -> None:
    """checkpoint.msgpack and export/ at ``steps``, from one copy of ``runner`` on the host."""
    host = jax.device_get(runner)
    write_checkpoint(out, host, steps, seeds)
    write_export(out, host, steps, seeds)


class Diverged(RuntimeError):
    """Training produced a non-finite loss, gradient norm or parameter; nothing of that update
    was written."""


def finite_parameters(params) -> dict:
    """{group: (members,) bool}, whether each member's parameters of the group are all finite;
    jitted where the parameters live, so that a row fetches a few booleans, not the parameters."""
    import jax.numpy as jnp

    def finite(leaves):
        return jnp.stack([jnp.isfinite(x).reshape(x.shape[0], -1).all(axis=1) for x in leaves]).all(axis=0)

    return {group: finite(jax.tree.leaves(tree)) for group, tree in params.items() if jax.tree.leaves(tree)}


def non_finite(metrics: dict, finite: dict, names: list[str]) -> list[str]:
    """What in one chunk's ``metrics`` and the parameters after it (``finite_parameters``;
    leading axis: member) is NaN or infinite, one line per member that has any:
    'NAME: term value, ..., GROUP parameters'."""
    found = []
    for i, name in enumerate(names):
        bad = [f"{k} {float(np.asarray(metrics[k])[i]):.6g}" for k in FINITE_TERMS
               if k in metrics and not np.isfinite(np.asarray(metrics[k])[i])]
        bad += [f"{group} parameters" for group, ok in finite.items() if not np.asarray(ok)[i]]
        if bad:
            found.append(f"{name}: {', '.join(bad)}")
    return found


def member_name(point: dict, seed: int) -> str:
    return " ".join(f"{k}={v}" for k, v in point.items()) + (" " if point else "") + f"seed {seed}"


def batch_sharding(batch: int, devices=None):
    """A sharding of the leading (member) axis over the local devices, or None on one device.
    Uses the most devices that divide the batch evenly."""
    import math

    from jax.sharding import Mesh, NamedSharding, PartitionSpec

    devices = jax.local_devices() if devices is None else devices
    n = math.gcd(batch, len(devices))
    if n == 1:
        return None
    return NamedSharding(Mesh(np.array(devices[:n]), ("member",)), PartitionSpec("member"))


PRETRAIN_COLUMNS = ("env_steps", "seed", "loss", "accuracy", "usable_pairs", "wall_s")
PRETRAIN_STATE = "pretrain_state.msgpack"
# what of a PretrainState goes on from one chunk to the next (``frames`` and ``starts`` are the
# chunk just trained on; ``collect`` replaces both before they are read again)
_CARRIED = ("params", "opt_state", "env_state", "key")


def write_pretrain_state(out: Path, state, chunks: int, seeds: list[int], plan) -> None:
    """pretrain_state.msgpack: the pretraining of ``plan`` after ``chunks`` chunks (every seed)."""
    import dataclasses

    from flax import serialization

    carried = {k: serialization.to_state_dict(jax.device_get(getattr(state, k))) for k in _CARRIED}
    record = {"state": carried, "chunks": chunks, "seeds": list(seeds), "plan": dataclasses.asdict(plan)}
    atomic_write(out / PRETRAIN_STATE, serialization.msgpack_serialize(record))


def read_pretrain_state(out: Path, plan, seeds: list[int] | None = None) -> dict:
    """The record ``write_pretrain_state`` wrote, checked against this run's ``plan`` (and
    ``seeds``); a ValueError naming the file if it is damaged or another pretraining's."""
    import dataclasses

    from flax import serialization

    path = out / PRETRAIN_STATE
    again = "delete it to start the pretraining again"
    try:
        record = serialization.msgpack_restore(path.read_bytes())
        chunks, saved_seeds, saved_plan = int(record["chunks"]), list(record["seeds"]), record["plan"]
        record["state"]
    except (ValueError, TypeError, KeyError) as err:
        raise ValueError(f"{path} is damaged ({err!r}); {again}") from None
    if plan is None or saved_plan != dataclasses.asdict(plan) or not 0 < chunks <= plan.num_chunks:
        raise ValueError(f"{path} is another pretraining's ({saved_plan}, after {chunks} chunks), not this run's; {again}")
    if seeds is not None and saved_seeds != list(seeds):
        raise ValueError(f"{path} holds seeds {saved_seeds}, this run trains {list(seeds)}; {again}")
    return record


def load_pretrain_state(out: Path, template, plan, seeds: list[int]):
    """(state, chunks done) saved by ``write_pretrain_state``, rebuilt into ``template``'s types."""
    from flax import serialization

    record = read_pretrain_state(out, plan, seeds)
    carried = {k: serialization.from_state_dict(getattr(template, k), record["state"][k]) for k in _CARRIED}
    return template._replace(**carried), int(record["chunks"])


def pretrain(pretrainer, runner, out: Path, seeds: list[int], quiet: bool,
             devices=None, sharding=None, resume: bool = False):
    """EC's pretraining for every member of ``runner`` (leading axis: member, point-major, so
    member ``p * len(seeds) + s`` is seed ``seeds[s]`` of point ``p``), done once per seed on
    point 0's members (sharded over ``devices``) and given to every point's member of that seed;
    one compiled call at a time; each chunk's mean loss and accuracy (on each batch before its
    update) become a row per seed of ``out``/pretrain.csv, and its state pretrain_state.msgpack
    (with ``resume``, the pretraining goes on from that file's chunk). Returns the runner
    (sharded by ``sharding``) with the pretrained network and its episodic memories restarted
    with it, and the seconds of pretraining done before this process (resumed: pretrain.csv's
    last kept ``wall_s``; else 0)."""
    plan, num_seeds = pretrainer.plan, len(seeds)
    num_members = len(runner.key)
    keys = np.asarray(jax.device_get(runner.key)).reshape(num_members // num_seeds, num_seeds, -1)
    if not (keys == keys[:1]).all():  # then the members of a seed would not share their pretraining
        raise ValueError("EC's pretraining is shared by a seed's members, but they start from different keys")
    first = jax.device_get(jax.tree.map(lambda x: x[:num_seeds], runner))  # point 0: one member per seed
    seed_sharding = batch_sharding(num_seeds, devices)
    shard = {} if seed_sharding is None else {"in_shardings": seed_sharding, "out_shardings": seed_sharding}
    out_shard = {} if seed_sharding is None else {"out_shardings": seed_sharding}
    state = jax.jit(jax.vmap(lambda r: pretrainer.start(r)[0]), **out_shard)(first)
    collect = jax.jit(jax.vmap(pretrainer.collect), **shard).lower(state).compile()
    train = jax.jit(jax.vmap(pretrainer.train), **shard).lower(state).compile()
    rows, done, wall_before = [",".join(PRETRAIN_COLUMNS)], 0, 0.0
    if resume and (out / PRETRAIN_STATE).exists():
        state, done = load_pretrain_state(out, jax.device_get(state), plan, seeds)
        state = state if seed_sharding is None else jax.device_put(state, seed_sharding)
        steps_done = done * plan.chunk_len * plan.num_envs
        rows = [",".join(r) for r in rows_up_to(out / "pretrain.csv", steps_done, PRETRAIN_COLUMNS)]
        wall_before = float(rows[-1].split(",")[-1]) if done else 0.0
    started = time.perf_counter() - wall_before
    if not quiet:
        at = f", resuming after chunk {done} of {plan.num_chunks}" if done else ""
        print(f"pretraining EC's reachability network: {plan.env_steps:,} random-policy steps per seed, "
              f"{plan.updates:,} updates of {pretrainer.batch} pairs{at}", file=sys.stderr, flush=True)
    for c in range(done, plan.num_chunks):
        state = jax.block_until_ready(collect(state))
        per_call = []
        for _ in range(plan.calls):
            state, metrics = train(state)
            per_call.append(jax.device_get(metrics))
        metrics = {k: np.mean([np.asarray(m[k]) for m in per_call], axis=0) for k in per_call[0]}
        steps = (c + 1) * plan.chunk_len * plan.num_envs
        wall = time.perf_counter() - started
        for i, seed in enumerate(seeds):
            rows.append(f"{steps},{seed},{metrics['loss'][i]:.6g},{metrics['accuracy'][i]:.6g},"
                        f"{metrics['usable_pairs'][i]:.6g},{wall:.1f}")
        with stops_deferred():  # a Ctrl-C or SIGTERM waits until the chunk's rows and state are written
            atomic_write(out / "pretrain.csv", ("\r\n".join(rows) + "\r\n").encode())
            write_pretrain_state(out, state, c + 1, seeds, plan)
        if not quiet:
            print(f"pretraining: {steps:,}/{plan.env_steps:,} steps per seed | loss {np.mean(metrics['loss']):.3f} | "
                  f"accuracy {np.mean(metrics['accuracy']):.3f} | {wall:.0f} s", file=sys.stderr, flush=True)
    params = jax.device_get(state.params)  # per seed; member m gets seed m % num_seeds's
    index = np.arange(num_members) % num_seeds

    def finish(r, p):  # each member as ``pretrainer.start`` leaves it (its key split), then finished
        return jax.vmap(lambda r_, p_: pretrainer.finish(pretrainer.start(r_)[1], p_))(
            r, jax.tree.map(lambda x: x[index], p))

    runner = jax.jit(finish, **({} if sharding is None else {"out_shardings": sharding}))(runner, params)
    return runner, wall_before


def member_programs(trainer, sharding=None):
    """A run's two programs over its members (leading axis: member), jitted: ``init(keys,
    hypers)`` and ``chunk(runner) -> (runner, row)``, one chunk of updates and its row's
    measures (``summarize``). Traced inside ``runtime.matmul_precision(config.precision)``, as
    ``run`` traces them, they are the run's own programs (the compilation cache's too)."""
    from simjax.agents import summarize

    shard = {} if sharding is None else {"in_shardings": sharding, "out_shardings": sharding}

    def chunk_and_summarize(r):
        r, metrics = trainer.run_chunk(r)
        return r, summarize(metrics)

    # no buffer donation: a Ctrl-C must leave the last finished runner intact to be saved
    return jax.jit(jax.vmap(trainer.init), **shard), jax.jit(jax.vmap(chunk_and_summarize), **shard)


def run(config: TrainConfig, out: Path, quiet: bool = False, resume: bool = False,
        tensorboard: bool = False, sweep: dict | None = None,
        devices=None, checkpoint_every: float = CHECKPOINT_EVERY) -> Path:
    """Train ``config`` into the run folder ``out``; with ``resume``, go on from its checkpoint
    (bit for bit the run it would have been); ``checkpoint_every``: seconds between
    checkpoints (0: after every row; the end and a stop always write one);
    ``tensorboard``: also write the metrics as TensorBoard scalars (``MetricsLog``);
    ``sweep``: field -> values, every combination trained side by side (``check_sweep`` made
    ``config`` from them); ``devices``: the devices to shard the members over (default: all).
    Every program is traced at ``config.precision`` (``runtime.matmul_precision``), whatever
    JAX's global setting. Raises ``Diverged`` at the first row with a non-finite loss, gradient
    norm or parameter."""
    from simjax import runtime

    if not checkpoint_every >= 0:
        raise ValueError(f"--checkpoint-every must be a number of seconds >= 0, got {checkpoint_every}")
    with runtime.matmul_precision(config.precision):
        return _train(config, out, quiet, resume, tensorboard, sweep, devices, checkpoint_every)


def _train(config: TrainConfig, out: Path, quiet: bool, resume: bool, tensorboard: bool, sweep: dict | None,
           devices, checkpoint_every: float) -> Path:
    from simjax import plotting, runtime
    from simjax.agents import make_trainer

    runtime.enable_compilation_cache()
    out = Path(out)
    if resume:
        check_resumable(out)
    out.mkdir(parents=True, exist_ok=True)
    versions = {m: __import__(m).__version__ for m in ("jax", "flax", "optax", "brax")}
    sweep = sweep or {}
    # on resume: the config read from it, with this process's versions
    write_config(out, config, versions, sweep)

    trainer = make_trainer(config)
    grid = grid_of(sweep)
    batch = members(config, grid)
    seeds = [seed for _, seed in batch]
    names = [member_name(point, seed) for point, seed in batch]
    columns = metric_columns(sweep)
    done_steps, wall_before = 0, 0.0
    rows = [list(columns)]
    sharding = batch_sharding(len(batch), devices)
    init, chunk = member_programs(trainer, sharding)
    steps_per_chunk = config.updates_per_log * config.steps_per_update
    if resume and (out / "checkpoint.msgpack").exists():
        ckpt = load_checkpoint(out, runner_template(trainer, config, sweep))
        runner, done_steps = jax.device_put(ckpt["runner"], sharding), int(ckpt["env_steps"])
        if (out / "metrics.csv").exists():  # absent if stopped before the first row's file (EC's pretraining)
            rows = rows_up_to(out / "metrics.csv", done_steps, columns)
        wall_before = float(rows[-1][-1]) if len(rows) > 1 else 0.0
    else:
        (out / PRETRAIN_STATE).unlink(missing_ok=True)  # a fresh run never goes on from an earlier one's
        runner = init(*jax.device_put(batch_inputs(config, grid), sharding))
    finite = jax.jit(finite_parameters)

    total = config.step_offset + config.num_logs * steps_per_chunk
    progress = Progress(total, quiet, len(batch))
    if not quiet:
        what = f"resuming at {done_steps:,} steps" if done_steps else "compiling"
        points = f"{len(grid)} sweep points x " if sweep else ""
        on = f", on {len(sharding.mesh.devices)} devices" if sharding is not None else ""
        print(f"{what}: {config.algo} ({config.learner} learner) on {config.env} ({points}{config.num_seeds} seed(s), "
              f"{config.num_envs} envs each{on}); run folder {out}", file=sys.stderr, flush=True)
    save_state(out, runner, done_steps, seeds)
    pretrain_s = 0.0
    if trainer.pretrain is not None and done_steps < config.step_offset:
        began = time.perf_counter()
        runner, earlier = pretrain(trainer.pretrain, runner, out, seeds[: config.num_seeds], quiet, devices,
                                   sharding, resume)
        done_steps, pretrain_s = config.step_offset, time.perf_counter() - began + earlier
        with stops_deferred():  # the checkpoint after the pretraining, then its state is not needed
            save_state(out, runner, done_steps, seeds)
            (out / PRETRAIN_STATE).unlink(missing_ok=True)
    elif trainer.pretrain is not None and len(rows) == 1 and (out / "pretrain.csv").exists():
        # resumed after the pretraining's checkpoint, before the first row: wall_s counts the pretraining
        with open(out / "pretrain.csv", newline="") as f:
            pretrain_s = float(list(csv.reader(f))[-1][-1])
    if done_steps >= config.step_offset:  # a kill between the checkpoint and the removal leaves it
        (out / PRETRAIN_STATE).unlink(missing_ok=True)
    compiled = chunk.lower(runner).compile()
    start = time.perf_counter() - wall_before - pretrain_s  # wall_s counts the pretraining too
    log = MetricsLog(out, rows, tensorboard, labels=tuple(sweep))
    saved = {"steps": done_steps, "at": time.monotonic()}  # the checkpoint on disk

    def save():
        save_state(out, runner, done_steps, seeds)
        saved.update(steps=done_steps, at=time.monotonic())

    try:
        last = time.perf_counter()
        while done_steps < total:
            next_runner, metrics = compiled(runner)
            metrics = jax.device_get(metrics)
            now = time.perf_counter()
            steps = done_steps + steps_per_chunk
            bad = non_finite(metrics, jax.device_get(finite(next_runner.params)), names)
            if bad:  # neither this row nor its runner is written: the checkpoint stays finite
                raise Diverged(
                    f"training diverged in the updates up to {steps:,} agent steps per member: "
                    f"{'; '.join(bad)}. {out} keeps its rows and checkpoint up to {done_steps:,} steps; "
                    "a smaller --learning-rate or --max-grad-norm may help")
            rate = steps_per_chunk * len(batch) / (now - last)
            last = now
            with stops_deferred():  # a Ctrl-C or SIGTERM waits until the rows (and a checkpoint due) are written
                for i, (point, seed) in enumerate(batch):
                    values = {k: float(np.asarray(v)[i]) for k, v in metrics.items()}
                    log.append(steps, seed, values | {"steps_per_s": rate, "wall_s": now - start}, point)
                log.flush()
                runner, done_steps = next_runner, steps
                if done_steps >= total or time.monotonic() - saved["at"] >= checkpoint_every:
                    save()
            progress.update(done_steps, rate, mean_over_seeds(metrics["success_ratio"]),
                            mean_over_seeds(metrics["mean_episode_length"]))
    except KeyboardInterrupt:
        print(f"\nstopped at {done_steps:,} steps; saving what the run has", file=sys.stderr)
        if saved["steps"] != done_steps:
            save()
    except Diverged:  # the rows before it are written: so is the state they lead to
        if saved["steps"] != done_steps:
            save()
        raise
    finally:
        log.close()
        progress.close()
        if done_steps:
            plotting.plot_run(out)
    return out
