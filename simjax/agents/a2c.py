"""Synchronous LSTM-A2C (the paper's LSTM-A3C with its asynchronous actors made a ``vmap``).

``simjax.agents.make_train(config)`` returns a pure ``train(key)``: N environments step in one ``jax.vmap``,
a rollout of T steps is a ``lax.scan``, and ``lax.scan`` over updates runs a whole chunk of K
updates inside one compiled call. Seeds are a ``jax.vmap`` of the same functions over keys.

Per update, with values V from the network and ``done``/``trunc`` from the environment:
    r_t   = task_scale * r^e_t + bonus_t                         (bonus_t = beta * r+_t)
    G_T   = V(o_T)
    G_t   = r_t + gamma * ((1 - done_t) G_{t+1} + trunc_t V(o_t))
    loss  = -mean(log pi(a_t|o_t) (G_t - V(o_t))) + c_v mean((G_t - V(o_t))^2) - c_H mean(H[pi])
A termination (goal reached) stops the return there; a truncation (time limit) bootstraps
(``bootstrap_time_limit``; without it, trunc_t is 0 above and the return stops there too, the
ICM code's rule). With ``reward_clip`` each r_t is clipped to [-1, 1] first (the ICM code's, in
its Doom runs).
With ``bonus_episodic=False`` (RND's non-episodic intrinsic return, Burda et al. 2018) the
network has a second value head V_b and the two rewards get returns of their own:
    G^e_t = task_scale * r^e_t + gamma_e * ((1 - done_t) G^e_{t+1} + trunc_t V_e(o_t))
    G^b_t = bonus_t + gamma * G^b_{t+1}        (on across episode ends), G^b_T = V_b(o_T)
    A_t   = w (G^e_t - V_e(o_t)) + (G^b_t - V_b(o_t)),  value loss: the sum of both squared errors,
with gamma_e = ``task_gamma`` (default gamma) and w = ``task_advantage_weight`` (default 1); RND's
code runs gamma_e 0.999, gamma 0.99 and w = 2.
Episodic, a positive bonus is worth about beta * r+ / (1 - gamma) to an agent that keeps going;
once that exceeds the goal's reward, ending the episode at the goal is a loss (docs/paper-differences.md).
The auto-resetting environment returns the new episode's first frame, not the truncated
episode's last one, so the truncation bootstrap uses V(o_t), the value of the last frame the
episode showed; with 525-step episodes and 0/1 rewards this one-step shift is immaterial.

Novelty models (``simjax.novelty``) enter through one object, ``Novelty``: its bonus is added to
the reward above and its loss to the objective, eq. (8) of the paper,
    eta * loss_A2C + lambda * L_F + (1 - lambda) * L_I,
minimised jointly over ``params = {"policy": ..., "novelty": ...}`` by one Adam. The two groups
share no parameters, so each group's gradient is clipped to its own global norm: the policy's at
eta * max_grad_norm and with Adam's epsilon scaled by eta too, which makes its step exactly plain
A2C's (Adam of (eta g, eta eps) is Adam of (g, eps)); the novelty model's at max_grad_norm.
Scaling epsilon matters: the policy gradients of eta * loss_A2C are ~1e-6 per parameter, below
Adam's usual 1e-5, which would otherwise shrink the policy's steps several-fold.

That update is one rule (``a2c_rule``); ``assemble_trainer`` builds the rollout and the loop
around a rule, and ``simjax.agents.trainer.make_trainer`` hands it the one ``config.learner``
names (A3C's is ``simjax.agents.a3c``'s), so this module imports neither a3c nor the trainer.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import chex
import jax
import jax.numpy as jnp
import optax

from simjax.agents.config import Hyper, TrainConfig
from simjax.envs import make
from simjax.envs.episodes import rollout, starts_episode
from simjax.networks import ActorCritic
from simjax.novelty import METRICS as NOVELTY_METRICS
from simjax.novelty import Novelty, make_novelty
from simjax.novelty.ec_pretrain import make_pretrainer

A2C_ADAM_EPS = 1e-5  # Adam's epsilon under A2C (A3C's is simjax.agents.a3c.TF_ADAM_EPS, 1e-8)


class Transition(NamedTuple):
    obs: jnp.ndarray  # (T, N, H, W, C) uint8, o_t
    reset: jnp.ndarray  # (T, N) bool, o_t is an episode's first frame
    action: jnp.ndarray  # (T, N) int32
    reward: jnp.ndarray  # (T, N) float32, extrinsic r^e_t
    done: jnp.ndarray  # (T, N) float32, the step ended the episode
    truncation: jnp.ndarray  # (T, N) float32, ...by the time limit
    metrics: dict  # (T, N) episode statistics, valid where metrics['episode_done']


class RunnerState(NamedTuple):
    params: chex.ArrayTree  # {"policy": actor-critic, "novelty": novelty model ({} for a2c)}
    opt_state: chex.ArrayTree
    env_state: chex.ArrayTree  # batched brax State
    carry: tuple  # LSTM (c, h), each (N, hidden); reset where env_state.done marks a new episode
    novelty: chex.ArrayTree  # NoveltyState: per-env frame/action memory, running statistics
    key: jnp.ndarray
    hyper: Hyper  # the numeric settings this runner trains with (a sweep point's)


class Trainer(NamedTuple):
    """The pieces of a run: ``init(key, hyper=None)``, ``run_chunk(state)`` (K updates) and
    ``train(key, hyper=None)``; ``hyper`` defaults to the config's (``TrainConfig.hyper``)."""

    init: Callable
    run_chunk: Callable
    train: Callable
    network: ActorCritic
    novelty: Novelty
    pretrain: object = None  # EC's ``Pretrainer`` (before the first update; ``train`` runs it), or None
    # an update's parts, for timing them apart (experiments/bench.py): ``collect(runner) -> (env_state,
    # carry, key, traj)``; A2C's ``loss(params, runner, traj, last_obs, last_reset) -> (loss, (info,
    # novelty state))`` and ``optimizer(hyper)`` the optax transformation (None under A3C's rule)
    collect: Callable | None = None
    loss: Callable | None = None
    optimizer: Callable | None = None


