"""Command line: ``python -m simjax.train --env maze-very-sparse ...`` (``make train``).

Config in, run folder out (``simjax.runs.folder`` lists its files); ``--resume`` continues a
plain run or a sweep (``simjax.sweep``). Every run setting is a
flag of ``TrainConfig``; bad values and tasks the learner cannot read fail here, before
anything compiles or is written. A stopped run (Ctrl-C, or SIGTERM as ``kill`` and job
schedulers send) keeps every row it wrote and still saves its checkpoint and curve;
``--resume FOLDER`` goes on from there.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as dt
import signal
import sys
from pathlib import Path

from simjax import flags
from simjax.agents import TrainConfig, make_trainer
from simjax.runs import Diverged, folder, run
from simjax.runs.training import CHECKPOINT_EVERY, PRETRAIN_STATE, read_pretrain_state


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
    add_checkpoint_flag(parser)
    return parser


def seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not (value >= 0 and value != float("inf")):
        raise argparse.ArgumentTypeError(f"expected a number of seconds >= 0, got {text!r}")
    return value


def add_checkpoint_flag(parser: argparse.ArgumentParser) -> None:
    """``--checkpoint-every``: how the command saves, not what the run is, so ``--resume`` takes it."""
    parser.add_argument("--checkpoint-every", type=seconds, default=CHECKPOINT_EVERY, metavar="SECONDS",
                        help="rewrite the checkpoint (every seed's whole state) after a row once this long has "
                             "passed since the last; 0: after every row. The end, Ctrl-C and SIGTERM always "
                             "write one; a kill -9 loses the rows since the last, which --resume trains again "
                             f"(default: {CHECKPOINT_EVERY:.0f})")


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
            config = folder.load_config(args.resume)
            folder.check_resumable(args.resume)
            if (args.resume / "checkpoint.msgpack").exists():
                folder.load_checkpoint(args.resume)
            if (args.resume / PRETRAIN_STATE).exists():
                read_pretrain_state(args.resume, config.pretrain_plan)
        except (FileNotFoundError, ValueError, TypeError) as err:
            parser.error(str(err))
        return config, args.resume, args
    try:
        config = TrainConfig(**flags.with_command_defaults(given))
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


@contextlib.contextmanager
def stopped_like_ctrl_c():
    """Within it, SIGTERM (what ``kill``, ``timeout`` and job schedulers send) stops the process
    as Ctrl-C does, with a ``KeyboardInterrupt`` in the main thread, so that a run saves its
    rows and checkpoint. Only the first SIGINT or SIGTERM interrupts: later ones are ignored, so
    a second signal cannot cut the saving short (SIGKILL still ends the process). Yields a dict
    whose "signal" is the signal that stopped it, or None."""
    previous = {s: signal.getsignal(s) for s in folder.STOP_SIGNALS}
    got = {"signal": None}

    def stop(signum, frame):
        for s in folder.STOP_SIGNALS:
            signal.signal(s, signal.SIG_IGN)
        got["signal"] = signum
        raise KeyboardInterrupt

    for s in folder.STOP_SIGNALS:
        signal.signal(s, stop)
    try:
        yield got
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def train(config: TrainConfig, out: Path, args: argparse.Namespace, sweep: dict | None = None,
          resume: bool = False) -> int:
    """Train into ``out`` (``resume``: go on from its checkpoint); the command's exit status:
    0 when finished, 130 when stopped by Ctrl-C or SIGTERM (its rows and checkpoint saved), 1
    when the run diverged."""
    with stopped_like_ctrl_c() as got:
        try:
            run(config, out, args.quiet, resume=resume, tensorboard=args.tensorboard, sweep=sweep,
                checkpoint_every=args.checkpoint_every)
        except Diverged as err:
            print(f"python -m simjax.train: error: {err}", file=sys.stderr)
            return 1
        except KeyboardInterrupt:  # stopped before the training loop (compiling): the folder keeps what it has
            print(f"\nstopped; run folder: {out}", file=sys.stderr)
            return 130
    print(f"run folder: {out}")
    return 130 if got["signal"] is not None else 0


def main(argv=None) -> int:
    config, out, args = parse_config(argv)
    resume = args.resume is not None
    return train(config, out, args, folder.load_sweep(out) if resume else None, resume)


if __name__ == "__main__":
    sys.exit(main())
