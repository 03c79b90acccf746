"""Command line: ``python -m simjax.train --env maze-very-sparse ...`` (``make train``).

Config in, run folder out (``simjax.runs.folder`` lists its files); ``--resume`` continues a
plain run or a sweep (``simjax.sweep``). Every run setting is a
flag of ``TrainConfig``; bad values and tasks the learner cannot read fail here, before
anything compiles or is written. A stopped run (Ctrl-C) keeps every row it wrote and still
saves its checkpoint and curve; ``--resume FOLDER`` goes on from there.

The run itself goes on in a worker process that a supervisor restarts from the checkpoint
when XLA:CPU stalls (``simjax.runs.stall``); ``--no-supervise`` trains in this process.
"""

from __future__ import annotations

import argparse
import datetime as dt
import sys
from pathlib import Path

from simjax import flags, runtime
from simjax.agents import TrainConfig, make_trainer
from simjax.runs import Diverged, folder, run, stall


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m simjax.train",
        description="Train an LSTM actor-critic (with an exploration bonus) on a simjax task.",
    )
    flags.add_config_flags(parser)
    parser.add_argument("--out", type=Path, default=None, help="run folder (default: runs/ENV-ALGO-TIME)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--tensorboard", action="store_true",
                        help="also write the metrics as TensorBoard event files in OUT/tensorboard (tensorboardX)")
    parser.add_argument("--resume", type=Path, default=None,
                        help="continue the run in this folder from its checkpoint (no run settings, no --out)")
    parser.add_argument("--no-supervise", action="store_true",
                        help="train in this process, without restarting it when XLA stalls")
    parser.add_argument("--max-restarts", type=int, default=20, help="restarts after XLA stalls (default: 20)")
    parser.add_argument("--stall-timeout", type=float, default=300.0,
                        help="seconds the first compiled call may take before it counts as stalled (default: 300)")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    return parser


def parse_config(argv=None) -> tuple[TrainConfig, Path, argparse.Namespace]:
    """Parse and check a command line: (the run's config, its folder, every flag). Each
    refusal is argparse's one-line error (exit status 2), before anything is written."""
    parser = build_parser()
    args = parser.parse_args(argv)
    given = flags.given_settings(args)
    if args.tensorboard:
        missing = folder.tensorboard_available()
        if missing:
            parser.error(missing)
    if args.resume is not None:
        if given or args.out is not None:
            parser.error("--resume continues a run with its own config.json; give no run settings and no --out")
        try:
            return folder.load_config(args.resume), args.resume, args
        except (FileNotFoundError, ValueError, TypeError) as err:
            parser.error(str(err))
    try:
        config = TrainConfig(**given)
    except ValueError as err:
        parser.error(str(err))
    return config, new_run_folder(parser, config, args.out), args


def new_run_folder(parser: argparse.ArgumentParser, config: TrainConfig, out: Path | None, kind: str = "") -> Path:
    """The folder a new run (``kind``: "-sweep" for a sweep) trains into, default
    runs/ENV-ALGO[KIND]-TIME; refused (argparse's error) if it holds a run or if the learner
    cannot be built for the task (its action space, its frames), before the worker starts."""
    if out is None:
        stamp = dt.datetime.now().strftime("%Y%m%d-%H%M%S")
        out = Path("runs") / f"{config.env}-{config.algo}{kind}-{stamp}"
    if (out / "metrics.csv").exists():
        parser.error(f"{out} already holds a run (metrics.csv); choose another --out")
    try:
        make_trainer(config)
    except ValueError as err:
        parser.error(str(err))
    return out


def worker_command(out: Path, args: argparse.Namespace):
    """The command of a training process that resumes ``out``, its first call allowed ``limit`` s."""
    def command(limit: float) -> list[str]:
        return ([sys.executable, "-m", "simjax.train", "--resume", str(out), "--worker", "--stall-timeout", str(limit)]
                + ["--quiet"] * args.quiet + ["--tensorboard"] * args.tensorboard)

    return command


def main(argv=None) -> int:
    runtime.split_cpu()  # one XLA device per core: members shard over them (BENCHMARKS.md: x1.06 for 2 seeds)
    runtime.configure()
    config, out, args = parse_config(argv)
    if args.worker or args.no_supervise:
        try:
            run(config, out, args.quiet, resume=args.resume is not None,
                stall_limit=args.stall_timeout if args.worker else None, tensorboard=args.tensorboard,
                sweep=folder.load_sweep(out) if args.resume is not None else None)
        except Diverged as err:
            print(f"python -m simjax.train: error: {err}", file=sys.stderr)
            return 1
        print(f"run folder: {out}")
        return 0
    if args.resume is None:  # write config.json here, so the worker resumes what was asked
        out.mkdir(parents=True, exist_ok=True)
        folder.write_config(out, config)
    return stall.supervise(worker_command(out, args), out, args.max_restarts, args.stall_timeout)


if __name__ == "__main__":
    sys.exit(main())