def total_reward(task_scale: float, extrinsic: jnp.ndarray, bonus: jnp.ndarray) -> jnp.ndarray:
    """The one place where the reward is formed: r = task_scale * r_e + bonus."""
    return task_scale * extrinsic + bonus


def sampling_policy(network: ActorCritic, params):
    """The policy as it acts in training, for ``simjax.envs.episodes.rollout``: ``(carry,
    state, key) -> (actions, carry)``, one step of the network on the batch's frames (its LSTM
    memory reset where a frame starts an episode) and an action sampled from its distribution."""

    def act(carry, state, key):
        carry, logits, _ = network.apply(params, carry, state.obs[None], starts_episode(state)[None])
        return jax.random.categorical(key, logits[0]).astype(jnp.int32), carry

    return act


def n_step_returns(rewards, dones, truncations, values, gamma: float):
    """n-step returns G_t (T, N) from rewards/dones/truncations (T, N) and values (T+1, N)."""
    chex.assert_equal_shape([rewards, dones, truncations])
    chex.assert_shape(values, (rewards.shape[0] + 1,) + rewards.shape[1:])

    def back(next_return, xs):
        r, d, tr, v = xs
        g = r + gamma * ((1.0 - d) * next_return + tr * v)
        return g, g

    _, returns = jax.lax.scan(back, values[-1], (rewards, dones, truncations, values[:-1]), reverse=True)
    return returns


