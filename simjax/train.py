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


def _atomic_write(path: Path, data: bytes) -> None:
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


def run(config: TrainConfig, out: Path, quiet: bool = False) -> Path:
    import jax
    import numpy as np
    from flax import serialization

    from simjax import plotting
    from simjax.agents import make_trainer, summarize

    enable_compilation_cache()
    out.mkdir(parents=True, exist_ok=True)
    versions = {m: __import__(m).__version__ for m in ("jax", "flax", "optax", "brax")}
    _atomic_write(
        out / "config.json",
        json.dumps({"config": dataclasses.asdict(config), "versions": versions}, indent=2).encode(),
    )

    trainer = make_trainer(config)
    seeds = [config.seed + i for i in range(config.num_seeds)]
    keys = jax.numpy.stack([jax.random.PRNGKey(s) for s in seeds])
    runner = jax.jit(jax.vmap(trainer.init))(keys)

    def chunk_and_summarize(r):
        r, metrics = trainer.run_chunk(r)
        return r, summarize(metrics)

    # no buffer donation: a Ctrl-C must leave the last finished runner intact to be saved
    chunk = jax.jit(jax.vmap(chunk_and_summarize))

    def save_checkpoint(runner, steps):
        state = {"params": serialization.to_state_dict(jax.device_get(runner.params)),
                 "env_steps": steps, "seeds": seeds}
        _atomic_write(out / "checkpoint.msgpack", serialization.msgpack_serialize(state))

    steps_per_chunk = config.updates_per_log * config.steps_per_update
    total = config.num_logs * steps_per_chunk
    progress = Progress(total, quiet, config.num_seeds)
    start = time.perf_counter()
    done_steps = 0
    if not quiet:
        print(f"compiling {config.algo} on {config.env} ({config.num_seeds} seed(s), "
              f"{config.num_envs} envs each); run folder {out}", file=sys.stderr, flush=True)
    try:
        with open(out / "metrics.csv", "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(METRIC_COLUMNS)
            last = time.perf_counter()
            for _ in range(config.num_logs):
                next_runner, metrics = chunk(runner)
                metrics = jax.device_get(metrics)
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
    finally:
        progress.close()
        save_checkpoint(runner, done_steps)
        if done_steps:
            plotting.plot_run(out)
    return out


def main(argv=None) -> int:
    config, out, quiet = parse_config(argv)
    run(config, out, quiet)
    print(f"run folder: {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
