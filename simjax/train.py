"""Command line: ``python -m simjax.train --env maze-very-sparse ...`` (``make train``).

Config in, run folder out:
    config.json       every setting of the run (TrainConfig) and the package versions
    metrics.csv       one row per seed per log interval, appended and flushed as training goes
    checkpoint.msgpack  parameters of every seed as of the last metrics row (rewritten, atomically,
                      after each row, so a stopped or killed run keeps it)
    curve.png         success ratio and mean episode length against agent steps
Every flag comes from ``TrainConfig``; bad values fail here, before anything compiles.
A stopped run (Ctrl-C) keeps every row it wrote and still saves its checkpoint and curve.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import datetime as dt
import json
import os
import sys
import time
from pathlib import Path

from simjax.agents.config import TrainConfig

METRIC_COLUMNS = (
    "env_steps", "seed", "success_ratio", "mean_episode_length", "mean_extrinsic_return",
    "episodes", "policy_loss", "value_loss", "entropy", "value_mean", "grad_norm",
    "bonus_mean", "forward_loss", "inverse_loss", "steps_per_s", "wall_s",
)


def _parse_bool(text: str) -> bool:
    lowered = text.strip().lower()
    if lowered in ("1", "true", "yes", "on"):
        return True
    if lowered in ("0", "false", "no", "off"):
        return False
    raise argparse.ArgumentTypeError(f"expected true or false, got {text!r}")


_FIELD_TYPES = {"int": int, "float": float, "str": str, "bool": _parse_bool, "float | None": float}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m simjax.train",
        description="Train an LSTM actor-critic (with an exploration bonus) on a simjax task.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    for field in dataclasses.fields(TrainConfig):
        parser.add_argument(
            "--" + field.name.replace("_", "-"),
            type=_FIELD_TYPES[str(field.type)],
            default=field.default,
            help=field.metadata.get("help", ""),
        )
    parser.add_argument("--out", type=Path, default=None, help="run folder (default: runs/ENV-ALGO-TIME)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--resume", type=Path, default=None,
                        help="continue the run in this folder from its checkpoint (no other flags)")
    parser.add_argument("--no-supervise", action="store_true",
                        help="train in this process, without restarting it when XLA stalls")
    parser.add_argument("--max-restarts", type=int, default=20, help="restarts after XLA stalls")
    parser.add_argument("--stall-timeout", type=float, default=300.0,
                        help="seconds the first compiled call may take before it counts as stalled")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    return parser


def parse_config(argv=None) -> tuple[TrainConfig, Path, bool]:
    """Parse and validate; every error is reported by argparse before JAX is imported."""
    parser = build_parser()
    args = parser.parse_args(argv)
    values = {f.name: getattr(args, f.name) for f in dataclasses.fields(TrainConfig)}
    try:
        config = TrainConfig(**values)
    except ValueError as err:
        parser.error(str(err))
    out = args.out
    if out is None:
        stamp = dt.datetime.now().strftime("%Y%m%d-%H%M%S")
        out = Path("runs") / f"{config.env}-{config.algo}-{stamp}"
    if (out / "metrics.csv").exists():
        parser.error(f"{out} already holds a run (metrics.csv); choose another --out")
    return config, out, args.quiet


def enable_compilation_cache() -> None:
    import jax

    cache = os.environ.get("SIMJAX_CACHE_DIR", str(Path.home() / ".cache" / "simjax" / "jax"))
    jax.config.update("jax_compilation_cache_dir", cache)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)


def atomic_write(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and a rename, so a run stopped
    mid-write leaves the old file or the new one, never half of one."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


class Progress:
    """A one-line progress bar on stderr (plain lines when stderr is not a terminal)."""

    def __init__(self, total: int, quiet: bool, num_seeds: int = 1):
        self.total, self.quiet, self.tty = total, quiet, sys.stderr.isatty()
        self.num_seeds = num_seeds

    def update(self, done: int, steps_per_s: float, success: float, length: float):
        """``done``/``total`` count agent steps per seed; ``steps_per_s`` counts all seeds'."""
        if self.quiet:
            return
        frac = done / self.total
        bar = "#" * int(30 * frac) + "." * (30 - int(30 * frac))
        eta = (self.total - done) * self.num_seeds / max(steps_per_s, 1e-9)
        line = (
            f"[{bar}] {done:,}/{self.total:,} steps per seed | {steps_per_s:,.0f} steps/s | "
            f"success {success:.2f} | ep len {length:.0f} | ETA {dt.timedelta(seconds=int(eta))}"
        )
        print(("\r" + line) if self.tty else line, end="" if self.tty else "\n", file=sys.stderr, flush=True)

    def close(self):
        if self.tty and not self.quiet:
            print(file=sys.stderr)


def _mean(values) -> float:
    """Mean over seeds, ignoring seeds in which no episode ended (NaN)."""
    import numpy as np

    values = np.asarray(values, dtype=np.float64)
    finite = values[np.isfinite(values)]
    return float(finite.mean()) if finite.size else float("nan")


STALLED = 75  # exit status of a worker whose XLA computation stopped making progress


