"""A3C's update rule (Mnih et al. 2016) as the ICM code runs it, for ``TrainConfig(learner="a3c")``.

The paper trains every method with LSTM-A3C (appendix A.5) and takes its baselines' settings
from the ICM code (pathak22/noreward-rl, read at commit 0d47c9e). There, each of 16
asynchronous workers runs rollouts of at most 20 steps and applies each one's gradient to the
shared parameters with one Adam that all of them share. Here each of the N environments is such
an actor. Per update (N x T agent steps), with the rollout, the returns and the loss terms of
``simjax.agents.a2c``:

    each actor's T steps are cut at its episode ends into pieces (a piece ends where an episode
    ends, or at the rollout's end); piece j of actor i, L_ij steps long, has the loss
        loss_ij = 20 * mean_{piece} L_A2C + (20 / eta) * mean_{piece's scored transitions} L_nov
    g_ij = grad loss_ij at the parameters the update started from
    for round k = 0, 1, ... (the actors' k-th pieces), in a permutation of the actors drawn
    afresh each round, for each actor i that has a k-th piece:
        params, adam <- Adam(clip_40(g_ik["policy"]), clip_40(g_ik["novelty"]); adam)

with one Adam state per parameter group, shared by all actors: one count, one m and one v
(``opt_state["policy"]``, ``opt_state["novelty"]``), as the ICM code's. The update makes one
optimiser step per piece, N when no episode ends, as the paper's N actors would; the gradients
are all taken at the update's starting parameters, so a later one is stale by the steps before
it, as an asynchronous worker's can be. With one shared Adam the order matters (each step reads
the moments the steps before it left), so it is drawn, round by round: the actors' pieces
interleave as asynchronous workers' would, each actor's in its own time order.

Why one shared Adam: the ICM code's comment says otherwise (src/a3c.py:363, "each worker has a
different set of adam optimizer parameters"), but its graph does not. A3C.__init__ builds the
global network under ``tf.device(tf.train.replica_device_setter(1, ...))`` and applies
``tf.train.AdamOptimizer(...).apply_gradients`` to the global variables; Adam's slots (m, v) are
colocated with those variables and its beta powers with the first of them, all on the parameter
server, under the same names in every worker's graph. src/worker.py:41-43 makes every global
variable not named ``local...`` ``variables_to_save`` and ``init_op``; src/worker.py:78-85 has
the chief alone run ``init_op`` (``tf.train.Supervisor(is_chief=(args.task == 0), init_op=...,
ready_op=tf.report_uninitialized_variables(variables_to_save))``), every other worker waiting
until those are initialised: per-worker slots would never be. (Runs before this rule gave each
actor an Adam of its own; their checkpoints hold N states and do not load into this one.)

Why cut at episode ends: the ICM code's rollouts stop at a terminal (src/a3c.py env_runner:
``if terminal_end: break``), and a shorter rollout is its own update, its mean loss times the
constant 20 (a3c.py:299, 308, "batchsize=20. Factored out..."), so each of its L steps weighs
20 / L. The constant is 20 whatever ``--rollout-len`` is (``ROLLOUT_SCALE``), so that T does not
change the loss's scale against the clip at 40. A piece here starts where the update's rollout
starts or where an episode starts, where the ICM code's next rollout starts 20 steps after the
last one or at an episode's start: the pieces of an episode that outlasts a rollout are cut at
other steps (both make the same returns: a piece's return bootstraps from the value after it, a
piece that ends an episode gets none).

What the ICM code does, besides (src/a3c.py, src/constants.py, src/model.py):
- L_A2C = pi_loss + 0.5 * vf_loss - 0.01 * entropy (a3c.py:290-296), where pi_loss and the
  entropy are batch means and vf_loss = 0.5 * mean((V - R)^2) (a3c.py:292): the value term is
  0.25 times the mean squared error, ``value_coef`` 0.25 by default here (the paper's "value
  weight 0.5" is that 0.5 on half the squared error).
- The predictor's loss is PREDICTION_LR_SCALE (10) * ((1 - 0.2) L_I + 0.2 L_F) (a3c.py:306,
  constants.py:18-20), its gradient also of ``* 20`` (a3c.py:308): with eta = 0.1 and lambda
  = 0.2, the paper's values, (20 / eta) * L_nov above (``prediction_scale``: 1 / eta). Its L_I
  and L_F are batch means over the rollout (model.py:273, 282).
- Each gradient is clipped to global norm GRAD_NORM_CLIP = 40 on its own (a3c.py:353, 356), then
  both are applied by one tf.train.AdamOptimizer(1e-4) (a3c.py:367, constants.py:14) with TF's
  defaults (beta 0.9, 0.999, epsilon 1e-8, ``TF_ADAM_EPS``; TF puts epsilon outside the bias
  correction, a difference of sqrt(1 - 0.999^t) on a 1e-8 that is left alone here).
- Reward plus bonus is clipped to [-1, 1] (REWARD_CLIP, a3c.py:40, 48) when the workers run with
  --envWrap, which its Doom command (train.py --default) sets: ``reward_clip``.
- GAE lambda 1 (constants.py:3): the advantage is the n-step return minus V, as here.
- An episode that ends, at the goal or at the time limit (a3c.py:200), gives the rollout no
  bootstrap value (a3c.py:234-235): ``bootstrap_time_limit`` false.
- The last transition of an episode is scored there (``pred_bonus(last_state, state, action)``
  with the terminal frame ``state``). Here it gets no bonus and no loss: the environments reset
  themselves, and the step that ends an episode returns the next episode's first frame, so the
  frame the last action led to is never seen (``simjax.novelty.base``).
Those settings are ``TrainConfig``'s defaults under ``learner="a3c"`` (``LEARNER_DEFAULTS``).

Per-actor gradients: each round's losses are ``vmap``ped over the environments, one column
each, with its own gradient (``jax.vmap(jax.grad(...))``), the steps outside the round's piece
weighted 0, so a round costs what the batch's backward pass does, and an update as many rounds
as its actors' most pieces (1 where no episode ends within the rollout; a ``lax.while_loop``).
The novelty model is run through ``Novelty.prepare`` / ``model_loss`` / ``bonus_and_state``: the
bonus comes from one pass over the whole rollout first (the frame normalisation and the bonus's
normaliser see the whole batch, as under A2C), and each round's loss is the model's on the
transitions of the round's pieces (``model_loss(..., targets=...)``). A stateful model that
trains (EC's ECO) has no loss per transition: its whole loss goes with each actor's first piece.
``metrics.csv``'s ``grad_norm`` is the mean, over the update's optimiser steps, of the norm of
the policy gradient before clipping, of 20 x a piece's mean loss (what the ICM code logs, and
what the clip at 40 acts on); it is not comparable with A2C's, the norm of the gradient of the
mean loss over all N x T steps. Its loss terms are the batch means A2C logs.
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

TF_ADAM_EPS = 1e-8  # tf.train.AdamOptimizer's default, which the ICM code uses (A2C's is a2c.A2C_ADAM_EPS)
ROLLOUT_SCALE = 20.0  # the ICM code's loss * 20.0 (src/a3c.py:299, 308): a rollout's mean loss times 20


def prediction_scale(hyper: Hyper):
    """The novelty model's loss scale against the policy's: 1 / eta (the ICM code's
    PREDICTION_LR_SCALE, 10, at the paper's eta 0.1). ``Hyper.policy_weight`` holds eta."""
    return 1.0 / hyper.policy_weight


def group_optimizers(hyper: Hyper, trainable: bool) -> dict[str, optax.GradientTransformation]:
    """The optimiser of each parameter group, one state shared by every actor: a gradient clipped
    to ``max_grad_norm``, then Adam. A novelty model that does not train (none, or EC's fixed
    network) has none."""
    group = optax.chain(optax.clip_by_global_norm(hyper.max_grad_norm),
                        optax.adam(hyper.learning_rate, eps=TF_ADAM_EPS))
    return {"policy": group, **({"novelty": group} if trainable else {})}


def pieces(done: jnp.ndarray) -> jnp.ndarray:
    """(T, N) int32: the piece of its actor's rollout each step belongs to, the number of episode
    ends before it (a step that ends an episode is its piece's last)."""
    ends = done.astype(jnp.int32)
    return jnp.cumsum(ends, axis=0) - ends


def piece_weights(piece: jnp.ndarray, k) -> jnp.ndarray:
    """(T, N): ROLLOUT_SCALE / L on the L steps of each actor's piece ``k``, 0 elsewhere (and
    everywhere for an actor with fewer pieces): the weights of the steps' losses in piece k's."""
    mask = (piece == k).astype(jnp.float32)
    return mask * ROLLOUT_SCALE / jnp.maximum(mask.sum(axis=0), 1.0)


def draw_order(key, k, num_actors: int) -> jnp.ndarray:
    """The order the actors' round-``k`` steps are applied in: a uniformly random permutation,
    drawn afresh each round from the update's key."""
    return jax.random.permutation(jax.random.fold_in(key, k), num_actors)


def apply_in_order(txs: dict, params: dict, opt_states: dict, grads: dict, order: jnp.ndarray, active: jnp.ndarray):
    """``(params, opt_states)`` after each active actor's step in turn, actor ``order[0]``'s
    first: group ``g`` of ``params`` is stepped by ``txs[g]`` with actor i's gradient
    ``grads[g][i]`` (leading axis: actor) and the one state ``opt_states[g]``, which each step
    reads as the step before left it; an actor with ``active[i]`` false takes no step. Groups
    without an optimiser are left as they are."""

    def one(j, carry):
        i = order[j]

        def step(carry):
            params, states = dict(carry[0]), dict(carry[1])
            for name, tx in txs.items():
                updates, states[name] = tx.update(jax.tree.map(lambda x: x[i], grads[name]), states[name],
                                                  params[name])
                params[name] = optax.apply_updates(params[name], updates)
            return params, states

        return jax.lax.cond(active[i], step, lambda carry: carry, carry)

    return jax.lax.fori_loop(0, order.shape[0], one, (params, opt_states))


def _column(tree, axis: int):
    """One environment's slice of a batch, kept as a batch of one (the shape the losses take)."""
    return jax.tree.map(lambda x: jnp.expand_dims(x, axis), tree)


def a3c_rule(config: TrainConfig, network: ActorCritic, novelty: Novelty) -> UpdateRule:
    N = config.num_envs
    trainable = novelty.trainable
    # a stateful model whose loss is no sum over transitions (EC's ECO) gives it all with the first piece
    whole_loss = getattr(novelty.model, "stateful", False) and not getattr(novelty.model, "per_transition_loss", False)

    def init(params, hyper: Hyper):
        """One optimiser state per group, shared by the actors (as the ICM code's one Adam)."""
        return {name: tx.init(params[name]) for name, tx in group_optimizers(hyper, trainable).items()}

    def novelty_bonus(params, runner: RunnerState, traj: Transition, last_obs, last_reset):
        """(the bonus (T, N), the metrics, the novelty state after the rollout, the prepared
        rollout): the model's pass over the whole rollout, each actor's column on its own."""
        hyper = runner.hyper
        if novelty.model is None:  # no bonus, no loss
            _, (bonus, metrics, state) = novelty.loss_and_bonus(params, runner.novelty, traj.obs, traj.reset,
                                                                traj.action, last_obs, last_reset, hyper.novelty)
            return bonus, metrics, state, None
        prepared = novelty.prepare(runner.novelty, traj.obs, traj.reset, traj.action, last_obs, last_reset)
        tl = prepared.timeline

        def actor(frames, actions, segment, valid, model_state):
            one = prepared._replace(timeline=Timeline(*_column((frames, actions, segment, valid), 1), tl.history))
            _, (error, scored, metrics, state) = novelty.model_loss(params, _column(model_state, 0), one,
                                                                    hyper.novelty)
            return error[:, 0], scored[:, 0], metrics, jax.tree.map(lambda x: x[0], state)

        error, scored, metrics, model_state = jax.vmap(actor, in_axes=(1, 1, 1, 1, 0), out_axes=(1, 1, 0, 0))(
            tl.frames, tl.actions, tl.segment, tl.valid, runner.novelty.model)
        metrics = jax.tree.map(jnp.mean, metrics)
        bonus, metrics, state = novelty.bonus_and_state(runner.novelty, prepared, error, scored, metrics, model_state,
                                                        hyper.novelty)
        return bonus, metrics, state, prepared

    def novelty_grads(params, runner: RunnerState, prepared, piece, k):
        """Each actor's gradient of (20 / eta) L_nov on the transitions of its piece ``k``
        (leading axis: actor)."""
        hyper = runner.hyper
        tl = prepared.timeline
        scale = ROLLOUT_SCALE * prediction_scale(hyper)

        def actor(frames, actions, segment, valid, model_state, piece_i):
            one = prepared._replace(timeline=Timeline(*_column((frames, actions, segment, valid), 1), tl.history))

            def loss(p):
                if whole_loss:  # ECO: no loss per transition; all of it with the actor's first piece
                    value, _ = novelty.model_loss(p, _column(model_state, 0), one, hyper.novelty)
                    return jnp.where(k == 0, scale * value, 0.0)
                value, _ = novelty.model_loss(p, _column(model_state, 0), one, hyper.novelty,
                                              targets=(piece_i == k)[:, None])
                return scale * value

            return jax.grad(loss)(params)

        return jax.vmap(actor, in_axes=(1, 1, 1, 1, 0, 1))(tl.frames, tl.actions, tl.segment, tl.valid,
                                                           runner.novelty.model, piece)

    def policy_grads(params, runner: RunnerState, traj: Transition, last_obs, last_reset, bonus, weights):
        """(each actor's gradient of sum_t w_t l_t, its A2C loss's steps weighted by ``weights``
        (T, N) (leading axis: actor), each actor's loss terms)."""

        def actor(traj_i, carry_i, last_obs_i, last_reset_i, bonus_i, weights_i):
            def loss(p):
                return a2c_loss(p, network, _column(carry_i, 0), _column(traj_i, 1), last_obs_i[None],
                                last_reset_i[None], bonus_i[:, None], config, runner.hyper, weights_i[:, None])

            return jax.grad(loss, has_aux=True)(params)

        return jax.vmap(actor, in_axes=(1, 0, 0, 0, 1, 1))(traj._replace(metrics={}), runner.carry, last_obs,
                                                           last_reset, bonus, weights)

    def step(runner: RunnerState, traj: Transition, last_obs, last_reset, key):
        key, order_key = jax.random.split(key)
        start = runner.params
        bonus, novelty_info, novelty_state, prepared = novelty_bonus(start["novelty"], runner, traj, last_obs,
                                                                     last_reset)
        piece = pieces(traj.done)
        count = piece[-1] + 1  # (N,) each actor's pieces
        txs = group_optimizers(runner.hyper, trainable)

        def round_(k, params, opt_state):
            grads, info = policy_grads(start["policy"], runner, traj, last_obs, last_reset, bonus,
                                       piece_weights(piece, k))
            norms = jax.vmap(optax.tree.norm)(grads)
            grads = {"policy": grads}
            if trainable:
                grads["novelty"] = novelty_grads(start["novelty"], runner, prepared, piece, k)
            active = count > k
            params, opt_state = apply_in_order(txs, params, opt_state, grads, draw_order(order_key, k, N), active)
            return params, opt_state, info, jnp.sum(jnp.where(active, norms, 0.0))

        # round k while any actor has a k-th piece (round 0: every actor); the loss terms are the
        # same plain means in every round, the last round's kept
        def more(carry):
            return carry[0] < jnp.max(count)

        def next_round(carry):
            k, params, opt_state, _, norm_sum = carry
            params, opt_state, info, norms = round_(k, params, opt_state)
            return k + 1, params, opt_state, info, norm_sum + norms

        terms = jax.eval_shape(lambda: round_(0, start, runner.opt_state)[2])
        zeros = jax.tree.map(lambda x: jnp.zeros(x.shape, x.dtype), terms)
        _, params, opt_state, info, norm_sum = jax.lax.while_loop(
            more, next_round, (jnp.zeros((), jnp.int32), start, runner.opt_state, zeros, jnp.zeros(())))
        info = {**jax.tree.map(jnp.mean, info), **novelty_info, "grad_norm": norm_sum / jnp.sum(count)}
        return params, opt_state, key, info, novelty_state

    return UpdateRule(init, step)
