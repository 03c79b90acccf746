"""The learner: rollouts, the A2C loss, the jitted update and ``make_train(config)``."""

from simjax.agents.a2c import (
    RunnerState,
    Trainer,
    Transition,
    a2c_loss,
    n_step_returns,
    sampling_policy,
    summarize,
    total_reward,
)
from simjax.agents.config import ALGOS, SWEEPABLE, Hyper, TrainConfig
from simjax.agents.trainer import make_train, make_trainer

__all__ = [
    "ALGOS", "SWEEPABLE", "Hyper", "RunnerState", "TrainConfig", "Trainer", "Transition", "a2c_loss", "make_train",
    "make_trainer", "n_step_returns", "sampling_policy", "summarize", "total_reward",
]
