"""Command line: ``python -m simjax.sweep --env maze-very-sparse --algo sim --act-len 1,2,3,4,5``
(``make sweep``).

The flags are ``simjax.train``'s; a setting in ``SWEEPABLE`` (learning rate, discount, loss
weights, beta, lambda, eta, SIM's H and L) may take comma-separated values. Every combination
of them, times ``--num-seeds`` seeds, trains side by side in one run folder as one
``jax.vmap`` inside one ``jax.jit``, compiled once: the swept values are arrays in the runner
state, and SIM's windows are laid out for the largest H and L and masked. metrics.csv gets a
column per swept setting; ``--resume FOLDER`` (here or in ``simjax.train``) continues a sweep.
Bad values fail here, naming the flag, before anything compiles or is written.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from simjax import flags
from simjax.novelty.settings import flag
from simjax.runs import folder
from simjax.runs.grid import check_sweep
from simjax.train import add_checkpoint_flag, new_run_folder, train


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m simjax.sweep",
        description="Train every combination of the comma-separated settings, side by side, in one compiled program.",
    )
    flags.add_config_flags(parser, lists=True)
    parser.add_argument("--out", type=Path, default=None, help="run folder (default: runs/ENV-ALGO-sweep-TIME)")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.add_argument("--tensorboard", action="store_true", help="also write TensorBoard event files")
    add_checkpoint_flag(parser)
    return parser


def parse_sweep(argv=None):
    """(config, grid, sweep, out, args); each refusal is argparse's one-line error (exit 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    given = flags.with_command_defaults(flags.given_settings(args), lists=True)
    settings, sweep = {}, {}
    for name, values in given.items():
        if not values:
            parser.error(f"{flag(name)} has an empty list of values")
        if len(values) == 1:
            settings[name] = values[0]
        else:
            sweep[name] = values
    if args.tensorboard and folder.tensorboard_available():
        parser.error(folder.tensorboard_available())
    try:
        config, grid = check_sweep(settings, sweep)
    except ValueError as err:
        parser.error(str(err))
    return config, grid, sweep, new_run_folder(parser, config, args.out, "-sweep"), args


def main(argv=None) -> int:
    config, grid, sweep, out, args = parse_sweep(argv)
    if not args.quiet:
        print(f"sweep: {len(grid)} points x {config.num_seeds} seed(s) = {len(grid) * config.num_seeds} members, "
              "one compiled program", file=sys.stderr)
    return train(config, out, args, sweep)


if __name__ == "__main__":
    sys.exit(main())