def a2c_loss(params, network, carry0, traj: Transition, last_obs, last_reset, bonus, config: TrainConfig,
             hyper: Hyper | None = None, step_weights=None):
    """The A2C objective on one rollout, and its parts for logging; the numbers come from
    ``hyper`` (default ``config.hyper()``), the structure (``bonus_episodic``, ``reward_clip``,
    ``bootstrap_time_limit``) from ``config``. The objective is the mean over the (T, N) steps,
    or with ``step_weights`` (T, N) the weighted sum sum_t w_t l_t of the steps' losses l_t (A3C's
    pieces, ``simjax.agents.a3c``); the logged parts are the plain means either way."""
    hyper = config.hyper() if hyper is None else hyper
    obs = jnp.concatenate([traj.obs, last_obs[None]], axis=0)
    reset = jnp.concatenate([traj.reset, last_reset[None]], axis=0)
    _, logits, values = network.apply(params, carry0, obs, reset)
    logits, value = logits[:-1], values[:-1]
    truncation = traj.truncation if config.bootstrap_time_limit else jnp.zeros_like(traj.truncation)
    clip = (lambda r: jnp.clip(r, -1.0, 1.0)) if config.reward_clip else (lambda r: r)
    if config.bonus_episodic:
        rewards = clip(total_reward(hyper.task_scale, traj.reward, bonus))
        returns = n_step_returns(rewards, traj.done, truncation, jax.lax.stop_gradient(values), hyper.gamma)
        advantage = returns - jax.lax.stop_gradient(value)
    else:  # two streams: the task's return ends with the episode, the bonus's runs on into the next
        chex.assert_shape(values, (traj.done.shape[0] + 1, traj.done.shape[1], 2))
        never = jnp.zeros_like(traj.done)
        v = jax.lax.stop_gradient(values)
        task_gamma = hyper.gamma if config.task_gamma is None else config.task_gamma
        returns = jnp.stack([  # each stream's reward clipped on its own: they have no sum to clip
            n_step_returns(clip(total_reward(hyper.task_scale, traj.reward, 0.0)), traj.done, truncation, v[..., 0],
                           task_gamma),
            n_step_returns(clip(bonus), never, never, v[..., 1], hyper.gamma),
        ], axis=-1)
        advantages = returns - v[:-1]
        if config.task_advantage_weight != 1.0:  # (a default run's program stays as it was)
            advantages = advantages * jnp.asarray([config.task_advantage_weight, 1.0], advantages.dtype)
        advantage = jnp.sum(advantages, axis=-1)  # the policy follows both: A = w A_task + A_bonus
    log_probs = jax.nn.log_softmax(logits)
    log_pi = jnp.take_along_axis(log_probs, traj.action[..., None], axis=-1)[..., 0]
    entropy = -jnp.sum(jnp.exp(log_probs) * log_probs, axis=-1)
    policy_loss = -jnp.mean(log_pi * advantage)
    squared = (returns - value) ** 2
    value_loss = jnp.mean(squared if config.bonus_episodic else squared.sum(-1))
    entropy_mean = jnp.mean(entropy)
    if step_weights is None:
        loss = policy_loss + hyper.value_coef * value_loss - hyper.entropy_coef * entropy_mean
    else:
        per_step = (-log_pi * advantage + hyper.value_coef * (squared if config.bonus_episodic else squared.sum(-1))
                    - hyper.entropy_coef * entropy)
        loss = jnp.sum(step_weights * per_step)
    return loss, {
        "policy_loss": policy_loss,
        "value_loss": value_loss,
        "entropy": entropy_mean,
        "value_mean": jnp.mean(value if config.bonus_episodic else value.sum(-1)),  # both streams together
    }


def frozen(tx: optax.GradientTransformation) -> optax.GradientTransformation:
    """``tx``'s state, never updated, and zero updates: the optimiser of a group whose params
    stay fixed (EC's network after its pretraining). A frozen model's gradient is zero, and Adam
    would still read and write its moments and params every update (EC's are 12M floats, 5% of
    its update); the state keeps ``tx``'s structure, so checkpoints load either way."""
    def update(updates, state, params=None):
        return jax.tree.map(jnp.zeros_like, updates), state

    return optax.GradientTransformation(tx.init, update)


