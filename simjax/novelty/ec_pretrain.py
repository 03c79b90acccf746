"""EC's pretraining: the reachability network learns, before the run, which frames of a random
policy's episodes are near each other (at most k = 5 steps apart) and which far (more than 25),
as the SIM paper's EC baseline did (section 3.1: 0.6M pretraining steps, curves shifted by them).

Everything is compiled JAX: random-policy rollouts of the run's ``num_envs`` environments
(``simjax.envs.episodes.rollout``), pair sampling within episodes (``ec.sample_pair``), Adam
(EC's constants.py: lr 1e-4, epsilon 1e-8) on batches of 64 pairs. The frames come in chunks
(``PretrainPlan``): a chunk of ``chunk_len`` steps per environment is collected, trained on by
``calls`` x ``updates_per_call`` updates of pairs drawn afresh from it, then replaced; the 0.6M
frames are never held at once (3.2 GB of 42x42 RGB). ``run`` is the whole pretraining as one
function (``jax.lax.scan`` over chunks); ``simjax.runs.training`` calls ``collect`` and
``train`` one by one instead, to show progress and to watch each call for XLA stalls.

The pretraining's agent steps count in the run's step axis: ``TrainConfig.step_offset``.
"""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import optax

from simjax.envs.episodes import rollout, starts_episode, uniform_policy
from simjax.novelty.ec import ADAM_EPS, BATCH_SIZE, EC, LEARNING_RATE, episode_bounds, pair_loss, sample_pair
from simjax.novelty.settings import PretrainPlan


class PretrainState(NamedTuple):
    params: Any  # the novelty model's params, {"r": ...}
    opt_state: Any
    env_state: Any  # the pretraining's own batch of environments (random policy)
    frames: jnp.ndarray  # (chunk_len, N, h, w, c): the chunk being trained on
    starts: jnp.ndarray  # (chunk_len, N) bool: the frame begins an episode
    key: jnp.ndarray


@dataclasses.dataclass(frozen=True)
class Pretrainer:
    env: Any
    model: EC
    plan: PretrainPlan
    batch: int = BATCH_SIZE
    learning_rate: float = LEARNING_RATE

    @property
    def optimizer(self):
        return optax.adam(self.learning_rate, b1=0.9, b2=0.999, eps=ADAM_EPS)

    def init(self, key, params) -> PretrainState:
        """Fresh environments and Adam for ``params``; the first chunk is collected by ``collect``."""
        k_env, key = jax.random.split(key)
        n, c = self.plan.num_envs, self.plan.chunk_len
        env_state = jax.vmap(self.env.reset)(jax.random.split(k_env, n))
        frames = jnp.zeros((c,) + env_state.obs.shape, env_state.obs.dtype)
        return PretrainState(params, self.optimizer.init(params), env_state, frames, jnp.zeros((c, n), bool), key)

    def collect(self, state: PretrainState) -> PretrainState:
        """The next chunk: ``chunk_len`` random-policy steps of every environment."""
        key, sub = jax.random.split(state.key)
        n = self.plan.num_envs
        act = uniform_policy(self.env.action_size, n)
        record = lambda s, a, s2: (s.obs, starts_episode(s))
        xs = jax.random.split(sub, self.plan.chunk_len)
        env_state, _, (frames, starts) = rollout(self.env, act, state.env_state, (), xs, record)
        return state._replace(env_state=env_state, frames=frames, starts=starts, key=key)

    @staticmethod
    def bounds(starts):
        """(C, N) first and last index of each frame's episode within the chunk."""
        segment = jnp.cumsum(starts, axis=0)
        valid = jnp.ones(starts.shape[:1], bool)
        return jax.vmap(lambda s: episode_bounds(s, valid), out_axes=1)(segment.T)

    def sample(self, key, frames, start, end):
        """A batch of pairs from a chunk with episode bounds ``start``/``end`` (C, N): (x1, x2)
        (B, h, w, c), labels (B,), mask (B,) of the pairs that exist."""
        c, n = start.shape
        valid = jnp.ones((c,), bool)
        k_env, k_pair = jax.random.split(key)
        env = jax.random.randint(k_env, (self.batch,), 0, n)
        i, j, label, ok = jax.vmap(lambda k, e: sample_pair(k, start[:, e], end[:, e], valid))(
            jax.random.split(k_pair, self.batch), env)
        return frames[i, env], frames[j, env], label, ok

    def loss(self, params, x1, x2, label, ok):
        net = self.model.net()
        logits = net.apply(params["r"], x1.astype(jnp.float32) / 255.0, x2.astype(jnp.float32) / 255.0)
        return pair_loss(logits, label, ok)

    def train(self, state: PretrainState):
        """``updates_per_call`` Adam updates on pairs drawn from the current chunk; returns the
        state and the mean loss and accuracy (on each batch before its update)."""
        tx = self.optimizer
        start, end = self.bounds(state.starts)

        def update(carry, key):
            params, opt_state = carry
            batch = self.sample(key, state.frames, start, end)
            (loss, accuracy), grads = jax.value_and_grad(self.loss, has_aux=True)(params, *batch)
            updates, opt_state = tx.update(grads, opt_state, params)
            return (optax.apply_updates(params, updates), opt_state), (loss, accuracy, jnp.mean(batch[3]))

        key, sub = jax.random.split(state.key)
        keys = jax.random.split(sub, self.plan.updates_per_call)
        (params, opt_state), (loss, accuracy, usable) = jax.lax.scan(update, (state.params, state.opt_state), keys)
        metrics = {"loss": jnp.mean(loss), "accuracy": jnp.mean(accuracy), "usable_pairs": jnp.mean(usable)}
        return state._replace(params=params, opt_state=opt_state, key=key), metrics

    def run(self, key, params):
        """The whole pretraining in one function: (trained params, per-chunk mean metrics)."""
        def chunk(state, _):
            state = self.collect(state)
            state, metrics = jax.lax.scan(lambda s, _: self.train(s), state, None, self.plan.calls)
            return state, jax.tree.map(jnp.mean, metrics)

        state, metrics = jax.lax.scan(chunk, self.init(key, params), None, self.plan.num_chunks)
        return state.params, metrics


    # -- as the learner uses it: a fresh runner (``simjax.agents.a2c.RunnerState``) in, the same
    # runner with the pretrained params and every environment's memory started again with them out

    def start(self, runner):
        """The pretraining's state for ``runner``'s novelty params, on a key split off its own."""
        key, sub = jax.random.split(runner.key)
        return self.init(sub, runner.params["novelty"]), runner._replace(key=key)

    def finish(self, runner, params):
        """``runner`` with the novelty ``params`` and its episodic memories restarted with them."""
        memory = self.model.restart(params, runner.novelty.model, runner.env_state.obs)
        return runner._replace(params={**runner.params, "novelty": params}, novelty=runner.novelty._replace(model=memory))

    def pretrain_runner(self, runner):
        """``start``, the whole pretraining (``run``), ``finish``: one function."""
        key, sub = jax.random.split(runner.key)
        params, _ = self.run(sub, runner.params["novelty"])
        return self.finish(runner._replace(key=key), params)


def make_pretrainer(config, env, novelty) -> Pretrainer | None:
    """The pretraining of ``config`` (a ``TrainConfig``), None where there is none."""
    plan = config.pretrain_plan
    if plan is None:
        return None
    if not isinstance(novelty.model, EC):
        raise ValueError(f"pretraining is EC's; --algo {config.algo} has none")
    return Pretrainer(env, novelty.model, plan)