def write_config(run_dir: Path, config: TrainConfig, versions: dict | None = None) -> None:
    """config.json: every setting (and, from a training process, the package versions)."""
    record = {"config": dataclasses.asdict(config)} | ({"versions": versions} if versions else {})
    atomic_write(Path(run_dir) / "config.json", json.dumps(record, indent=2).encode())


def load_config(run_dir: Path) -> TrainConfig:
    path = Path(run_dir) / "config.json"
    if not path.exists():
        raise FileNotFoundError(f"{run_dir} is not a run folder (no config.json)")
    return TrainConfig(**json.loads(path.read_text())["config"])


def seed_keys(config: TrainConfig):
    """(num_seeds, 2) the PRNG keys a run's seeds start from: seed, seed + 1, ..."""
    import jax

    return jax.numpy.stack([jax.random.PRNGKey(config.seed + i) for i in range(config.num_seeds)])


def load_checkpoint(run_dir: Path, template=None) -> dict:
    """The checkpoint as saved: {"runner": RunnerState of every seed (leading axis: seed),
    "env_steps", "seeds"}; with a ``template`` RunnerState the runner is rebuilt into its types."""
    from flax import serialization

    ckpt = serialization.msgpack_restore((Path(run_dir) / "checkpoint.msgpack").read_bytes())
    if template is not None:
        ckpt["runner"] = serialization.from_state_dict(template, ckpt["runner"])
    return ckpt


class StallWatchdog:
    """Ends the process with ``STALLED`` when one compiled call makes no progress for too long.

    jaxlib 0.10.2 on XLA:CPU now and then never signals a finished computation (see
    simjax/__init__.py); the process then waits forever and ignores Ctrl-C. Everything a run
    has written is on disk by then, so the supervising ``main`` restarts the worker from the
    last checkpoint. The first call of a process may take ``first_limit`` seconds; later ones
    max(60 s, 4 x the slowest call so far).
    """

    def __init__(self, first_limit: float):
        import threading

        self.first_limit, self.slowest, self.started = first_limit, 0.0, None
        self._lock = threading.Lock()
        threading.Thread(target=self._watch, daemon=True).start()

    def begin(self):
        with self._lock:
            self.started = time.perf_counter()

    def end(self, record: bool = True):
        with self._lock:
            if record:
                self.slowest = max(self.slowest, time.perf_counter() - self.started)
            self.started = None

    def limit(self) -> float:
        return self.first_limit if self.slowest == 0.0 else max(60.0, 4.0 * self.slowest)

    def _watch(self):
        while True:
            time.sleep(1.0)
            with self._lock:
                stuck = self.started is not None and time.perf_counter() - self.started > self.limit()
            if stuck:
                print(f"\nno progress for {self.limit():.0f} s (XLA:CPU stall); exiting to resume "
                      "from the last checkpoint", file=sys.stderr, flush=True)
                os._exit(STALLED)


