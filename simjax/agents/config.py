"""The one typed configuration of a training run; the command line is generated from it.

Defaults follow the paper's LSTM-A3C (appendix A.5 and table B.2): value-loss weight 0.5,
entropy weight 0.01, 20-step rollouts, discount 0.99, Adam; A3C's 16 asynchronous actors
become ``num_envs`` = 16 synchronous environments. One default differs: the learning rate is
1e-3, not the paper's 1e-4. A3C applies each actor's 20-step gradient on its own, so per agent
step it makes 16x the updates of a synchronous batch of 16; at 1e-4 (and 3e-4) synchronous
A2C did not move off the random policy's success on maze-dense in 1M steps, at 1e-3 it did
(docs/results.md has the runs).

``learner="a3c"`` (``simjax.agents.a3c``) is A3C's update rule as the ICM code runs it (each
actor's steps cut at episode ends into pieces, one step per piece, in sequence, of one Adam per
parameter group that all actors share: the ICM code's Adam slots live on its parameter server
and its chief alone initialises them, src/worker.py:41-43, 78-85; ``a3c`` runs before that
gave each actor an Adam of its own), and its defaults are that code's: learning rate 1e-4,
gradient clip 40, value weight 0.25 on the mean squared error (its 0.5 times half the squared
error), rewards clipped to [-1, 1] where the task's rewards lie there anyway, no bootstrap at
the time limit (``LEARNER_DEFAULTS``).
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np

from simjax.envs import check_name, episodes_end_early, is_mywayhome
from simjax.novelty.settings import MODELS, NoveltyHyper, NoveltySettings, PretrainPlan, flag

ALGOS = ("a2c",) + MODELS
LEARNERS = ("a2c", "a3c")
# the settings whose default depends on the learner: A2C's are simjax's own (docs/paper-differences.md),
# A3C's the ICM code's (pathak22/noreward-rl, src/constants.py and src/a3c.py; simjax.agents.a3c)
LEARNER_DEFAULTS = {
    "a2c": {"learning_rate": 1e-3, "value_coef": 0.5, "max_grad_norm": 0.5, "bootstrap_time_limit": True},
    "a3c": {"learning_rate": 1e-4, "value_coef": 0.25, "max_grad_norm": 40.0, "bootstrap_time_limit": False},
}
# paper tables B.2, C.2, D.2 (ViZDoom): bonus reward scale beta per method (EC's is its alpha)
PAPER_BONUS_SCALE = {"a2c": 0.0, "sim": 0.001, "rnd": 0.01, "icm": 0.01, "ec": 0.01}
# E3B is not in the paper: the least harmful beta of a sweep here (1e-6, 5e-6, 3e-5 on
# maze-very-sparse, within its authors' ViZDoom range 3e-7 ... 3e-5); docs/paper-differences.md
DEFAULT_BONUS_SCALE = {**PAPER_BONUS_SCALE, "e3b": 1e-6, "e3b-sim": 1e-6}
# the settings that change no array shape once windows are laid out for their largest values:
# they are arrays in the runner state (``Hyper``), so a sweep over them is one compiled program
SWEEPABLE = ("learning_rate", "gamma", "value_coef", "entropy_coef", "max_grad_norm", "task_scale",
             "bonus_scale", "forward_weight", "rl_weight", "obs_len", "act_len")
INT_SETTINGS = ("obs_len", "act_len")


class Hyper(NamedTuple):
    """A run's numeric settings as arrays (``TrainConfig.hyper``), carried in the runner state."""

    learning_rate: np.ndarray
    gamma: np.ndarray
    value_coef: np.ndarray
    entropy_coef: np.ndarray
    max_grad_norm: np.ndarray
    task_scale: np.ndarray
    policy_weight: np.ndarray  # eta where a novelty model shares the objective, else 1
    novelty: NoveltyHyper


def rewards_within_one(env: str) -> bool:
    """Whether every reward of task ``env`` lies in [-1, 1] (MyWayHome's and maze-tiny's goal,
    +1), so that clipping the reward to it changes only the bonus; melon's +20 and explore-goals'
    +10 do not, and a gymnax environment's rewards are not known here."""
    return env == "maze-tiny" or is_mywayhome(env)