class UpdateRule(NamedTuple):
    """How an update turns a rollout into new parameters: A2C's (``a2c_rule``) or A3C's
    (``simjax.agents.a3c.a3c_rule``); ``assemble_trainer`` builds the rest around it.

    ``init(params, hyper) -> opt_state``; ``step(runner, traj, last_obs, last_reset, key) ->
    (params, opt_state, key, info, novelty_state)``: ``runner`` as the rollout ``traj`` started
    from, ``last_obs``/``last_reset`` the frame after it, ``key`` the runner's key after the
    rollout; ``info`` the loss terms, the novelty metrics and ``grad_norm``. ``loss`` and
    ``optimizer`` are the rule's parts that ``Trainer`` exposes for timing them apart (or None)."""

    init: Callable
    step: Callable
    loss: Callable | None = None
    optimizer: Callable | None = None


def a2c_rule(config: TrainConfig, network: ActorCritic, novelty: Novelty) -> UpdateRule:
    """Synchronous A2C's update: one Adam step on eq. (8) over the batch's mean losses."""

    def optimizer(hyper: Hyper):
        """Adam per parameter group, built from the runner's (traced) settings each update: its
        state (counts and moments) does not depend on them, so any values share one program."""
        def group(scale):
            clip, eps = scale * hyper.max_grad_norm, scale * A2C_ADAM_EPS
            return optax.chain(optax.clip_by_global_norm(clip), optax.adam(hyper.learning_rate, eps=eps))

        novelty_group = group(1.0) if novelty.trainable else frozen(group(1.0))
        return optax.multi_transform(
            {"policy": group(hyper.policy_weight), "novelty": novelty_group},
            {"policy": "policy", "novelty": "novelty"},
        )

    def loss_fn(params, runner: RunnerState, traj: Transition, last_obs, last_reset):
        novelty_loss, (bonus, novelty_info, novelty_state) = novelty.loss_and_bonus(
            params["novelty"], runner.novelty, traj.obs, traj.reset, traj.action, last_obs, last_reset,
            runner.hyper.novelty,
        )
        rl_loss, info = a2c_loss(params["policy"], network, runner.carry, traj, last_obs, last_reset, bonus, config,
                                 runner.hyper)
        return runner.hyper.policy_weight * rl_loss + novelty_loss, ({**info, **novelty_info}, novelty_state)

    def init(params, hyper: Hyper):
        return optimizer(hyper).init(params)

    def step(runner: RunnerState, traj: Transition, last_obs, last_reset, key):
        grads, (info, novelty_state) = jax.grad(loss_fn, has_aux=True)(runner.params, runner, traj, last_obs, last_reset)
        updates, opt_state = optimizer(runner.hyper).update(grads, runner.opt_state, runner.params)
        params = optax.apply_updates(runner.params, updates)
        if not novelty.trainable:  # kept as they are, not plus zero (which writes -0.0 as +0.0)
            params = {**params, "novelty": runner.params["novelty"]}
        # of the A2C loss, as plain A2C logs it
        info = {**info, "grad_norm": optax.tree.norm(grads["policy"]) / runner.hyper.policy_weight}
        return params, opt_state, key, info, novelty_state

    return UpdateRule(init, step, loss_fn, optimizer)


RuleMaker = Callable[[TrainConfig, ActorCritic, Novelty], UpdateRule]


