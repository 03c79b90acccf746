"""Novelty models as exploration bonuses: SIM (and its ablations), RND and ICM.

``make_novelty(config, num_actions, obs_shape)`` builds the ``Novelty`` object the learner is
given, after ``check_observation`` has made sure the model can read the observations.
"""

from __future__ import annotations

from simjax.novelty.base import Memory, RunningMeanStd, Timeline, build_timeline, in_episode, init_memory
from simjax.novelty.bonus import METRICS, Novelty, NoveltyState
from simjax.novelty.models import ICM, RND, SIM


def make_model(config, num_actions: int):
    """The model a TrainConfig names (None for ``a2c``)."""
    if config.algo == "a2c":
        return None
    if config.algo == "rnd":
        return RND(num_actions)
    if config.algo == "icm":
        return ICM(num_actions, forward_weight=config.forward_weight)
    if config.algo == "sim":
        return SIM(
            num_actions, obs_len=config.obs_len, act_len=config.act_len, combine=config.sim_combine,
            sequence=config.sim_sequence, target=config.sim_target, inverse=config.sim_inverse,
            forward_weight=config.forward_weight,
        )
    raise ValueError(f"unknown algo {config.algo!r}")


# RND's target (8x8 s4, 4x4 s2, 3x3 s1, all VALID) leaves at least one pixel from 36x36 frames
RND_TARGET_MIN_SIZE = 36


def check_observation(config, obs_shape) -> None:
    """A clear error if ``config.algo``'s model cannot read observations of ``obs_shape``."""
    if config.algo == "a2c":
        return
    shape = tuple(obs_shape)
    if len(shape) != 3:
        raise ValueError(
            f"ALGO={config.algo} reads image observations (height, width, channels); "
            f"{config.env} gives shape {shape}. Use ALGO=a2c for vector observations."
        )
    uses_rnd_target = config.algo == "rnd" or (config.algo == "sim" and config.sim_target == "rnd")
    if uses_rnd_target and min(shape[:2]) < RND_TARGET_MIN_SIZE:
        raise ValueError(
            f"ALGO={config.algo}'s RND target needs frames of at least {RND_TARGET_MIN_SIZE}x"
            f"{RND_TARGET_MIN_SIZE}; {config.env} gives {shape[0]}x{shape[1]}. "
            "Use ALGO=sim with --sim-target embed, or ALGO=icm."
        )


def make_novelty(config, num_actions: int, obs_shape=None) -> Novelty:
    if obs_shape is not None:
        check_observation(config, obs_shape)
    return Novelty(
        model=make_model(config, num_actions),
        bonus_scale=config.bonus_scale,
        gamma=config.gamma,
        obs_norm=config.obs_norm,
        bonus_norm=config.bonus_norm,
    )


__all__ = [
    "ICM", "METRICS", "Memory", "Novelty", "NoveltyState", "RND", "RunningMeanStd", "SIM",
    "Timeline", "build_timeline", "check_observation", "in_episode", "init_memory", "make_model",
    "make_novelty",
]
