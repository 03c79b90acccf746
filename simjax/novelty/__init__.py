"""Novelty models as exploration bonuses: SIM (and its ablations), RND and ICM.

``make_novelty(config, num_actions)`` builds the ``Novelty`` object the learner is given.
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


def make_novelty(config, num_actions: int) -> Novelty:
    return Novelty(
        model=make_model(config, num_actions),
        bonus_scale=config.bonus_scale,
        gamma=config.gamma,
        obs_norm=config.obs_norm,
        bonus_norm=config.bonus_norm,
    )


__all__ = [
    "ICM", "METRICS", "Memory", "Novelty", "NoveltyState", "RND", "RunningMeanStd", "SIM",
    "Timeline", "build_timeline", "in_episode", "init_memory", "make_model", "make_novelty",
]
