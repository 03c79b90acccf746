"""SIM, RND and ICM behind one small interface.

A model is a frozen dataclass with
    history                       frames/actions each environment keeps across rollouts (M)
    init(key, tl, x) -> params    tl: a Timeline, x: its frames normalised (``base``)
    apply(params, tl, x) -> (error (T, N), scored (T, N) bool, loss, metrics)
``error`` is the per-transition novelty before scaling (the bonus is beta * error where
``scored``, 0 elsewhere); ``loss`` is the model's share of eq. (8), lambda * L_F + (1 - lambda)
* L_I, already weighted; ``metrics`` holds ``forward_loss`` and ``inverse_loss``.
Target parameters are kept under ``params["target"]`` and only ever seen through
``stop_gradient``, so the optimiser never moves them.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp

from simjax.novelty.base import Timeline, in_episode, masked_mean, shifted, to_unit
from simjax.novelty.networks import ICMNet, RNDPredictor, RNDTarget, SIMNet


def half_squared_error(prediction, target):
    """eq. (5)/(6) without beta: 1/2 ||target - prediction||^2 over the last axis."""
    return 0.5 * jnp.sum(jnp.square(target - prediction), axis=-1)


@dataclasses.dataclass(frozen=True)
class RND:
    """Random network distillation (A.3): predict a fixed random network's output on o_{t+1}."""

    num_actions: int
    history: int = 1

    def init(self, key, tl: Timeline, x):
        k_t, k_p = jax.random.split(key)
        frames = x[tl.history + 1 :]
        return {"target": RNDTarget().init(k_t, frames), "predictor": RNDPredictor().init(k_p, frames)}

    def apply(self, params, tl: Timeline, x):
        frames = x[tl.history + 1 :]  # the target frames o_1 ... o_T
        target = jax.lax.stop_gradient(RNDTarget().apply(params["target"], frames))
        error = half_squared_error(RNDPredictor().apply(params["predictor"], frames), target)
        scored = in_episode(tl, 1)
        forward = masked_mean(error, scored)
        return error, scored, forward, {"forward_loss": forward, "inverse_loss": jnp.zeros(())}


@dataclasses.dataclass(frozen=True)
class SIM:
    """The sequence-level novelty model (section 2, A.1) and its ablations (section 3.5).

    target "rnd": f*(o_t) is the fixed RND target; "embed" (SIM-no-RND): stop_gradient f_e(o_t).
    sequence "lstm" / "ff" (SIM-no-Seq); combine "full" / "itr" / "concat"; inverse on/off.
    The settings are checked where they are given (``NoveltySettings``), not here.
    """

    num_actions: int
    obs_len: int = 10  # H
    act_len: int = 3  # L
    combine: str = "full"
    sequence: str = "lstm"
    target: str = "rnd"
    inverse: bool = True
    forward_weight: float = 0.2  # lambda

    @property
    def history(self) -> int:
        return self.obs_len + self.act_len - 2

    def net(self) -> SIMNet:
        return SIMNet(
            num_actions=self.num_actions, obs_len=self.obs_len, act_len=self.act_len,
            combine=self.combine, sequence=self.sequence, inverse=self.inverse,
            target_dim=64 if self.target == "rnd" else 256,
        )

    def masks(self, tl: Timeline):
        """(T, H, N) frame mask (oldest first), (T, L, N) action mask, (T, H-1, N) inverse mask."""
        H, L = self.obs_len, self.act_len
        frame = jnp.stack([in_episode(tl, k) for k in range(L + H - 1, L - 1, -1)], axis=1)
        action = jnp.stack([in_episode(tl, k) for k in range(L, 0, -1)], axis=1)
        return frame, action, frame[:, :-1]

    def inverse_targets(self, tl: Timeline) -> jnp.ndarray:
        """(T, H-1, N): the actions taken at the window's frames but the last."""
        H, L, m, t = self.obs_len, self.act_len, tl.history, tl.num_targets
        return jnp.stack([shifted(tl.actions, m, t, k) for k in range(L + H - 1, L, -1)], axis=1)

    def init(self, key, tl: Timeline, x):
        k_t, k_s = jax.random.split(key)
        frame, action, _ = self.masks(tl)
        params = {"sim": self.net().init(k_s, x, tl.actions, frame, action)}
        if self.target == "rnd":
            params["target"] = RNDTarget().init(k_t, x[tl.history + 1 :])
        return params

    def apply(self, params, tl: Timeline, x):
        frame, action, inv_mask = self.masks(tl)
        emb, prediction, logits = self.net().apply(params["sim"], x, tl.actions, frame, action)
        if self.target == "rnd":
            target = RNDTarget().apply(params["target"], x[tl.history + 1 :])
        else:
            target = emb[tl.history + 1 :]
        error = half_squared_error(prediction, jax.lax.stop_gradient(target))
        # scored: the window's newest frame, o_{t-L}, is in o_t's episode (so o_t is no reset frame)
        scored = frame[:, -1]
        forward = masked_mean(error, scored)
        if self.inverse:
            labels = jnp.moveaxis(self.inverse_targets(tl), 1, 2)  # (T, N, H-1)
            log_p = jax.nn.log_softmax(logits)
            ce = -jnp.take_along_axis(log_p, labels[..., None], axis=-1)[..., 0]
            inverse = masked_mean(ce, jnp.moveaxis(inv_mask, 1, 2) & scored[..., None])
            loss = self.forward_weight * forward + (1.0 - self.forward_weight) * inverse
        else:
            inverse = jnp.zeros(())
            loss = self.forward_weight * forward
        return error, scored, loss, {"forward_loss": forward, "inverse_loss": inverse}


