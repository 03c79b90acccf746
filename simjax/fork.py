"""Command line: fork a run, a new run folder that goes on from another's checkpoint with some
settings changed (``simjax.runs.fork`` says what carries over).

    python -m simjax.fork SRC DST --bonus-scale 0.001 [--total-steps 6000000] [...]
    python -m simjax.train --resume DST

The flags are ``simjax.train``'s run settings; only those given count as changes, and only
learning and reward settings may change (``simjax.runs.fork.FORKABLE``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from simjax import flags


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m simjax.fork", description=__doc__.split("\n")[0])
    parser.add_argument("src", type=Path, help="the run folder to go on from (never written to)")
    parser.add_argument("dst", type=Path, help="the new run folder")
    flags.add_config_flags(parser, title="settings to change (default: the source's)")
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    changes = flags.given_settings(args)
    if not changes:
        parser.error("give at least one setting to change")
    from simjax.runs import fork

    try:
        new = fork(args.src, args.dst, changes)
    except (FileNotFoundError, FileExistsError, ValueError, TypeError) as err:
        parser.error(str(err))
    print(f"forked {args.src} -> {args.dst}: {changes}; new leaves: {len(new)}; "
          f"go on with python -m simjax.train --resume {args.dst}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
