"""E3B's episodic bonus times SIM's lifelong novelty (``--algo e3b-sim``), combined as NGU
combines its two (Badia et al. 2020, "Never Give Up", section 2): a method beyond the paper
that keeps the paper's model in it.

    alpha_t = 1 + (e_t - mu_e) / sigma_e          e_t: SIM's error at transition t (its bonus before beta)
    r+_t    = b_t * min(max(alpha_t, 1), L)       b_t: E3B's elliptical bonus, L = 5

An episode's novelty (E3B) decides whether a frame pays at all, so a loud room stops paying once
the episode has seen it; the lifelong error (SIM) only multiplies that pay by up to 5 where the
model still predicts badly. mu_e and sigma_e are running statistics of SIM's error over every
scored transition so far (NGU normalises its RND error the same way). E3B's own code takes the
same kind of product with NovelD (``e3b_noveld``).

The two models are this package's own, unchanged (``E3B``, ``SIM``), on one timeline (the longer
of their histories): SIM reads the normalised frames as it does alone and E3B the grey ones; the
loss is the sum of their losses (SIM's eq. (8) share and E3B's inverse loss, each the weight it
has alone). ``forward_loss`` is SIM's, ``inverse_loss`` the sum of the two inverse losses.

The error statistics are kept per environment (leading axis N, as every model state): under
A2C each copy is folded with the whole rollout's errors, so all are equal; under A3C each actor
folds in its own environment's, so each normalises by its own.
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar, NamedTuple

import jax
import jax.numpy as jnp

from simjax.novelty.base import RunningMeanStd, Timeline
from simjax.novelty.e3b import E3B, E3BState
from simjax.novelty.models import SIM

CLIP = 5.0  # NGU's L: the largest multiplier the lifelong error gives


class E3BSIMState(NamedTuple):
    """E3B's inverse covariances and the running statistics of SIM's error, per environment."""

    cov_inverse: jnp.ndarray  # (N, D, D) float32
    error_mean: jnp.ndarray  # (N,) float32
    error_var: jnp.ndarray  # (N,) float32
    error_count: jnp.ndarray  # (N,) float32, transitions folded in


def multiplier(error: jnp.ndarray, mean, var) -> jnp.ndarray:
    """NGU's alpha clipped to [1, L]: 1 + (e - mu) / sigma."""
    return jnp.clip(1.0 + (error - mean) / jnp.sqrt(var + 1e-8), 1.0, CLIP)


@dataclasses.dataclass(frozen=True)
class E3BSIM:
    """``E3B`` x ``SIM`` as one stateful ``Novelty`` model."""

    e3b: E3B
    sim: SIM

    stateful: ClassVar[bool] = True
    per_transition_loss: ClassVar[bool] = True

    @property
    def history(self) -> int:
        return max(self.e3b.history, self.sim.history)

    def init(self, key, tl: Timeline, x):
        k_e, k_s = jax.random.split(key)
        return {"e3b": self.e3b.init(k_e, tl, x), "sim": self.sim.init(k_s, tl, x)}

    def init_state(self, params, obs, key=None) -> E3BSIMState:
        cov = self.e3b.init_state(params["e3b"], obs).cov_inverse
        n = obs.shape[0]
        # no error seen yet: the first rollout's errors set the statistics before they are used
        return E3BSIMState(cov, jnp.zeros((n,), jnp.float32), jnp.ones((n,), jnp.float32), jnp.zeros((n,), jnp.float32))

    def apply(self, params, tl: Timeline, x=None, hyper=None, targets=None):
        raise TypeError("E3B x SIM keeps an inverse covariance per environment: call apply_with_state")

    def apply_with_state(self, params, state: E3BSIMState, tl: Timeline, x=None, hyper=None, targets=None):
        """(bonus before beta (T, N), scored (T, N): E3B's, loss, metrics, state)."""
        extra = {} if targets is None else {"targets": targets}
        b, e3b_scored, e3b_loss, e3b_metrics, e3b_state = self.e3b.apply_with_state(
            params["e3b"], E3BState(state.cov_inverse), tl, x, hyper, **extra)
        error, sim_scored, sim_loss, sim_metrics = self.sim.apply(params["sim"], tl, x, hyper, **extra)
        error = jax.lax.stop_gradient(error).astype(jnp.float32)
        fold = jax.vmap(lambda m, v, c: RunningMeanStd(m, v, c).update(error, sim_scored))
        mean, var, count = fold(state.error_mean, state.error_var, state.error_count)
        # every copy holds the same numbers: read the first (the copies of one actor under A3C)
        # SIM scores no transition whose window reaches before the episode (its first L): those
        # pay E3B's bonus alone, as they would at an average error
        alpha = jnp.where(sim_scored, multiplier(error, mean[0], var[0]), 1.0)
        bonus = jax.lax.stop_gradient(b) * alpha
        metrics = {"forward_loss": sim_metrics["forward_loss"],
                   "inverse_loss": sim_metrics["inverse_loss"] + e3b_metrics["inverse_loss"]}
        return bonus, e3b_scored, sim_loss + e3b_loss, metrics, E3BSIMState(e3b_state.cov_inverse, mean, var, count)
