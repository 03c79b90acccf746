"""A3C's update rule (``--learner a3c``, ``simjax.agents.a3c``) against references written by hand:
each actor's loss as plain sums over its steps (the ICM code's weights), optax's clip and Adam
applied actor by actor, and the return rules on handmade episodes."""

import csv
import dataclasses
import json

import chex
import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

from simjax import runs
from simjax import train as cli
from simjax.agents import TrainConfig, a3c, make_trainer
from simjax.agents.a2c import Transition, a2c_loss
from simjax.envs import starts_episode
from simjax.novelty.base import normalize_frames
from simjax.novelty.networks import RNDPredictor, RNDTarget
from simjax.runs.grid import check_sweep
from simjax.runs.progress import Progress

T = 3  # steps per actor per update


def _config(num_envs: int) -> TrainConfig:
    # one update per compiled call; RND: a novelty model with a loss of its own, on normalised frames
    n = num_envs * T
    return TrainConfig(env="maze-tiny", algo="rnd", learner="a3c", num_envs=num_envs, rollout_len=T, total_steps=n,
                       log_every=n)


def hand_gradients(network, config: TrainConfig, runner, traj: Transition, last_obs, last_reset):
    """Each actor's gradients, by hand: {"policy": [g_0, g_1, ...], "novelty": [...]}, of its loss
    summed over its T steps as the ICM code weighs it (src/a3c.py:290-308):
        sum_t [-log pi(a_t) A_t + 0.25 (G_t - V_t)^2 - 0.01 H_t]   (pi_loss + 0.5 * 0.5 MSE - 0.01 H, times T)
        + (T / eta) * (RND's error averaged over the actor's scored steps)
    with r_t = clip(r^e_t + beta * error_t, -1, 1) and no bootstrap where an episode ends."""
    n = traj.reward.shape[1]
    gamma, eta, beta = 0.99, config.rl_weight, config.bonus_scale
    # RND: o_{t+1} normalised by the running statistics with this rollout's frames folded in
    stats = runner.novelty.obs_stats.update(traj.obs)
    x = normalize_frames(jnp.concatenate([traj.obs[1:], last_obs[None]]), stats)
    scored = ~jnp.concatenate([traj.reset[1:], last_reset[None]])  # o_{t+1} is not an episode's first frame

    def rnd_error(p):  # (T, N)
        target = jax.lax.stop_gradient(RNDTarget().apply(p["target"], x))
        return 0.5 * jnp.sum((RNDPredictor().apply(p["predictor"], x) - target) ** 2, axis=-1)

    bonus = beta * rnd_error(runner.params["novelty"]) * scored

    def novelty_loss(p, i):
        mask = scored[:, i].astype(jnp.float32)
        return T / eta * jnp.sum(rnd_error(p)[:, i] * mask) / jnp.maximum(jnp.sum(mask), 1.0)

    def policy_loss(p, i):
        obs = jnp.concatenate([traj.obs[:, i], last_obs[i][None]])[:, None]
        reset = jnp.concatenate([traj.reset[:, i], last_reset[i][None]])[:, None]
        carry = jax.tree.map(lambda c: c[i : i + 1], runner.carry)
        _, logits, values = network.apply(p, carry, obs, reset)
        logits, values = logits[:, 0], values[:, 0]
        v = jax.lax.stop_gradient(values)
        r = jnp.clip(traj.reward[:, i] + bonus[:, i], -1.0, 1.0)
        returns, g = [None] * T, v[T]
        for t in reversed(range(T)):
            g = r[t] + gamma * (1.0 - traj.done[t, i]) * g
            returns[t] = g
        total = 0.0
        for t in range(T):
            log_p = jax.nn.log_softmax(logits[t])
            entropy = -jnp.sum(jnp.exp(log_p) * log_p)
            total += -log_p[traj.action[t, i]] * (returns[t] - v[t]) + 0.25 * (returns[t] - values[t]) ** 2 - 0.01 * entropy
        return total

    params = runner.params
    return {"policy": [jax.grad(policy_loss)(params["policy"], i) for i in range(n)],
            "novelty": [jax.grad(novelty_loss)(params["novelty"], i) for i in range(n)]}


def hand_update(params, grads, order, clip, lr):
    """Actor i's gradients clipped to ``clip`` per group and stepped by an Adam of actor i's own,
    fresh (its first update), one actor after another in ``order``: (params, states per group per actor)."""
    tx = optax.chain(optax.clip_by_global_norm(clip), optax.adam(lr, eps=1e-8))
    n = len(grads["policy"])
    states = {group: [tx.init(params[group]) for _ in range(n)] for group in ("policy", "novelty")}
    params = dict(params)
    for i in order:
        for group in ("policy", "novelty"):
            updates, states[group][i] = tx.update(grads[group][i], states[group][i], params[group])
            params[group] = optax.apply_updates(params[group], updates)
    return params, states