def assemble_trainer(config: TrainConfig, make_rule: RuleMaker, env=None, novelty: Novelty | None = None) -> Trainer:
    """The learner for ``config`` with the update rule ``make_rule(config, network, novelty)``;
    ``novelty`` overrides the model ``config.algo`` names. The rollout and the loop are this
    module's. ``simjax.agents.trainer.make_trainer`` picks the rule ``config.learner`` names."""
    env = make(config.env) if env is None else env
    network = ActorCritic(num_actions=env.action_size, two_values=not config.bonus_episodic)
    if novelty is None:  # the model must read the env's observations: checked here, before compiling
        novelty = make_novelty(config.novelty, env.action_size, env.observation_size, task=config.env)
    rule = make_rule(config, network, novelty)

    N, T = config.num_envs, config.rollout_len

    def init(key, hyper: Hyper | None = None) -> RunnerState:
        hyper = jax.tree.map(jnp.asarray, config.hyper() if hyper is None else hyper)
        k_net, k_env, k_nov, k_run = jax.random.split(key, 4)
        env_state = jax.vmap(env.reset)(jax.random.split(k_env, N))
        carry = network.initial_carry(N)
        policy = network.init(k_net, carry, env_state.obs[None], starts_episode(env_state)[None])
        novelty_params, novelty_state = novelty.init(k_nov, env_state.obs)
        params = {"policy": policy, "novelty": novelty_params}
        return RunnerState(params, rule.init(params, hyper), env_state, carry, novelty_state, k_run, hyper)

    def record(state, action, next_state) -> Transition:
        return Transition(
            obs=state.obs,
            reset=starts_episode(state),
            action=action,
            reward=next_state.reward,
            done=next_state.done,
            truncation=next_state.info["truncation"],
            metrics=next_state.metrics,
        )

    def collect(runner: RunnerState):
        key, sub = jax.random.split(runner.key)
        act = sampling_policy(network, runner.params["policy"])
        env_state, carry, traj = rollout(env, act, runner.env_state, runner.carry, jax.random.split(sub, T), record)
        return env_state, carry, key, traj

    def update(runner: RunnerState, _):
        env_state, carry, key, traj = collect(runner)
        chex.assert_shape(traj.obs, (T, N) + tuple(env.observation_size))
        params, opt_state, key, info, novelty_state = rule.step(runner, traj, env_state.obs, starts_episode(env_state),
                                                                 key)
        m = traj.metrics
        done = m["episode_done"]
        info = {
            **info,
            "episodes": jnp.sum(done),
            "successes": jnp.sum(done * m["episode_success"]),
            "length_sum": jnp.sum(done * m["episode_length"]),
            "return_sum": jnp.sum(done * m["episode_return"]),
        }
        return RunnerState(params, opt_state, env_state, carry, novelty_state, key, runner.hyper), info

    def run_chunk(runner: RunnerState):
        """K = config.updates_per_log updates; episode counts summed, losses averaged."""
        runner, info = jax.lax.scan(update, runner, None, config.updates_per_log)
        sums = ("episodes", "successes", "length_sum", "return_sum")
        return runner, {k: (v.sum() if k in sums else v.mean()) for k, v in info.items()}

    pretrain = make_pretrainer(config, env, novelty)

    def train(key, hyper: Hyper | None = None):
        runner = init(key, hyper)
        if pretrain is not None:
            runner = pretrain.pretrain_runner(runner)
        return jax.lax.scan(lambda r, _: run_chunk(r), runner, None, config.num_logs)

    return Trainer(init, run_chunk, train, network, novelty, pretrain, collect, rule.loss, rule.optimizer)


def summarize(chunk: dict) -> dict:
    """Turn one chunk's summed counts into the paper's measures (NaN where no episode ended)."""
    episodes = chunk["episodes"]
    safe = jnp.maximum(episodes, 1.0)
    nan = jnp.nan
    return {
        "episodes": episodes,
        "success_ratio": jnp.where(episodes > 0, chunk["successes"] / safe, nan),
        "mean_episode_length": jnp.where(episodes > 0, chunk["length_sum"] / safe, nan),
        "mean_extrinsic_return": jnp.where(episodes > 0, chunk["return_sum"] / safe, nan),
        **{k: chunk[k] for k in ("policy_loss", "value_loss", "entropy", "value_mean", "grad_norm")},
        **{k: chunk[k] for k in NOVELTY_METRICS},
    }