def _rows_up_to(path: Path, steps: int) -> list[list[str]]:
    """metrics.csv rows (header first) up to ``steps``: a row written after the last checkpoint
    (the process died between the two writes) is dropped, its update will be rerun."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows or tuple(rows[0]) != METRIC_COLUMNS:
        raise ValueError(f"{path} does not have the columns this version writes")
    return [rows[0]] + [r for r in rows[1:] if int(r[0]) <= steps]


def run(config: TrainConfig, out: Path, quiet: bool = False, resume: bool = False,
        stall_limit: float | None = None) -> Path:
    """Train ``config`` into the run folder ``out``; with ``resume``, go on from its checkpoint
    (bit for bit the run it would have been). ``stall_limit``: see ``StallWatchdog``."""
    import jax
    import numpy as np
    from flax import serialization

    from simjax import plotting
    from simjax.agents import make_trainer, summarize

    enable_compilation_cache()
    out.mkdir(parents=True, exist_ok=True)
    versions = {m: __import__(m).__version__ for m in ("jax", "flax", "optax", "brax")}
    write_config(out, config, versions)  # on resume: the config read from it, with this process's versions

    trainer = make_trainer(config)
    seeds = [config.seed + i for i in range(config.num_seeds)]
    keys = seed_keys(config)
    init = jax.vmap(trainer.init)
    done_steps, wall_before = 0, 0.0
    rows = [list(METRIC_COLUMNS)]
    watchdog = StallWatchdog(stall_limit) if stall_limit else None
    if watchdog:
        watchdog.begin()
    if resume and (out / "checkpoint.msgpack").exists():
        ckpt = load_checkpoint(out, jax.eval_shape(init, keys))
        runner, done_steps = jax.device_put(ckpt["runner"]), int(ckpt["env_steps"])
        rows = _rows_up_to(out / "metrics.csv", done_steps)
        wall_before = float(rows[-1][-1]) if len(rows) > 1 else 0.0
    else:
        runner = jax.jit(init)(keys)

    def chunk_and_summarize(r):
        r, metrics = trainer.run_chunk(r)
        return r, summarize(metrics)

    # no buffer donation: a Ctrl-C must leave the last finished runner intact to be saved
    chunk = jax.jit(jax.vmap(chunk_and_summarize))

    def save_checkpoint(runner, steps):
        state = {"runner": serialization.to_state_dict(jax.device_get(runner)), "env_steps": steps, "seeds": seeds}
        atomic_write(out / "checkpoint.msgpack", serialization.msgpack_serialize(state))

    steps_per_chunk = config.updates_per_log * config.steps_per_update
    total = config.num_logs * steps_per_chunk
    progress = Progress(total, quiet, config.num_seeds)
    if not quiet:
        what = f"resuming at {done_steps:,} steps" if done_steps else "compiling"
        print(f"{what}: {config.algo} on {config.env} ({config.num_seeds} seed(s), "
              f"{config.num_envs} envs each); run folder {out}", file=sys.stderr, flush=True)
    save_checkpoint(runner, done_steps)
    if watchdog:
        watchdog.end(record=False)
    compiled = chunk.lower(runner).compile()  # compiling is not watched, only running
    start = time.perf_counter() - wall_before
    try:
        atomic_write(out / "metrics.csv", "".join(",".join(r) + "\r\n" for r in rows).encode())
        with open(out / "metrics.csv", "a", newline="") as f:
            writer = csv.writer(f)
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
                rate = steps_per_chunk * config.num_seeds / (now - last)
                last = now
                for i, seed in enumerate(seeds):
                    row = {k: float(np.asarray(v)[i]) for k, v in metrics.items()}
                    writer.writerow(
                        [steps, seed] + [f"{row[c]:.6g}" for c in METRIC_COLUMNS[2:-2]]
                        + [f"{rate:.1f}", f"{now - start:.1f}"]
                    )
                f.flush()
                os.fsync(f.fileno())
                # the checkpoint always matches the last row on disk, even if the process is killed
                runner, done_steps = next_runner, steps
                save_checkpoint(runner, done_steps)
                progress.update(done_steps, rate, _mean(metrics["success_ratio"]), _mean(metrics["mean_episode_length"]))
    except KeyboardInterrupt:
        print(f"\nstopped at {done_steps:,} steps; saving what the run has", file=sys.stderr)
        save_checkpoint(runner, done_steps)
    finally:
        progress.close()
        if done_steps:
            plotting.plot_run(out)
    return out


def _checkpoint_steps(out: Path) -> int:
    try:
        return int(load_checkpoint(out)["env_steps"])
    except (FileNotFoundError, KeyError, ValueError):
        return -1


def supervise(out: Path, quiet: bool, max_restarts: int, stall_timeout: float = 300.0,
              cmd: list[str] | None = None) -> int:
    """Run the worker (``--resume out --worker``) in a child process; restart it from the last
    checkpoint each time it exits ``STALLED``. A worker that stalls again without having added
    a row gets twice the time for its first call (in case that call is just slow). Ctrl-C
    reaches both processes; the worker saves and stops."""
    import subprocess

    limit, steps = stall_timeout, _checkpoint_steps(out)
    for attempt in range(max_restarts + 1):
        worker = cmd or ([sys.executable, "-m", "simjax.train", "--resume", str(out), "--worker",
                          "--stall-timeout", str(limit)] + (["--quiet"] if quiet else []))
        proc = subprocess.Popen(worker)
        try:
            code = proc.wait()
        except KeyboardInterrupt:
            try:  # the worker got the same Ctrl-C and is saving; a stalled one cannot, so end it
                code = proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                code = proc.wait()
            return 130
        if code != STALLED:
            return code
        now = _checkpoint_steps(out)
        limit = limit * 2 if now == steps else stall_timeout
        steps = now
        print(f"restarting from the checkpoint in {out} ({attempt + 1} of {max_restarts})", file=sys.stderr, flush=True)
    print(f"gave up after {max_restarts} restarts; resume with --resume {out}", file=sys.stderr)
    return STALLED


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    extra = argparse.ArgumentParser(add_help=False)
    extra.add_argument("--resume", type=Path, default=None)
    extra.add_argument("--worker", action="store_true")
    extra.add_argument("--no-supervise", action="store_true")
    extra.add_argument("--max-restarts", type=int, default=20)
    extra.add_argument("--stall-timeout", type=float, default=300.0)
    known, rest = extra.parse_known_args(argv)
    parser = build_parser()
    if known.resume is not None:
        args = parser.parse_args(rest)
        if any(a.startswith("--") and a != "--quiet" for a in rest):
            parser.error("--resume continues a run with its own config.json; give no other flags")
        try:
            config = load_config(known.resume)
        except (FileNotFoundError, ValueError, TypeError) as err:
            parser.error(str(err))
        out, quiet = known.resume, args.quiet
    else:
        config, out, quiet = parse_config(rest)
    if known.worker or known.no_supervise:
        run(config, out, quiet, resume=known.resume is not None,
            stall_limit=known.stall_timeout if known.worker else None)
        print(f"run folder: {out}")
        return 0
    if known.resume is None:  # write config.json here, so the worker resumes what was asked
        out.mkdir(parents=True, exist_ok=True)
        write_config(out, config)
    return supervise(out, quiet, known.max_restarts, known.stall_timeout)


if __name__ == "__main__":
    sys.exit(main())
