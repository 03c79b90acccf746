"""A3C's update rule (Mnih et al. 2016) as the ICM code runs it, for ``TrainConfig(learner="a3c")``.

The paper trains every method with LSTM-A3C (appendix A.5) and takes its baselines' settings
from the ICM code (pathak22/noreward-rl). There, each of 16 asynchronous workers runs its own
20-step rollout and applies its own gradient to the shared parameters with its own Adam
(src/a3c.py:363, "each worker has a different set of adam optimizer parameters"). Here each of
the N environments is such an actor. Per update (N x T agent steps), with the rollout, the
returns and the loss terms of ``simjax.agents.a2c``:

    loss_i = T * L_A2C(actor i's T steps) + (T / eta) * L_nov(actor i's T steps)
    g_i    = grad loss_i at the parameters the update started from       (one batched backward)
    for i in a permutation of the actors drawn afresh each update:
        params <- Adam_i(clip_40(g_i["policy"]), clip_40(g_i["novelty"]))  (Adam_i: actor i's own state)

so the update makes N optimiser steps, one per T agent steps as the paper's N actors do, and
the last of them applies a gradient N - 1 steps stale, as an asynchronous worker's can be. With
Adam the step does not read the parameters it is applied to, so the order changes only the
rounding of the sums; it is drawn anyway, as the rule is stated.

What the ICM code does, read at commit 0d47c9e (src/a3c.py, src/constants.py, src/model.py):
- L_A2C = pi_loss + 0.5 * vf_loss - 0.01 * entropy (a3c.py:290-296), where pi_loss and the
  entropy are batch means and vf_loss = 0.5 * mean((V - R)^2) (a3c.py:292): the value term is
  0.25 times the mean squared error, ``value_coef`` 0.25 by default here (the paper's "value
  weight 0.5" is that 0.5 on half the squared error). The gradient is of ``loss * 20``
  (a3c.py:299), the sum over a full 20-step rollout; its rollouts stop at an episode's end, so
  a shorter one is still weighted by 20, where here a rollout spans episode ends and its T
  steps are always summed.
- The predictor's loss is PREDICTION_LR_SCALE (10) * ((1 - 0.2) L_I + 0.2 L_F) (a3c.py:306,
  constants.py:18-20), its gradient also of ``* 20`` (a3c.py:308): with eta = 0.1 and lambda
  = 0.2, the paper's values, (T / eta) * L_nov above. Its L_I and L_F are batch means
  (model.py:273, 282).
- Each gradient is clipped to global norm GRAD_NORM_CLIP = 40 on its own (a3c.py:353, 356), then
  both are applied by one tf.train.AdamOptimizer(1e-4) (a3c.py:367, constants.py:14) with TF's
  defaults (beta 0.9, 0.999, epsilon 1e-8; TF puts epsilon outside the bias correction, a
  difference of sqrt(1 - 0.999^t) on a 1e-8 that is left alone here).
- Reward plus bonus is clipped to [-1, 1] (REWARD_CLIP, a3c.py:40, 48) when the workers run with
  --envWrap, which its Doom command (train.py --default) sets: ``reward_clip``.
- GAE lambda 1 (constants.py:3): the advantage is the n-step return minus V, as here.
- An episode that ends, at the goal or at the time limit (a3c.py:200), gives the rollout no
  bootstrap value (a3c.py:234-235): ``bootstrap_time_limit`` false.
Those settings are ``TrainConfig``'s defaults under ``learner="a3c"`` (``LEARNER_DEFAULTS``).

Per-actor gradients: each actor's loss is ``vmap``ped over the environments, one column each,
with its own gradient (``jax.vmap(jax.grad(...))``), so the backward pass costs what the batch's
does. The novelty model is run through ``Novelty.prepare`` / ``model_loss`` /
``bonus_and_state``: the frame normalisation and the bonus's normaliser see the whole batch, as
under A2C, and only the model's loss is per actor (a stateful model's state split along its
leading environment axis). ``metrics.csv``'s ``grad_norm`` is the mean over actors of the norm
of the gradient of T * L_A2C_i before clipping (what the ICM code logs); its loss terms are the
batch means A2C logs.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import optax

from simjax.agents.a2c import RunnerState, Transition, UpdateRule, a2c_loss
from simjax.agents.config import Hyper, TrainConfig
from simjax.networks import ActorCritic
from simjax.novelty import Novelty
from simjax.novelty.base import Timeline

ADAM_EPS = 1e-8  # tf.train.AdamOptimizer's default, which the ICM code uses


def actor_optimizers(hyper: Hyper, trainable: bool) -> dict[str, optax.GradientTransformation]:
    """One actor's optimiser per parameter group: its gradient clipped to ``max_grad_norm``,
    then Adam. A novelty model that does not train (none, or EC's fixed network) has none."""
    group = optax.chain(optax.clip_by_global_norm(hyper.max_grad_norm),
                        optax.adam(hyper.learning_rate, eps=ADAM_EPS))
    return {"policy": group, **({"novelty": group} if trainable else {})}


def draw_order(key, num_actors: int) -> jnp.ndarray:
    """The order the actors' steps are applied in: a uniformly random permutation."""
    return jax.random.permutation(key, num_actors)


def apply_in_order(txs: dict, params: dict, opt_states: dict, grads: dict, order: jnp.ndarray):
    """``(params, opt_states)`` after each actor's step in turn, actor ``order[0]``'s first:
    group ``g`` of ``params`` is stepped by ``txs[g]`` with actor i's gradient ``grads[g][i]``
    and state ``opt_states[g][i]`` (leading axis: actor), which alone is replaced; groups
    without an optimiser are left as they are."""

    def one(k, carry):
        params, states = dict(carry[0]), dict(carry[1])
        i = order[k]
        pick = lambda tree: jax.tree.map(lambda x: x[i], tree)
        for name, tx in txs.items():
            updates, state = tx.update(pick(grads[name]), pick(states[name]), params[name])
            params[name] = optax.apply_updates(params[name], updates)
            states[name] = jax.tree.map(lambda all_, x: all_.at[i].set(x), states[name], state)
        return params, states

    return jax.lax.fori_loop(0, order.shape[0], one, (params, opt_states))


def _column(tree, axis: int):
    """One environment's slice of a batch, kept as a batch of one (the shape the losses take)."""
    return jax.tree.map(lambda x: jnp.expand_dims(x, axis), tree)


def a3c_rule(config: TrainConfig, network: ActorCritic, novelty: Novelty) -> UpdateRule:
    N, T = config.num_envs, config.rollout_len
    trainable = novelty.trainable

    def init(params, hyper: Hyper):
        """Every actor's own optimiser state, as a fresh worker's: the state of one, N times."""
        return {name: jax.tree.map(lambda x: jnp.broadcast_to(x, (N,) + x.shape), tx.init(params[name]))
                for name, tx in actor_optimizers(hyper, trainable).items()}

    def novelty_part(params, runner: RunnerState, traj: Transition, last_obs, last_reset):
        """(each actor's gradient of (T / eta) L_nov (leading axis: actor; None if the model does
        not train), the bonus (T, N), the metrics, the novelty state after the rollout)."""
        hyper = runner.hyper
        if novelty.model is None:  # no bonus, no loss
            _, (bonus, metrics, state) = novelty.loss_and_bonus(params, runner.novelty, traj.obs, traj.reset,
                                                                traj.action, last_obs, last_reset, hyper.novelty)
            return None, bonus, metrics, state
        prepared = novelty.prepare(runner.novelty, traj.obs, traj.reset, traj.action, last_obs, last_reset)
        tl = prepared.timeline

        def actor(frames, actions, segment, valid, model_state):
            one = prepared._replace(timeline=Timeline(*_column((frames, actions, segment, valid), 1), tl.history))

            def loss(p):
                value, (error, scored, metrics, state) = novelty.model_loss(p, _column(model_state, 0), one,
                                                                            hyper.novelty)
                return T / hyper.policy_weight * value, (error[:, 0], scored[:, 0], metrics,
                                                         jax.tree.map(lambda x: x[0], state))

            if trainable:
                return jax.grad(loss, has_aux=True)(params)
            return None, loss(params)[1]

        grads, (error, scored, metrics, model_state) = jax.vmap(actor, in_axes=(1, 1, 1, 1, 0), out_axes=(0, (1, 1, 0, 0)))(
            tl.frames, tl.actions, tl.segment, tl.valid, runner.novelty.model)
        metrics = jax.tree.map(jnp.mean, metrics)
        bonus, metrics, state = novelty.bonus_and_state(runner.novelty, prepared, error, scored, metrics, model_state,
                                                        hyper.novelty)
        return grads, bonus, metrics, state

    def policy_part(params, runner: RunnerState, traj: Transition, last_obs, last_reset, bonus):
        """(each actor's gradient of T * L_A2C (leading axis: actor), each actor's loss terms)."""

        def actor(traj_i, carry_i, last_obs_i, last_reset_i, bonus_i):
            def loss(p):
                value, info = a2c_loss(p, network, _column(carry_i, 0), _column(traj_i, 1), last_obs_i[None],
                                       last_reset_i[None], bonus_i[:, None], config, runner.hyper)
                return T * value, info

            return jax.grad(loss, has_aux=True)(params)

        return jax.vmap(actor, in_axes=(1, 0, 0, 0, 1))(traj._replace(metrics={}), runner.carry, last_obs, last_reset,
                                                        bonus)

    def step(runner: RunnerState, traj: Transition, last_obs, last_reset, key):
        key, order_key = jax.random.split(key)
        novelty_grads, bonus, novelty_info, novelty_state = novelty_part(runner.params["novelty"], runner, traj,
                                                                         last_obs, last_reset)
        policy_grads, info = policy_part(runner.params["policy"], runner, traj, last_obs, last_reset, bonus)
        grads = {"policy": policy_grads, **({"novelty": novelty_grads} if trainable else {})}
        params, opt_state = apply_in_order(actor_optimizers(runner.hyper, trainable), runner.params, runner.opt_state,
                                           grads, draw_order(order_key, N))
        info = {**jax.tree.map(jnp.mean, info), **novelty_info,
                "grad_norm": jnp.mean(jax.vmap(optax.tree.norm)(policy_grads))}
        return params, opt_state, key, info, novelty_state

    return UpdateRule(init, step)
