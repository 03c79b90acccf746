"""Where the learner is assembled: the update rule ``config.learner`` names, and the rollout and
loop of ``simjax.agents.a2c`` around it.

The modules import one way: ``config`` < ``a2c`` (the rollout, the loss, A2C's rule, the loop)
< ``a3c`` (A3C's rule, built on a2c's loss) < this module, the one that knows both rules
(tests/test_imports.py checks it).
"""

from __future__ import annotations

from simjax.agents.a2c import RuleMaker, Trainer, a2c_rule, assemble_trainer
from simjax.agents.a3c import a3c_rule
from simjax.agents.config import LEARNERS, TrainConfig
from simjax.novelty import Novelty

RULES: dict[str, RuleMaker] = {"a2c": a2c_rule, "a3c": a3c_rule}
assert tuple(RULES) == LEARNERS


def make_trainer(config: TrainConfig, env=None, novelty: Novelty | None = None) -> Trainer:
    """The learner for ``config`` (``simjax.agents.a2c.Trainer``), with the update rule that
    ``config.learner`` names; ``novelty`` overrides the model ``config.algo`` names."""
    return assemble_trainer(config, RULES[config.learner], env, novelty)


def make_train(config: TrainConfig, env=None):
    """A pure ``train(key) -> (final RunnerState, per-chunk metrics)``; vmap it over keys."""
    return make_trainer(config, env).train
