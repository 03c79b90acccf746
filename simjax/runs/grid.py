"""A sweep: the grid of settings one run folder trains side by side, in one compiled program.

A run trains a batch of *members*, one per (sweep point, seed), point-major: member
``p * num_seeds + s`` is point ``p`` with seed ``config.seed + s``. A plain run is the sweep of
one point, ``{}``. Only settings in ``SWEEPABLE`` can vary (they are arrays in the runner state,
``Hyper``); the run's config is laid out for the largest H and L of the grid, and every point's
own values travel in its members' ``hyper``.
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np

from simjax.agents import SWEEPABLE, TrainConfig
from simjax.agents.config import INT_SETTINGS
from simjax.novelty.settings import flag

Point = dict  # field name -> value


def grid_of(sweep: dict[str, list]) -> list[Point]:
    """Every combination of the swept values, the first field varying slowest."""
    fields = list(sweep)
    return [dict(zip(fields, values)) for values in itertools.product(*(sweep[f] for f in fields))]


def check_sweep(settings: dict, sweep: dict[str, list]) -> tuple[TrainConfig, list[Point]]:
    """The run's config (``settings`` with windows for the largest swept H and L) and its grid.

    Raises ValueError, naming the flag, for a field that cannot be swept (it changes array
    shapes, or means nothing for ``--algo``), an empty or repeated list, or a value the
    config refuses (each point is checked as a config of its own)."""
    for name, values in sweep.items():
        if name not in SWEEPABLE:
            raise ValueError(f"{flag(name)} cannot be swept: it changes the compiled program's shapes or "
                             f"structure; sweepable: {', '.join(map(flag, SWEEPABLE))}")
        if not len(values):
            raise ValueError(f"{flag(name)} has an empty list of values")
        if len(set(values)) != len(values):
            raise ValueError(f"{flag(name)} repeats a value: {values}")
        if name in INT_SETTINGS and any(int(v) != v for v in values):
            raise ValueError(f"{flag(name)} takes integers, got {values}")
    algo = settings.get("algo", TrainConfig.algo)
    swept = {k for k, v in sweep.items() if len(v) > 1}
    pointless = ({"bonus_scale", "forward_weight", "rl_weight", "obs_len", "act_len"} if algo == "a2c"
                 else {"obs_len", "act_len"} if algo not in ("sim", "e3b-sim") else set()) & swept
    if algo in ("rnd", "ec", "e3b"):  # no forward / inverse split of the model's loss
        pointless |= {"forward_weight"} & swept
    if pointless:
        raise ValueError(f"sweeping {', '.join(map(flag, sorted(pointless)))} changes nothing for --algo {algo}")
    grid = grid_of(sweep)
    for point in grid:  # each point a valid config (errors name the flag)
        TrainConfig(**{**settings, **point})
    widest = {k: max(p[k] for p in grid) for k in INT_SETTINGS if k in sweep}
    return TrainConfig(**{**settings, **grid[0], **widest}), grid


def point_config(config: TrainConfig, point: Point) -> TrainConfig:
    """The config one point of the sweep trains with (its H and L within the run's windows)."""
    return dataclasses.replace(config, **point)


def members(config: TrainConfig, grid: list[Point]) -> list[tuple[Point, int]]:
    """(point, seed) of every member of the batch, in batch order."""
    return [(point, config.seed + s) for point in grid for s in range(config.num_seeds)]


def batch_inputs(config: TrainConfig, grid: list[Point]):
    """The PRNG keys (B, 2) and the ``Hyper`` (leading axis B) of every member. Seeds repeat
    across points: every point starts from the same keys, so points differ only by settings
    (and EC's pretraining, which reads none of them, is done once per seed and shared by the
    seed's members: ``simjax.runs.training.pretrain``)."""
    import jax
    import jax.numpy as jnp

    keys = jnp.stack([jax.random.PRNGKey(seed) for _, seed in members(config, grid)])
    hypers = [point_config(config, point).hyper() for point, _ in members(config, grid)]
    return keys, jax.tree.map(lambda *xs: jnp.asarray(np.stack(xs)), *hypers)
