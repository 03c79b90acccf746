"""``NoveltySettings``: everything a novelty model and its bonus are built from, typed and
checked in one place. ``TrainConfig.novelty`` builds it from a run's config; its field names are
the config's, so an error names the command-line flag (``obs_len`` is ``--obs-len``)."""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np

MODELS = ("sim", "rnd", "icm", "ec", "e3b", "e3b-sim")  # and "a2c": no model, no bonus
SIM_COMBINE = ("full", "itr", "concat")
SIM_SEQUENCE = ("lstm", "ff")
SIM_TARGET = ("rnd", "embed")
MAX_WINDOW = 64  # H and L above this are almost surely typos (memory is H + L - 2 frames per env)
# RND's target (8x8 s4, 4x4 s2, 3x3 s1, all VALID) leaves at least one pixel from 36x36 frames
RND_TARGET_MIN_SIZE = 36


class NoveltyHyper(NamedTuple):
    """The novelty settings that change no array shape, as arrays: one compiled program takes
    any values of them (a sweep vmaps over them). SIM's H and L are among them: its windows are
    laid out for the largest H and L and masked (``SIM.windows``)."""

    bonus_scale: np.ndarray  # beta
    gamma: np.ndarray  # discount of the bonus normaliser's running return
    forward_weight: np.ndarray  # lambda
    obs_len: np.ndarray  # int32, H
    act_len: np.ndarray  # int32, L


def flag(name: str) -> str:
    """The command-line flag of a config field: ``act_len`` -> ``--act-len``."""
    return "--" + name.replace("_", "-")


@dataclasses.dataclass(frozen=True)
class NoveltySettings:
    """The novelty model ``algo`` names (none for ``a2c``) and how its error becomes a bonus."""

    algo: str = "a2c"
    bonus_scale: float = 0.0  # beta: bonus = beta * error
    gamma: float = 0.99  # discount of the bonus normaliser's running return
    obs_norm: bool = True
    bonus_norm: bool = False
    forward_weight: float = 0.2  # lambda (sim, icm)
    obs_len: int = 10  # SIM's H
    act_len: int = 3  # SIM's L
    sim_combine: str = "full"
    sim_sequence: str = "lstm"
    sim_target: str = "rnd"
    sim_inverse: bool = True
    ec_memory: int = 200  # EC: episodic memory slots per environment
    ec_width: int = 64  # EC: filters of the ResNet-18's first stage
    ec_embed: int = 512  # EC: embedding size, and the comparator's fc
    ec_online: bool = False  # ECO: the reachability network also trains during the run
    ec_beta: float = 0.5  # EC: the bonus's offset, alpha * (beta - similarity)
    e3b_ridge: float = 0.1  # E3B: lambda, each episode's C starts at lambda I

    def __post_init__(self):
        if self.algo != "a2c" and self.algo not in MODELS:
            raise ValueError(f"unknown novelty model {self.algo!r}; known: {', '.join(MODELS)}")
        for name, allowed in (("sim_combine", SIM_COMBINE), ("sim_sequence", SIM_SEQUENCE),
                              ("sim_target", SIM_TARGET)):
            if getattr(self, name) not in allowed:
                raise ValueError(f"{flag(name)} must be one of {', '.join(allowed)}; got {getattr(self, name)!r}")
        if not 2 <= self.obs_len <= MAX_WINDOW:
            raise ValueError(f"{flag('obs_len')} (H) must lie in [2, {MAX_WINDOW}], got {self.obs_len}")
        if not 1 <= self.act_len <= MAX_WINDOW:
            raise ValueError(f"{flag('act_len')} (L) must lie in [1, {MAX_WINDOW}], got {self.act_len}")
        if not 0.0 <= self.forward_weight <= 1.0:
            raise ValueError(f"{flag('forward_weight')} (lambda) must lie in [0, 1], got {self.forward_weight}")
        for name in ("ec_memory", "ec_width", "ec_embed"):
            if getattr(self, name) < 1:
                raise ValueError(f"{flag(name)} must be a positive integer, got {getattr(self, name)}")
        if not 0.0 <= self.ec_beta <= 1.0:
            raise ValueError(f"{flag('ec_beta')} must lie in [0, 1] (a similarity's range), got {self.ec_beta}")
        if not (self.e3b_ridge > 0 and math.isfinite(self.e3b_ridge)):
            raise ValueError(f"{flag('e3b_ridge')} (lambda) must be a finite number > 0, got {self.e3b_ridge}")
        if not (self.bonus_scale >= 0 and math.isfinite(self.bonus_scale)):
            raise ValueError(f"{flag('bonus_scale')} must be a finite number >= 0, got {self.bonus_scale}")

    def hyper(self) -> NoveltyHyper:
        """These settings' traced values (numpy, so building them computes nothing on a device)."""
        return NoveltyHyper(np.float32(self.bonus_scale), np.float32(self.gamma), np.float32(self.forward_weight),
                            np.int32(self.obs_len), np.int32(self.act_len))

    @property
    def reads_images(self) -> bool:
        return self.algo != "a2c"

    @property
    def uses_rnd_target(self) -> bool:
        return self.algo == "rnd" or (self.algo in ("sim", "e3b-sim") and self.sim_target == "rnd")


