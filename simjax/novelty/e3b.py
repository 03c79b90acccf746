"""E3B (Henaff et al. 2022, "Exploration via Elliptical Episodic Bonuses"), a method beyond the
SIM paper, behind the same ``Novelty`` interface as SIM, RND, ICM and EC.

Each environment keeps the inverse of its episode's feature covariance,

    C_t = lambda I + sum_{frames o of the episode up to t} phi(o) phi(o)^T,

and a frame's bonus is its feature's elliptical norm under the episode so far, b = phi^T C^-1 phi:
large for a direction the episode has not yet shown, small for one it has, however loud or
unpredictable the frame is. C^-1 is kept, not C, and updated by Sherman-Morrison:

    u = C^-1 phi,   b = phi^T u,   C^-1 <- C^-1 - u u^T / (1 + b).

phi is ICM's encoder (4 conv 32, 3x3, stride 2, ELU, 288 features on 4 stacked grey 42x42
frames), trained only through an inverse-dynamics head (fc 256, ReLU, |A|) on (phi_t, phi_{t+1});
there is no forward model. What is taken from E3B's code (facebookresearch/e3b,
minihack/torchbeast: ``src/utils.py`` ``act`` for the bonus, ``src/models.py`` for the networks,
``sweep_slurm_neurips_2022.py`` for its ViZDoom runs), and where this differs:

* lambda = 0.1 (``--ridge``), C^-1 = I / lambda at every episode's start; an episode's first
  frame pays 0 but enters C. E3B's code does the same.
* phi comes from the encoder the rollout was collected with (the learner's params before
  the update), free of gradients. E3B's actors use a copy that the learner refreshes after each
  step. Either way, one episode's C mixes features from several encoder versions.
* The bonus of rollout transition t is that of the frame it reaches, o_{t+1}, against the
  episode's frames o_0 ... o_t: this project's convention for every model (``base``). E3B's code
  pays b(o_t) against o_0 ... o_{t-1} at the same transition, one step earlier.
* The covariance and its updates stay float32 under ``--precision bfloat16``: they are not
  network products, and every product here is taken at ``Precision.HIGHEST``.
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar, NamedTuple

import jax
import jax.numpy as jnp

from simjax.novelty.base import Timeline, in_episode, masked_mean
from simjax.novelty.models import grey, grey_stacks
from simjax.novelty.networks import ICMEncoder, InverseHead

RIDGE = 0.1  # lambda: E3B's ``--ridge`` default, and its ViZDoom sweep's value
FEATURES = 288  # ICM's encoder on 42x42 frames: 32 channels of 3x3
HIGHEST = jax.lax.Precision.HIGHEST


class E3BState(NamedTuple):
    """Each environment's inverse covariance (leading axis: environment)."""

    cov_inverse: jnp.ndarray  # (N, D, D) float32


def elliptical_step(cov_inverse: jnp.ndarray, phi: jnp.ndarray, start: jnp.ndarray, ridge: float = RIDGE):
    """One frame of one environment: (C^-1 (D, D), phi (D,), start: the frame begins an episode)
    -> (C^-1 with phi folded in, bonus b = phi^T C^-1 phi before it (0 at a start))."""
    d = cov_inverse.shape[-1]
    cov_inverse = jnp.where(start, jnp.eye(d, dtype=jnp.float32) / ridge, cov_inverse)
    phi = phi.astype(jnp.float32)
    u = jnp.dot(cov_inverse, phi, precision=HIGHEST)
    b = jnp.dot(phi, u, precision=HIGHEST)
    cov_inverse = cov_inverse - jnp.outer(u, u) / (1.0 + b)
    return cov_inverse, jnp.where(start, 0.0, b)


def scan_elliptical(state: E3BState, phi: jnp.ndarray, starts: jnp.ndarray, ridge: float = RIDGE):
    """A rollout's features (T, N, D) against the environments' covariances, frame after frame
    (``lax.scan`` over T, ``vmap`` over N). ``starts`` (T, N): the frame begins an episode.
    Returns (state, bonus (T, N))."""
    step_env = jax.vmap(lambda c, p, s: elliptical_step(c, p, s, ridge))

    def step(cov_inverse, xs):
        return step_env(cov_inverse, *xs)

    cov_inverse, bonus = jax.lax.scan(step, state.cov_inverse, (phi, starts))
    return E3BState(cov_inverse), bonus