def _close(got, want, what: str, rel: float = 1e-4):
    """Every leaf within ``rel`` of the leaf's largest magnitude (the gradients are summed in
    another order here than in the learner, so their float rounding differs)."""
    for path, g, w in zip(jax.tree_util.tree_leaves_with_path(want), jax.tree.leaves(got), jax.tree.leaves(want)):
        g, w = np.asarray(g), np.asarray(w)
        np.testing.assert_allclose(g, w, rtol=0, atol=rel * max(float(np.max(np.abs(w))), 1e-12),
                                   err_msg=f"{what} {jax.tree_util.keystr(path[0])}")


class _Case:
    """One learner update of the config with ``num_envs`` actors and its reference, from key ``seed``."""

    def __init__(self, num_envs: int, seed: int = 0):
        self.config = config = _config(num_envs)
        self.trainer = trainer = make_trainer(config)
        self.hyper = config.hyper()
        runner = jax.jit(trainer.init)(jax.random.PRNGKey(seed), self.hyper)
        env_state, _, key, traj = jax.jit(trainer.collect)(runner)  # the rollout the update learns from
        self.runner, self.traj = runner, traj
        self.grads = _jit_hand_gradients(trainer.network, config)(runner, traj, env_state.obs, starts_episode(env_state))
        # the order the learner draws from its key (the key after the rollout, split once more)
        self.order = [int(i) for i in a3c.draw_order(jax.random.split(key)[1], num_envs)]


_HAND = {}


def _jit_hand_gradients(network, config):
    if config not in _HAND:  # one compiled reference per config, shared by the tests
        _HAND[config] = jax.jit(lambda *args: hand_gradients(network, config, *args))
    return _HAND[config]


def _norm(tree) -> float:
    return float(optax.tree.norm(tree))


@pytest.mark.xdist_group("a3c_rnd")
@pytest.mark.parametrize("num_envs", [1, 2])
def test_each_actor_takes_an_adam_step_of_its_own_on_its_summed_loss(num_envs):
    """N = 1: one Adam step on the summed loss, each group's gradient clipped on its own. N = 2:
    two steps in the drawn order, each with its actor's own (fresh) Adam state and its gradient
    taken at the parameters the update started from. The Adam moments after the update are
    (1 - beta) times the clipped gradients, so they show the loss's weights and the clips even
    where Adam's first step (about lr * sign(g)) does not. Twice, from one compiled program: with
    a clip no gradient reaches (every weight shows), and with one between the two groups'
    gradient norms (one group is clipped, the other is not, so a clip over both together, or
    none, gives other gradients)."""
    case = _Case(num_envs)
    config, grads = case.config, case.grads
    norms = sorted([_norm(grads["policy"][0]), _norm(grads["novelty"][0])])
    assert norms[1] > 2 * norms[0], norms
    largest = max(_norm(g) for group in grads.values() for g in group)
    init, chunk = jax.jit(case.trainer.init), jax.jit(case.trainer.run_chunk)
    hand = jax.jit(hand_update, static_argnums=2)
    assert config.learning_rate == 1e-4
    for clip in (2 * largest, float(np.sqrt(norms[0] * norms[1]))):
        runner = init(jax.random.PRNGKey(0), case.hyper._replace(max_grad_norm=np.float32(clip)))
        after, _ = chunk(runner)
        want_params, want_states = hand(runner.params, grads, tuple(case.order), clip, config.learning_rate)
        for group in ("policy", "novelty"):
            for i in range(num_envs):
                mine = jax.tree.map(lambda x, i=i: x[i], after.opt_state[group])
                _close(mine, want_states[group][i], f"clip {clip:.3g}: {group} actor {i}")
                counts = [leaf for leaf in jax.tree.leaves(after.opt_state[group]) if leaf.dtype == jnp.int32]
                assert all(int(c[i]) == 1 for c in counts)  # each actor's own Adam took one step
        moved = jax.tree.map(lambda a, b: a - b, after.params, runner.params)
        want_moved = jax.tree.map(lambda a, b: a - b, want_params, runner.params)
        # looser: where |g| is near Adam's epsilon its step follows g's rounding
        _close(moved, want_moved, f"clip {clip:.3g}: step", rel=1e-2)
        assert _norm(moved["policy"]) > 0 and _norm(moved["novelty"]["predictor"]) > 0
        chex.assert_trees_all_equal(after.params["novelty"]["target"], runner.params["novelty"]["target"])