@dataclasses.dataclass(frozen=True)
class ICM:
    """The intrinsic curiosity module (A.2) on 4 stacked 42x42 grey frames.

    Frames before the episode's first are zero in the stack. As in ICM's code, the forward loss
    trains the features too (no stop-gradient on phi_{t+1}); the inverse loss keeps them from
    collapsing. ICM reads raw grey frames / 255 (its own preprocessing), not normalised ones;
    stacks are of whatever frame size the environment gives.
    """

    num_actions: int
    forward_weight: float = 0.2  # ICM's forward-inverse ratio
    stack: int = 4

    @property
    def history(self) -> int:
        return self.stack - 1

    def stacks(self, tl: Timeline) -> jnp.ndarray:
        """(T+1, N, 42, 42, stack) grey stacks ending at frames M ... M+T (o_0 ... o_T)."""
        grey = jnp.mean(to_unit(tl.frames), axis=-1)  # (M+T+1, N, h, w)
        m, t = tl.history, tl.num_targets
        ends_seg = tl.segment[m:]
        layers = []
        for k in range(self.stack - 1, -1, -1):  # oldest first
            same = tl.valid[m - k : m - k + t + 1] & (tl.segment[m - k : m - k + t + 1] == ends_seg)
            layers.append(grey[m - k : m - k + t + 1] * same[..., None, None])
        return jnp.stack(layers, axis=-1)

    def init(self, key, tl: Timeline, x):
        return {"icm": ICMNet(self.num_actions).init(key, self.stacks(tl), tl.actions[tl.history :])}

    def apply(self, params, tl: Timeline, x):
        actions = tl.actions[tl.history :]  # a_0 ... a_{T-1}
        phi, prediction, logits = ICMNet(self.num_actions).apply(params["icm"], self.stacks(tl), actions)
        error = half_squared_error(prediction, phi[1:])
        scored = in_episode(tl, 1)
        forward = masked_mean(error, scored)
        ce = -jnp.take_along_axis(jax.nn.log_softmax(logits), actions[..., None], axis=-1)[..., 0]
        inverse = masked_mean(ce, scored)
        loss = self.forward_weight * forward + (1.0 - self.forward_weight) * inverse
        return error, scored, loss, {"forward_loss": forward, "inverse_loss": inverse}
