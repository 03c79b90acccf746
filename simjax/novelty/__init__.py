"""Novelty models as exploration bonuses: SIM (and its ablations), RND, ICM, EC, E3B
and E3B x SIM.

``make_novelty(settings, num_actions, obs_shape)`` builds the ``Novelty`` object the learner is
given from typed ``NoveltySettings``, after ``check_observation`` has made sure the model can
read the observations.
"""

from __future__ import annotations

from simjax.novelty.base import Memory, RunningMeanStd, Timeline, build_timeline, in_episode, init_memory
from simjax.novelty.bonus import METRICS, Novelty, NoveltyState
from simjax.novelty.e3b import E3B
from simjax.novelty.e3b_sim import E3BSIM
from simjax.novelty.ec import EC
from simjax.novelty.models import ICM, RND, SIM, Windows
from simjax.novelty.settings import MODELS, NoveltyHyper, NoveltySettings, check_observation


def make_model(settings: NoveltySettings, num_actions: int):
    """The model ``settings.algo`` names (None for ``a2c``)."""
    if settings.algo == "rnd":
        return RND(num_actions)
    if settings.algo == "icm":
        return ICM(num_actions, forward_weight=settings.forward_weight)
    if settings.algo in ("sim", "e3b-sim"):
        sim = SIM(
            num_actions, obs_len=settings.obs_len, act_len=settings.act_len, combine=settings.sim_combine,
            sequence=settings.sim_sequence, target=settings.sim_target, inverse=settings.sim_inverse,
            forward_weight=settings.forward_weight,
        )
        return sim if settings.algo == "sim" else E3BSIM(E3B(num_actions, ridge=settings.e3b_ridge), sim)
    if settings.algo == "ec":
        return EC(num_actions, capacity=settings.ec_memory, width=settings.ec_width, features=settings.ec_embed,
                  online=settings.ec_online, beta=settings.ec_beta)
    if settings.algo == "e3b":
        return E3B(num_actions, ridge=settings.e3b_ridge)
    return None


def make_novelty(settings: NoveltySettings, num_actions: int, obs_shape=None, task: str = "this task") -> Novelty:
    if obs_shape is not None:
        check_observation(settings, obs_shape, task)
    return Novelty(
        model=make_model(settings, num_actions),
        bonus_scale=settings.bonus_scale,
        gamma=settings.gamma,
        obs_norm=settings.obs_norm,
        bonus_norm=settings.bonus_norm,
    )


__all__ = [
    "E3B", "E3BSIM", "EC", "ICM", "METRICS", "MODELS", "Memory", "Novelty", "NoveltyHyper", "NoveltySettings", "NoveltyState", "RND",
    "RunningMeanStd", "SIM", "Timeline", "Windows", "build_timeline", "check_observation", "in_episode", "init_memory",
    "make_model", "make_novelty",
]