@pytest.mark.xdist_group("a3c_rnd")
def test_the_steps_are_applied_in_the_order_drawn_each_update(monkeypatch):
    """With Adam the order changes only rounding, so here each actor's "step" sets the params to
    its gradient: the params after the update are the gradient of the actor drawn last. Both
    orders of two actors come up among the first seeds, and each is followed."""
    def overwrite():  # params <- g; and a count per actor
        return optax.GradientTransformation(lambda p: jnp.zeros((), jnp.int32),
                                            lambda g, s, p: (jax.tree.map(jnp.subtract, g, p), s + 1))

    monkeypatch.setattr(a3c, "actor_optimizers", lambda hyper, trainable: {"policy": overwrite(), "novelty": overwrite()})
    seen = set()
    init, chunk = None, None
    for seed in range(8):
        case = _Case(2, seed)
        if init is None:
            init, chunk = jax.jit(case.trainer.init), jax.jit(case.trainer.run_chunk)
        after, _ = chunk(init(jax.random.PRNGKey(seed), case.hyper))
        last, first = case.order[-1], case.order[0]
        _close(after.params["policy"], case.grads["policy"][last], f"seed {seed}: policy", rel=1e-4)
        gap = jax.tree.map(lambda a, b: np.max(np.abs(np.asarray(a) - np.asarray(b))), after.params["policy"],
                           case.grads["policy"][first])
        assert max(jax.tree.leaves(gap)) > 1e-3 * _norm(case.grads["policy"][first])  # not the other actor's
        np.testing.assert_array_equal(after.opt_state["policy"], [1, 1])
        seen.add(tuple(case.order))
        if len(seen) == 2:
            break
    assert seen == {(0, 1), (1, 0)}


def test_apply_in_order_steps_each_actor_once_with_its_own_state():
    txs = {"w": optax.GradientTransformation(lambda p: jnp.zeros(()),
                                             lambda g, s, p: (jax.tree.map(jnp.subtract, g, p), s + 10 * p.sum()))}
    params = {"w": jnp.zeros(2), "frozen": jnp.ones(3)}
    grads = {"w": jnp.array([[1.0, 1.0], [2.0, 2.0], [3.0, 3.0]])}
    states = {"w": jnp.zeros(3)}
    got, got_states = a3c.apply_in_order(txs, params, states, grads, jnp.array([2, 0, 1]))
    np.testing.assert_array_equal(got["w"], [2.0, 2.0])  # actor 1's, applied last
    np.testing.assert_array_equal(got["frozen"], [1.0, 1.0, 1.0])  # a group without an optimiser stays
    # each state saw the params as the actors before it left them: actor 2 first (0), then 0 (after 2: 6), then 1 (after 0: 2)
    np.testing.assert_array_equal(got_states["w"], [60, 20, 0])


def _episodes(reward, bonus):
    """One env's handmade rollout of 4 steps: the goal ends step 1, the time limit step 3."""
    col = lambda xs: jnp.array(xs, jnp.float32)[:, None]
    traj = Transition(obs=jnp.zeros((4, 1, 2)), reset=jnp.array([[False], [False], [True], [False]]),
                      action=jnp.zeros((4, 1), jnp.int32), reward=col(reward), done=col([0, 1, 0, 1]),
                      truncation=col([0, 0, 0, 1]), metrics={})
    return traj, col(bonus)


class _FixedValues:
    """A stand-in network: uniform logits over 4 actions, the given values V(o_0..o_4)."""

    def apply(self, params, carry, obs, reset):
        values = jnp.array([10.0, 20.0, 30.0, 40.0, 50.0])[:, None]
        return carry, jnp.zeros((5, 1, 4)), values


@pytest.mark.parametrize("settings,returns", [
    # r = [0.5, 20.5, -3, 0.25] (task 20 at the goal, bonuses 0.5, 0.5, -3, 0.25), gamma 0.5;
    # a2c: nothing clipped, the time limit bootstraps from V(o_3) = 40:
    # G_3 = 0.25 + .5 * 40, G_2 = -3 + .5 * G_3, G_1 = 20.5 (the goal), G_0 = 0.5 + .5 * G_1
    (dict(learner="a2c"), [10.75, 20.5, 7.125, 20.25]),
    # a3c on a task with rewards in [-1, 1]: clipped to [0.5, 1, -1, 0.25], and no bootstrap
    (dict(learner="a3c"), [1.0, 1.0, -0.875, 0.25]),
    # each rule on its own
    (dict(learner="a3c", bootstrap_time_limit=True), [1.0, 1.0, 9.125, 20.25]),
    (dict(learner="a3c", reward_clip=False), [10.75, 20.5, -2.875, 0.25]),
])
def test_the_return_rules_on_handmade_episodes(settings, returns):
    config = TrainConfig(env="maze-tiny", gamma=0.5, entropy_coef=0.0, **settings)
    traj, bonus = _episodes([0, 20, 0, 0], [0.5, 0.5, -3, 0.25])
    _, info = a2c_loss(None, _FixedValues(), None, traj, jnp.zeros((1, 2)), jnp.zeros(1, bool), bonus, config)
    errors = np.array(returns) - [10.0, 20.0, 30.0, 40.0]
    np.testing.assert_allclose(info["value_loss"], np.mean(errors**2), rtol=1e-6)
    np.testing.assert_allclose(info["policy_loss"], np.log(4) * np.mean(errors), rtol=1e-6)  # -mean(log(1/4) A)