@dataclasses.dataclass(frozen=True)
class E3B:
    """E3B as a ``Novelty`` model with a per-environment state (``stateful``): ``init_state``
    folds each environment's first frame into C^-1 = I / lambda; ``apply_with_state`` scores a
    rollout's frames one after another and returns the inverse-dynamics loss, the encoder's only
    training signal (its whole share of eq. (8): no forward loss, so lambda is not read)."""

    num_actions: int
    ridge: float = RIDGE
    stack: int = 4

    stateful: ClassVar[bool] = True
    per_transition_loss: ClassVar[bool] = True  # ``apply_with_state`` takes ``targets`` (A3C's pieces)

    @property
    def history(self) -> int:
        return self.stack - 1

    def features(self, params, stacks):
        return ICMEncoder().apply(params["encoder"], stacks)

    def init(self, key, tl: Timeline, x=None):
        k_e, k_i = jax.random.split(key)
        feats, encoder = ICMEncoder().init_with_output(k_e, grey_stacks(tl, self.stack))
        return {"encoder": encoder, "inverse": InverseHead(self.num_actions).init(k_i, feats[:-1], feats[1:])}

    def first_stacks(self, obs):
        """The stacks of first frames ``obs`` (N, h, w, c): zeros, then the frame's grey (what
        ``grey_stacks`` gives an episode's first frame)."""
        g = grey(obs)
        return jnp.stack([jnp.zeros_like(g)] * self.history + [g], axis=-1)  # (N, h, w, stack)

    def init_state(self, params, obs, key=None) -> E3BState:
        """Every environment's C^-1 with its first frame ``obs`` (N, h, w, c) folded in."""
        phi = jax.lax.stop_gradient(self.features(params, self.first_stacks(obs)))
        n, d = phi.shape
        cov = jnp.broadcast_to(jnp.eye(d, dtype=jnp.float32) / self.ridge, (n, d, d))
        state, _ = scan_elliptical(E3BState(cov), phi[None], jnp.ones((1, n), bool), self.ridge)
        return state

    def apply(self, params, tl: Timeline, x=None, hyper=None, targets=None):
        raise TypeError("E3B keeps an inverse covariance per environment: call apply_with_state")

    def apply_with_state(self, params, state: E3BState, tl: Timeline, x=None, hyper=None, targets=None):
        """(error (T, N), scored (T, N), loss, metrics, state): error is b of each target frame
        o_{t+1}, free of gradients; scored is false where o_{t+1} starts an episode. ``loss`` is
        the inverse model's cross-entropy over the scored transitions (those ``targets`` marks,
        if given). ``x`` and ``hyper`` are not read: E3B reads grey frames / 255 as ICM does, and
        its beta is ``Novelty``'s."""
        m = tl.history
        stacks = grey_stacks(tl, self.stack)  # (T+1, N, h, w, stack): o_0 ... o_T
        phi = self.features(params, stacks)
        logits = InverseHead(self.num_actions).apply(params["inverse"], phi[:-1], phi[1:])
        actions = tl.actions[m:]  # a_0 ... a_{T-1}
        ce = -jnp.take_along_axis(jax.nn.log_softmax(logits), actions[..., None], axis=-1)[..., 0]
        scored = in_episode(tl, 1)
        inverse = masked_mean(ce, scored)
        loss = inverse if targets is None else masked_mean(ce, scored & targets)
        starts = tl.segment[m + 1 :] != tl.segment[m:-1]  # (T, N): o_{t+1} begins an episode
        state, bonus = scan_elliptical(state, jax.lax.stop_gradient(phi[1:]), starts, self.ridge)
        metrics = {"forward_loss": jnp.zeros(()), "inverse_loss": inverse}
        return bonus, scored, loss, metrics, state