def _f(default, help):
    return dataclasses.field(default=default, metadata={"help": help})


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    env: str = _f("maze-very-sparse", "task name (see simjax.envs.TASK_NAMES), or gymnax:NAME")
    algo: str = _f("a2c", "exploration method: " + ", ".join(ALGOS))
    total_steps: int = _f(2_000_000, "agent steps per seed (each is 4 simulator tics)")
    num_envs: int = _f(16, "synchronous environments per seed (N)")
    rollout_len: int = _f(20, "steps per environment per update (T), n-step return horizon")
    learner: str = dataclasses.field(default="a2c", metadata={
        "choices": LEARNERS,
        "help": "update rule: a2c (one Adam step on the N envs' mean loss) | a3c (each env an actor, its steps cut "
                "at episode ends into pieces, each piece's gradient of 20 x its mean loss applied one after another "
                "to one Adam the actors share: A3C's rule as the ICM code runs it)"})
    learning_rate: float | None = _f(None, "Adam learning rate (default: 1e-3 with --learner a2c; the paper's "
                                     "1e-4 with a3c)")
    gamma: float = _f(0.99, "discount")
    value_coef: float | None = _f(None, "weight of the value loss, the mean squared n-step error (default: 0.5 "
                                  "with --learner a2c; 0.25 with a3c, the ICM code's 0.5 x half the squared error)")
    entropy_coef: float = _f(0.01, "weight of the policy entropy bonus")
    max_grad_norm: float | None = _f(None, "global gradient-norm clip, per parameter group (policy, novelty "
                                     "model) (default: 0.5 with --learner a2c; 40, per piece's gradient, with a3c)")
    task_scale: float = _f(1.0, "scale of the extrinsic reward: r = task_scale * r_e + bonus")
    reward_clip: bool | None = _f(None, "clip each step's reward r (task plus bonus) to [-1, 1], as the ICM code "
                                  "does in its Doom runs (default: on with --learner a3c where the task's "
                                  "rewards lie in [-1, 1], the maze-* tasks; off otherwise)")
    bootstrap_time_limit: bool | None = _f(None, "an episode cut by its time limit bootstraps its return from "
                                           "the value of its last frame (default: true with --learner a2c; "
                                           "false with a3c, the ICM code's rule: the return ends there)")
    seed: int = _f(0, "first seed; seeds are seed, seed+1, ...")
    num_seeds: int = _f(1, "seeds trained together as one jax.vmap")
    log_every: int = _f(25_000, "agent steps per seed between metric rows (rounded to updates)")
    # novelty models (ignored by a2c); eq. (8): lambda L_F + (1 - lambda) L_I - eta * RL objective
    bonus_scale: float | None = _f(None, "beta, r = task_scale * r_e + beta * r+ (default: the paper's, "
                                   "sim 0.001, rnd 0.01, icm 0.01, ec 0.01; e3b 1e-6, the least harmful of a "
                                   "sweep here: docs/paper-differences.md)")
    forward_weight: float = _f(0.2, "lambda, forward vs inverse loss weight (sim, icm)")
    rl_weight: float = _f(0.1, "eta, weight of the RL loss against the novelty model's")
    obs_len: int = _f(10, "SIM: H, frames in the observation window (>= 2)")
    act_len: int = _f(3, "SIM: L, actions after the window, predicted open loop (>= 1)")
    sim_combine: str = _f("full", "SIM: h = full [ho, ha, ho*ha] | itr ho*ha | concat [ho, ha]")
    sim_sequence: str = _f("lstm", "SIM: lstm (two LSTMs) | ff (SIM-no-Seq: fc over stacked windows)")
    sim_target: str = _f("rnd", "SIM: rnd (fixed random target) | embed (SIM-no-RND: f_e(o_t))")
    sim_inverse: bool = _f(True, "SIM: train the inverse head (false: inverse loss off)")
    ec_memory: int = _f(200, "EC: episodic memory slots per environment (the original code's capacity)")
    ec_width: int = _f(64, "EC: filters of the ResNet-18's first stage (64: the paper's 64-128-256-512)")
    ec_embed: int = _f(512, "EC: size of the frame embedding and of the comparator's fc (the paper's 512)")
    ec_pretrain_steps: int = _f(600_000, "EC: random-policy agent steps its reachability network is trained on "
                                "before the policy starts; part of --total-steps, so metrics.csv starts "
                                "there (the paper's 0.6M shift); 0: no pretraining")
    ec_pretrain_epochs: int = _f(10, "EC: pretraining updates (batch 64), as passes over the pretraining "
                                 "frames at one pair per 4 steps")
    ec_beta: float | None = _f(None, "EC: the bonus is alpha * (beta - similarity) (default: the EC paper's rule, "
                               "1 for tasks whose episodes can end early, e.g. at the goal, 0.5 (the original "
                               "code's) where every episode runs to its step limit)")
    ec_online: bool = _f(False, "EC: ECO, the reachability network also trains during the run, on pairs "
                         "of the policy's own recent frames")
    e3b_ridge: float = _f(0.1, "E3B: lambda, each episode's feature covariance starts at lambda I (E3B's "
                          "--ridge)")
    obs_norm: bool = _f(True, "novelty nets see frames normalised by running per-pixel mean/std")
    bonus_norm: bool = _f(False, "divide the novelty error by a running std of its discounted sum")
    bonus_episodic: bool = _f(True, "the bonus's return ends with the episode, like the task reward's "
                              "(the paper's A2C, one value head); false: it runs on across episode "
                              "ends with its own value head (RND's non-episodic intrinsic return), so "
                              "reaching the goal does not forfeit the bonus still to come")
    task_gamma: float | None = _f(None, "with --bonus-episodic false: the discount of the task's return (default: "
                                  "--gamma); RND's code discounts it at 0.999 and the bonus's at 0.99, --gamma")
    task_advantage_weight: float = _f(1.0, "with --bonus-episodic false: the policy follows A = w * A_task + "
                                      "A_bonus; RND's code weighs them 2 : 1 (ext_coeff 2, int_coeff 1)")
    # how the command compiles the run: every float32 matmul and convolution of the program
    # (simjax.runtime.MATMUL_PRECISIONS). On a CPU highest, high and default give the numbers
    # JAX's default gives, to the bit; bfloat16 rounds the networks' operands (not the
    # renderer's). The dataclass's default is float32 so that a config.json without the field,
    # a test or a script gets the numbers runs had before the setting; the commands choose
    # bfloat16 on a CPU that multiplies bfloat16 in hardware (runtime.command_default_precision),
    # where the precision's learning check (experiments/results/precision-check) found it learns what float32 learns
    precision: str = dataclasses.field(default="highest", metadata={
        "choices": ("highest", "high", "default", "bfloat16"),
        "default_shown": "bfloat16 on a CPU with AMX or AVX-512 BF16, highest elsewhere",
        "help": "matmul precision: highest (float32), high and default (TF32 on NVIDIA GPUs that have it, A100 "
                "on; on a CPU the same numbers as highest), bfloat16 (every product of the policy's and the "
                "novelty model's networks, convolutions included, takes bfloat16 operands and sums in float32: "
                "the CPU's AMX units and a GPU's tensor cores; params, Adam, the LSTM state, the policy and value "
                "heads, losses and the renderer stay float32); recorded in config.json, it wins over "
                "JAX_DEFAULT_MATMUL_PRECISION"})

    def __post_init__(self):
        """Checks the values alone, cheaply (a config is made whenever one is loaded or
        replaced); what needs the task's shapes is checked where its env is built
        (``make_trainer``). Errors name the command-line flag."""
        check_name(self.env)
        if self.algo not in ALGOS:
            raise ValueError(f"unknown algo {self.algo!r}; known algos: {', '.join(ALGOS)}")
        if self.learner not in LEARNERS:
            raise ValueError(f"unknown --learner {self.learner!r}; known learners: {', '.join(LEARNERS)}")
        for name, default in LEARNER_DEFAULTS[self.learner].items():
            if getattr(self, name) is None:
                object.__setattr__(self, name, default)
        if self.reward_clip is None:
            object.__setattr__(self, "reward_clip", self.learner == "a3c" and rewards_within_one(self.env))
        if self.bonus_scale is None:
            object.__setattr__(self, "bonus_scale", DEFAULT_BONUS_SCALE[self.algo])
        if self.ec_beta is None:
            object.__setattr__(self, "ec_beta", 1.0 if episodes_end_early(self.env) else 0.5)
        for name in ("total_steps", "num_envs", "rollout_len", "num_seeds", "log_every"):
            if getattr(self, name) < 1:
                raise ValueError(f"{flag(name)} must be a positive integer, got {getattr(self, name)}")
        for name in ("learning_rate", "max_grad_norm"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{flag(name)} must be > 0, got {getattr(self, name)}")
        for name in ("value_coef", "entropy_coef", "task_scale"):
            value = getattr(self, name)
            if not (value >= 0 and math.isfinite(value)):
                raise ValueError(f"{flag(name)} must be a finite number >= 0, got {value}")
        if not (self.rl_weight > 0 and math.isfinite(self.rl_weight)):
            raise ValueError(f"{flag('rl_weight')} (eta) must be a finite number > 0, got {self.rl_weight}")
        if not 0.0 <= self.gamma <= 1.0:
            raise ValueError(f"{flag('gamma')} must lie in [0, 1], got {self.gamma}")
        if self.seed < 0:
            raise ValueError(f"{flag('seed')} must be >= 0, got {self.seed}")
        for name in ("ec_pretrain_steps", "ec_pretrain_epochs"):
            if getattr(self, name) < 0:
                raise ValueError(f"{flag(name)} must be >= 0, got {getattr(self, name)}")
        if self.total_steps - self.step_offset < self.steps_per_update:
            pretraining = f" after EC's {self.step_offset:,} pretraining steps" if self.step_offset else ""
            raise ValueError(
                f"{flag('total_steps')} ({self.total_steps}) leaves less than one update{pretraining} "
                f"(--num-envs * --rollout-len = {self.steps_per_update})"
            )
        if self.algo == "a2c" and not self.bonus_episodic:
            raise ValueError("--bonus-episodic false gives the bonus its own return; --algo a2c has no bonus")
        if self.task_gamma is not None and not 0.0 <= self.task_gamma <= 1.0:
            raise ValueError(f"{flag('task_gamma')} must lie in [0, 1], got {self.task_gamma}")
        if not (self.task_advantage_weight >= 0 and math.isfinite(self.task_advantage_weight)):
            raise ValueError(f"{flag('task_advantage_weight')} must be a finite number >= 0, "
                             f"got {self.task_advantage_weight}")
        if self.bonus_episodic and (self.task_gamma is not None or self.task_advantage_weight != 1.0):
            raise ValueError(f"{flag('task_gamma')} and {flag('task_advantage_weight')} set the task's stream apart "
                             "from the bonus's: they need --bonus-episodic false (one return otherwise)")
        _ = self.novelty  # building the novelty settings checks their values

    @property
    def novelty(self) -> NoveltySettings:
        """The settings the novelty model and its bonus are built from."""
        return NoveltySettings(
            algo=self.algo, bonus_scale=self.bonus_scale, gamma=self.gamma, obs_norm=self.obs_norm,
            bonus_norm=self.bonus_norm, forward_weight=self.forward_weight, obs_len=self.obs_len,
            act_len=self.act_len, sim_combine=self.sim_combine, sim_sequence=self.sim_sequence,
            sim_target=self.sim_target, sim_inverse=self.sim_inverse, ec_memory=self.ec_memory,
            ec_width=self.ec_width, ec_embed=self.ec_embed, ec_online=self.ec_online, ec_beta=self.ec_beta,
            e3b_ridge=self.e3b_ridge,
        )

    def hyper(self) -> Hyper:
        """The settings in ``SWEEPABLE`` as arrays, the values the compiled learner runs with."""
        f = np.float32
        return Hyper(f(self.learning_rate), f(self.gamma), f(self.value_coef), f(self.entropy_coef),
                     f(self.max_grad_norm), f(self.task_scale), f(self.policy_weight), self.novelty.hyper())

    @property
    def pretrain_plan(self) -> PretrainPlan | None:
        """How EC's reachability network is pretrained (None: no pretraining)."""
        if self.algo != "ec" or self.ec_pretrain_steps == 0 or self.ec_pretrain_epochs == 0:
            return None
        return PretrainPlan.make(self.ec_pretrain_steps, self.ec_pretrain_epochs, self.num_envs)

    @property
    def step_offset(self) -> int:
        """Agent steps per seed spent before the policy's first update: EC's pretraining (the
        paper shifts EC's curves by it). ``total_steps`` counts them; metrics.csv starts after."""
        plan = self.pretrain_plan
        return 0 if plan is None else plan.env_steps

    @property
    def policy_weight(self) -> float:
        """eta where a novelty model shares the objective; plain A2C's loss is the RL loss alone."""
        return 1.0 if self.algo == "a2c" else self.rl_weight

    @property
    def steps_per_update(self) -> int:
        return self.num_envs * self.rollout_len

    @property
    def num_updates(self) -> int:
        return math.ceil((self.total_steps - self.step_offset) / self.steps_per_update)

    @property
    def num_logs(self) -> int:
        """Metric rows in a run (one compiled call of ``updates_per_log`` updates each)."""
        target = max(1, round(self.log_every / self.steps_per_update))
        return math.ceil(self.num_updates / target)

    @property
    def updates_per_log(self) -> int:
        """Updates spread evenly over the rows: the run trains num_logs * updates_per_log
        updates, at least ``total_steps`` agent steps and less than one update per row more."""
        return math.ceil(self.num_updates / self.num_logs)