def test_each_learner_has_its_defaults_and_old_configs_load_as_a2c(tmp_path):
    a2c, a3c_ = TrainConfig(env="maze-tiny"), TrainConfig(env="maze-tiny", learner="a3c")
    assert (a2c.learning_rate, a2c.max_grad_norm, a2c.value_coef, a2c.reward_clip, a2c.bootstrap_time_limit) == (
        1e-3, 0.5, 0.5, False, True)
    assert (a3c_.learning_rate, a3c_.max_grad_norm, a3c_.value_coef, a3c_.reward_clip, a3c_.bootstrap_time_limit) == (
        1e-4, 40.0, 0.25, True, False)
    # the clip is on by default only where the task's rewards lie in [-1, 1]
    assert TrainConfig(env="maze-very-sparse-flat-SILVER2", learner="a3c").reward_clip
    assert not TrainConfig(env="melon", learner="a3c").reward_clip
    assert not TrainConfig(env="explore-goals", learner="a3c").reward_clip
    given = TrainConfig(env="melon", learner="a3c", learning_rate=3e-4, value_coef=0.5, reward_clip=True)
    assert (given.learning_rate, given.value_coef, given.reward_clip) == (3e-4, 0.5, True)
    with pytest.raises(ValueError, match="--learner"):
        TrainConfig(learner="a4c")
    # a config.json written before the flag is an A2C run with the values it recorded
    runs.write_config(tmp_path, TrainConfig(env="maze-tiny", learning_rate=3e-4))
    record = json.loads((tmp_path / "config.json").read_text())
    for name in ("learner", "reward_clip", "bootstrap_time_limit"):
        del record["config"][name]
    (tmp_path / "config.json").write_text(json.dumps(record))
    old = runs.load_config(tmp_path)
    assert (old.learner, old.learning_rate, old.reward_clip, old.bootstrap_time_limit) == ("a2c", 3e-4, False, True)
    assert runs.load_config(tmp_path) == dataclasses.replace(a2c, learning_rate=3e-4)


def test_the_learner_flags(capsys):
    config, _, _ = cli.parse_config(["--env", "maze-tiny", "--learner", "a3c"])
    assert (config.learner, config.learning_rate, config.reward_clip) == ("a3c", 1e-4, True)
    config, _, _ = cli.parse_config(["--env", "maze-tiny", "--learner", "a3c", "--reward-clip", "false",
                                     "--bootstrap-time-limit", "true", "--max-grad-norm", "20"])
    assert (config.reward_clip, config.bootstrap_time_limit, config.max_grad_norm) == (False, True, 20.0)
    with pytest.raises(SystemExit):
        cli.parse_config(["--learner", "a3"])
    assert "--learner: invalid choice: 'a3'" in capsys.readouterr().err
    with pytest.raises(ValueError, match="--learner cannot be swept"):
        check_sweep({}, {"learner": ["a2c", "a3c"]})


def test_an_a3c_run_resumes_as_the_run_it_would_have_been(tmp_path, monkeypatch):
    """Its checkpoint holds every actor's Adam state."""
    config = TrainConfig(env="maze-tiny", learner="a3c", num_envs=2, rollout_len=2, total_steps=12, log_every=4)
    runs.run(config, tmp_path / "whole", quiet=True)

    def stop_after_first(self, *args):
        raise KeyboardInterrupt

    with monkeypatch.context() as m:
        m.setattr(Progress, "update", stop_after_first)
        runs.run(config, tmp_path / "parts", quiet=True)
    adam = runs.load_checkpoint(tmp_path / "parts")["runner"]["opt_state"]["policy"]["1"]["0"]
    assert adam["count"].shape == (1, 2) and list(adam["count"][0]) == [1, 1]  # seeds x actors, after 1 update
    runs.run(runs.load_config(tmp_path / "parts"), tmp_path / "parts", quiet=True, resume=True)
    same = [c for c in runs.METRIC_COLUMNS if c not in ("steps_per_s", "wall_s")]
    rows = [list(csv.DictReader(open(tmp_path / d / "metrics.csv"))) for d in ("whole", "parts")]
    assert len(rows[0]) == len(rows[1]) == 3
    assert [[r[c] for c in same] for r in rows[0]] == [[r[c] for c in same] for r in rows[1]]
