"""Forking a run: a new run folder that goes on from another's checkpoint with some settings
changed (``python -m simjax.fork`` is its command line).

The new folder gets the source's metrics.csv and checkpoint and its config with the changes
applied, limited to settings that leave the run's state meaningful (``FORKABLE``: learning and
reward settings, not the task, model sizes or seeds). A change that adds parameters (e.g.
``bonus_episodic=False`` adds the bonus's value head) gets them freshly initialised; every
other parameter, optimiser moment, environment and novelty memory is the source's. fork.json
records where it came from, at which step, what changed and which leaves are new; the source
is never written to. A fork is not a run from scratch: its curve has the source's rows up to
the fork.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import shutil
from pathlib import Path

from simjax.novelty.settings import flag
from simjax.runs.folder import EXPORT, atomic_write, restore, seed_keys, write_checkpoint, write_config, write_export

# settings a fork may change: how it learns and what it is paid, not what it is
FORKABLE = ("total_steps", "learning_rate", "gamma", "value_coef", "entropy_coef", "max_grad_norm", "task_scale",
            "bonus_scale", "forward_weight", "rl_weight", "bonus_norm", "bonus_episodic", "task_gamma",
            "task_advantage_weight", "precision")


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

    src, dst = Path(src), Path(dst)
    source = restore(src)
    if source.sweep:
        raise ValueError(f"{src} is a sweep ({', '.join(map(flag, source.sweep))}); a fork goes on from one run's "
                         "seeds, not from a grid of points")
    if source.exported:
        raise FileNotFoundError(f"{src} has no checkpoint.msgpack: a fork goes on from the whole state, "
                                f"not from the policy in {EXPORT}/")
    if dst.exists():
        raise FileExistsError(f"{dst} exists; a fork writes a new run folder")
    bad = sorted(set(changes) - set(FORKABLE))
    if bad:
        raise ValueError(f"a fork cannot change {', '.join(map(flag, bad))}; it may change "
                         f"{', '.join(map(flag, FORKABLE))}")
    config = dataclasses.replace(source.config, **changes)  # validates
    if source.env_steps >= config.total_steps:
        raise ValueError(f"{src} is at {source.env_steps:,} steps; give a larger --total-steps")
    fresh = jax.jit(jax.vmap(make_trainer(config).init))(seed_keys(config))
    runner, new_leaves = _graft(serialization.to_state_dict(jax.device_get(fresh)), source.state)
    runner["hyper"] = serialization.to_state_dict(jax.device_get(fresh.hyper))  # the fork's settings, not the source's

    dst.mkdir(parents=True)
    shutil.copyfile(src / "metrics.csv", dst / "metrics.csv")
    write_config(dst, config)
    write_checkpoint(dst, runner, source.env_steps, source.seeds)
    write_export(dst, runner, source.env_steps, source.seeds)
    record = {
        "from": str(src), "env_steps": source.env_steps, "date": dt.date.today().isoformat(),
        "changed": {k: [getattr(source.config, k), v] for k, v in changes.items()}, "new_leaves": new_leaves,
    }
    atomic_write(dst / "fork.json", json.dumps(record, indent=2).encode())
    return new_leaves