def check_observation(settings: NoveltySettings, obs_shape, task: str = "this task") -> None:
    """A clear error if the model ``settings`` name cannot read observations of ``obs_shape``
    (known only once the task's env is built)."""
    if not settings.reads_images:
        return
    shape = tuple(obs_shape)
    if len(shape) != 3:
        raise ValueError(
            f"--algo {settings.algo} reads image observations (height, width, channels); "
            f"{task} gives shape {shape}. Use --algo a2c for vector observations."
        )
    if settings.uses_rnd_target and min(shape[:2]) < RND_TARGET_MIN_SIZE:
        raise ValueError(
            f"--algo {settings.algo}'s RND target needs frames of at least {RND_TARGET_MIN_SIZE}x"
            f"{RND_TARGET_MIN_SIZE}; {task} gives {shape[0]}x{shape[1]}. "
            f"Use --algo {'e3b-sim' if settings.algo == 'e3b-sim' else 'sim'} with --sim-target embed, or --algo icm."
        )


# EC's pretraining (``simjax.novelty.ec_pretrain``): random-policy frames come in chunks of at
# most PRETRAIN_CHUNK steps per environment, each trained on, then dropped (never all stored);
# one compiled call does at most PRETRAIN_CALL updates, so a call stays short on a CPU
PRETRAIN_CHUNK = 500
PRETRAIN_CALL = 32
PAIRS_PER_STEP = 0.25  # one training pair per 4 steps: the rate of EC's v2 sampler
PRETRAIN_BATCH = 64  # EC's constants.py BATCH_SIZE


@dataclasses.dataclass(frozen=True)
class PretrainPlan:
    """How EC's pretraining spends ``steps`` agent steps per seed of ``num_envs`` environments
    and ``epochs`` passes: ``num_chunks`` chunks of ``chunk_len`` steps per environment, each
    trained on by ``calls`` compiled calls of ``updates_per_call`` Adam updates."""

    chunk_len: int
    num_chunks: int
    calls: int
    updates_per_call: int
    num_envs: int

    @staticmethod
    def make(steps: int, epochs: int, num_envs: int) -> PretrainPlan:
        chunk_len = max(1, min(PRETRAIN_CHUNK, math.ceil(steps / num_envs)))
        num_chunks = math.ceil(steps / (num_envs * chunk_len))
        updates = max(1, math.ceil(epochs * PAIRS_PER_STEP * num_envs * chunk_len / PRETRAIN_BATCH))
        calls = math.ceil(updates / PRETRAIN_CALL)
        return PretrainPlan(chunk_len, num_chunks, calls, math.ceil(updates / calls), num_envs)

    @property
    def env_steps(self) -> int:
        """Agent steps per seed the pretraining takes (at least the steps asked for)."""
        return self.num_chunks * self.chunk_len * self.num_envs

    @property
    def updates(self) -> int:
        return self.num_chunks * self.calls * self.updates_per_call
