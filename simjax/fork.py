"""Fork a run: a new run folder that goes on from another's checkpoint with some settings changed.

    python -m simjax.fork SRC DST --bonus-scale 0.001 [--total-steps 6000000] [...]
    python -m simjax.train --resume DST

DST gets SRC's metrics.csv and checkpoint and SRC's config with the given flags changed (the
same flags as ``simjax.train``, limited to those that leave the run's state meaningful: learning
and reward settings, not the task, model sizes or seeds). A change that adds parameters (e.g.
``--bonus-episodic false`` adds the bonus's value head) gets them freshly initialised; every
other parameter, optimiser moment, environment and novelty memory is SRC's. ``DST/fork.json``
records where it came from, at which step, what changed and which leaves are new; SRC is
never written to. A fork is not a run from scratch: its curve has SRC's rows up to the fork.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as dt
import json
import shutil
import sys
from pathlib import Path

from simjax.agents.config import TrainConfig
from simjax.train import atomic_write, build_parser, load_config, write_config

# settings a fork may change: how it learns and what it is paid, not what it is
FORKABLE = ("total_steps", "learning_rate", "gamma", "value_coef", "entropy_coef", "max_grad_norm", "task_scale",
            "bonus_scale", "forward_weight", "rl_weight", "bonus_norm", "bonus_episodic")


def _graft(fresh, old, path=""):
    """``fresh``'s tree with ``old``'s leaf wherever the same path has the same shape; and the
    paths that kept the fresh value."""
    if isinstance(fresh, dict):
        out, new = {}, []
        for k, v in fresh.items():
            sub = old.get(k) if isinstance(old, dict) else None
            out[k], n = _graft(v, sub, f"{path}/{k}")
            new += n
        return out, new
    if fresh is None or (old is not None and getattr(old, "shape", None) == getattr(fresh, "shape", None)):
        return old, []  # (a None field, e.g. a fixed map's per-episode world, stays None)
    return fresh, [path]


def fork(src: Path, dst: Path, changes: dict) -> list[str]:
    """Write the fork; returns the leaves (paths in the checkpoint) that are freshly initialised."""
    import jax
    from flax import serialization

    from simjax.agents import make_trainer
    from simjax.train import load_checkpoint, seed_keys

    src, dst = Path(src), Path(dst)
    old_config = load_config(src)
    if not (src / "checkpoint.msgpack").exists():
        raise FileNotFoundError(f"{src} has no checkpoint.msgpack to fork from")
    if dst.exists():
        raise FileExistsError(f"{dst} exists; a fork writes a new run folder")
    bad = sorted(set(changes) - set(FORKABLE))
    if bad:
        raise ValueError(f"a fork cannot change {', '.join(bad)}; it may change {', '.join(FORKABLE)}")
    config = dataclasses.replace(old_config, **changes)  # validates
    ckpt = load_checkpoint(src)
    if int(ckpt["env_steps"]) >= config.total_steps:
        raise ValueError(f"{src} is at {int(ckpt['env_steps']):,} steps; give a larger --total-steps")
    fresh = jax.jit(jax.vmap(make_trainer(config).init))(seed_keys(config))
    runner, new_leaves = _graft(serialization.to_state_dict(jax.device_get(fresh)), ckpt["runner"])

    dst.mkdir(parents=True)
    shutil.copyfile(src / "metrics.csv", dst / "metrics.csv")
    write_config(dst, config)
    state = {"runner": runner, "env_steps": ckpt["env_steps"], "seeds": ckpt["seeds"]}
    atomic_write(dst / "checkpoint.msgpack", serialization.msgpack_serialize(state))
    record = {
        "from": str(src), "env_steps": int(ckpt["env_steps"]), "date": dt.date.today().isoformat(),
        "changed": {k: [getattr(old_config, k), v] for k, v in changes.items()}, "new_leaves": new_leaves,
    }
    atomic_write(dst / "fork.json", json.dumps(record, indent=2).encode())
    return new_leaves


def main(argv=None) -> int:
    parser = build_parser()
    parser.prog, parser.description = "python -m simjax.fork", __doc__.split("\n")[0]
    for action in parser._actions:  # only the flags given count as changes
        action.default = argparse.SUPPRESS
    parser.add_argument("src", type=Path)
    parser.add_argument("dst", type=Path)
    args = vars(parser.parse_args(argv))
    src, dst = args.pop("src"), args.pop("dst")
    fields = {f.name for f in dataclasses.fields(TrainConfig)}
    changes = {k: v for k, v in args.items() if k in fields}
    if set(args) - fields:
        parser.error(f"a fork takes config flags only, not {', '.join('--' + k for k in set(args) - fields)}")
    if not changes:
        parser.error("give at least one setting to change")
    try:
        new = fork(src, dst, changes)
    except (FileNotFoundError, FileExistsError, ValueError, TypeError) as err:
        parser.error(str(err))
    print(f"forked {src} -> {dst}: {changes}; new leaves: {len(new)}; go on with python -m simjax.train --resume {dst}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
