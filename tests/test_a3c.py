"""A3C's update rule (``--learner a3c``, ``simjax.agents.a3c``) against references written by hand:
each piece's loss (an actor's steps up to an episode's end) as plain sums over its steps with
the ICM code's weights, optax's clip and one Adam per group shared by the actors, applied piece
by piece, and the return rules on handmade episodes."""

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
from simjax.novelty.base import normalize_frames
from simjax.novelty.networks import RNDPredictor, RNDTarget
from simjax.runs.grid import check_sweep
from simjax.runs.progress import Progress

T = 3  # steps per actor per update
SCALE = 20.0  # the ICM code's loss * 20.0, whatever T is


def _config(num_envs: int) -> TrainConfig:
    # one update per compiled call; RND: a novelty model with a loss of its own, on normalised frames
    n = num_envs * T
    return TrainConfig(env="maze-tiny", algo="rnd", learner="a3c", num_envs=num_envs, rollout_len=T, total_steps=n,
                       log_every=n)


def hand_pieces(done) -> list[list[list[int]]]:
    """Each actor's pieces, as lists of its steps: a piece ends at an episode's end (``done``) or
    at the rollout's end."""
    done = np.asarray(done)
    out = []
    for i in range(done.shape[1]):
        pieces, current = [], []
        for t in range(done.shape[0]):
            current.append(t)
            if done[t, i] or t == done.shape[0] - 1:
                pieces.append(current)
                current = []
        out.append(pieces)
    return out


def _hand_piece_gradients(network, config: TrainConfig, runner, traj: Transition, last_obs, last_reset, i, steps):
    """Actor i's gradients ({"policy", "novelty"}) of the loss of its piece ``steps`` ((T,) 0/1),
    by hand, as the ICM code weighs a rollout of L steps (src/a3c.py:290-308):
        20 / L * sum_{t in piece} [-log pi(a_t) A_t + 0.25 (G_t - V_t)^2 - 0.01 H_t]
        + (20 / eta) * (RND's error averaged over the piece's scored transitions)
    with r_t = clip(r^e_t + beta * error_t, -1, 1) and no bootstrap where an episode ends."""
    gamma, eta, beta = 0.99, config.rl_weight, config.bonus_scale
    # RND: o_{t+1} normalised by the running statistics with this rollout's frames folded in
    stats = runner.novelty.obs_stats.update(traj.obs)
    x = normalize_frames(jnp.concatenate([traj.obs[1:], last_obs[None]]), stats)
    scored = ~jnp.concatenate([traj.reset[1:], last_reset[None]])  # o_{t+1} is not an episode's first frame

    def rnd_error(p):  # (T, N)
        target = jax.lax.stop_gradient(RNDTarget().apply(p["target"], x))
        return 0.5 * jnp.sum((RNDPredictor().apply(p["predictor"], x) - target) ** 2, axis=-1)

    bonus = beta * rnd_error(runner.params["novelty"]) * scored

    def novelty_loss(p):
        mask = scored[:, i] * steps
        return SCALE / eta * jnp.sum(rnd_error(p)[:, i] * mask) / jnp.maximum(jnp.sum(mask), 1.0)

    def policy_loss(p):
        obs = jnp.concatenate([traj.obs[:, i], last_obs[i][None]])[:, None]
        reset = jnp.concatenate([traj.reset[:, i], last_reset[i][None]])[:, None]
        carry = jax.tree.map(lambda c: jax.lax.dynamic_slice_in_dim(c, i, 1), runner.carry)
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
            term = -log_p[traj.action[t, i]] * (returns[t] - v[t]) + 0.25 * (returns[t] - values[t]) ** 2 - 0.01 * entropy
            total += steps[t] * term
        return SCALE / jnp.sum(steps) * total

    params = runner.params
    return {"policy": jax.grad(policy_loss)(params["policy"]), "novelty": jax.grad(novelty_loss)(params["novelty"])}


_HAND = {}


def hand_gradients(network, config, runner, traj, last_obs, last_reset):
    """{"policy": [[piece 0's gradient, piece 1's, ...] of actor 0, ...], "novelty": ...}."""
    if config not in _HAND:  # one compiled reference per config, shared by the tests
        def piece(runner, traj, last_obs, last_reset, i, steps):
            return _hand_piece_gradients(network, config, runner, traj, last_obs, last_reset, i, steps)

        _HAND[config] = jax.jit(piece)  # the actor i traced: one program for every actor
    grads = {"policy": [], "novelty": []}
    for i, pieces in enumerate(hand_pieces(traj.done)):
        per_piece = []
        for steps in pieces:
            mask = np.zeros(T, np.float32)
            mask[steps] = 1.0
            per_piece.append(_HAND[config](runner, traj, last_obs, last_reset, jnp.int32(i), jnp.asarray(mask)))
        for group in grads:
            grads[group].append([g[group] for g in per_piece])
    return grads


def hand_orders(key, rounds: int, num_actors: int) -> list[list[int]]:
    """The learner's orders, drawn here as the rule states them: from the runner's key after the
    rollout, split once more, a permutation folded with each round's number."""
    order_key = jax.random.split(key)[1]
    return [[int(i) for i in jax.random.permutation(jax.random.fold_in(order_key, k), num_actors)]
            for k in range(rounds)]


def hand_update(params, grads, orders, clip, lr):
    """Round k: for each actor in ``orders[k]`` that has a k-th piece, that piece's gradient of
    each group clipped to ``clip`` on its own and stepped by the group's one Adam, its state as
    the step before left it: (params, the state of each group, the steps taken)."""
    tx = optax.chain(optax.clip_by_global_norm(clip), optax.adam(lr, eps=1e-8))
    step = jax.jit(lambda g, s, p: (lambda u, s: (optax.apply_updates(p, u), s))(*tx.update(g, s, p)))
    states = jax.jit(lambda p: {group: tx.init(p[group]) for group in ("policy", "novelty")})(params)
    params, taken = dict(params), 0
    for k, order in enumerate(orders):
        for i in order:
            if k < len(grads["policy"][i]):
                taken += 1
                for group in ("policy", "novelty"):
                    params[group], states[group] = step(grads[group][i][k], states[group], params[group])
    return params, states, taken


def _rel_close(got, want, what: str, rel: float):
    """Every leaf within ``rel`` of the leaf's largest magnitude."""
    assert jax.tree.structure(got) == jax.tree.structure(want), what
    for path, g, w in zip(jax.tree_util.tree_leaves_with_path(want), jax.tree.leaves(got), jax.tree.leaves(want)):
        g, w = np.asarray(g), np.asarray(w)
        assert g.shape == w.shape, f"{what} {jax.tree_util.keystr(path[0])}: {g.shape} != {w.shape}"
        np.testing.assert_allclose(g, w, rtol=0, atol=rel * max(float(np.max(np.abs(w))), 1e-30),
                                   err_msg=f"{what} {jax.tree_util.keystr(path[0])}")


# The learner and the reference sum the same float32 terms in other orders (one vmapped backward
# pass against one per piece), so a gradient entry differs by a few float32 roundings (2^-24 =
# 6e-8 relative) of the largest terms that reach it: at most ~1e-5 of its leaf's largest entry
# for sums of the tens to thousands of terms here. The moments are linear in the gradients, so
# they are compared at MOMENT_REL (1e-4) of each leaf's largest entry, 10x above that bound.
MOMENT_REL = 1e-4
# Adam's step lr * m^ / (sqrt(v^) + eps) turns those roundings into step differences of up to
# lr where sqrt(v^) is itself near the rounding (a gradient that is nearly zero, ~1e-8, and
# whose sign is rounding): the steps are compared only where sqrt(v^) is at least STEP_FLOOR
# (1e-2) of its leaf's largest, 100x above the moments' tolerance, where the step's error is at
# most lr * (|dm^| + |m^/sqrt(v^)| |d sqrt(v^)|) / sqrt(v^) <~ lr * 3 * 1e-4 / 1e-2 = 0.03 lr.
STEP_FLOOR = 1e-2
STEP_ATOL = 0.05  # x lr


def _adam(state):
    """The ScaleByAdamState of a clip-then-Adam chain's state."""
    return state[1][0]


def _check_steps(moved, want_moved, adam_state, lr: float, what: str):
    """The params' change where Adam's step is not dominated by rounding (see STEP_FLOOR)."""
    count = int(adam_state.count)
    bias = 1.0 - 0.999 ** count
    compared = total = 0
    for path, g, w, nu in zip(jax.tree_util.tree_leaves_with_path(want_moved), jax.tree.leaves(moved),
                              jax.tree.leaves(want_moved), jax.tree.leaves(adam_state.nu)):
        root = np.sqrt(np.asarray(nu) / bias)
        mask = root >= STEP_FLOOR * root.max()
        compared, total = compared + mask.sum(), total + mask.size
        np.testing.assert_allclose(np.asarray(g)[mask], np.asarray(w)[mask], rtol=0, atol=STEP_ATOL * lr,
                                   err_msg=f"{what} {jax.tree_util.keystr(path[0])}")
    assert compared > 0.2 * total, (what, compared, total)  # most entries are compared


def _norm(tree) -> float:
    """The global norm, in float64 on the host (op by op on the device, each leaf's shape would
    compile programs of its own)."""
    return float(np.sqrt(sum(np.sum(np.square(np.asarray(x, np.float64))) for x in jax.tree.leaves(tree))))


def _cut(traj: Transition, ends) -> tuple[Transition, jnp.ndarray]:
    """The rollout with its episode ends set by hand to ``ends`` (T, N) (the frame after an end
    starts an episode), no time limits; and the reset flag of the frame after the rollout."""
    ends = jnp.asarray(ends, jnp.float32)
    reset = jnp.concatenate([traj.reset[:1], ends[:-1] > 0])
    return traj._replace(done=ends, reset=reset, truncation=jnp.zeros_like(ends)), ends[-1] > 0


class _Case:
    """One update of ``num_envs`` actors on a collected rollout whose episode ends are set to
    ``ends``, from key ``seed``: the learner's rule and its hand-written reference's gradients."""

    def __init__(self, num_envs: int, ends):
        self.config = config = _config(num_envs)
        self.trainer = trainer = make_trainer(config)
        self.hyper = config.hyper()
        init, collect = jax.jit(trainer.init), jax.jit(trainer.collect)
        for seed in range(16):  # the first seed whose first round is not in the actors' order
            runner = init(jax.random.PRNGKey(seed), self.hyper)
            env_state, _, key, traj = collect(runner)  # the rollout the update learns from
            if num_envs == 1 or hand_orders(key, 1, num_envs)[0] != list(range(num_envs)):
                break
        traj, last_reset = _cut(traj, ends)
        self.runner, self.traj, self.last_obs, self.last_reset, self.key = runner, traj, env_state.obs, last_reset, key
        self.grads = hand_gradients(trainer.network, config, runner, traj, env_state.obs, last_reset)
        self.pieces = hand_pieces(traj.done)
        self.orders = hand_orders(key, max(len(p) for p in self.pieces), num_envs)
        self.step = jax.jit(a3c.a3c_rule(config, trainer.network, trainer.novelty).step)

    def learner(self, runner):
        """(params, opt_state, info) after the learner's update of ``runner``'s params and state."""
        params, opt_state, _, info, _ = self.step(runner, self.traj, self.last_obs, self.last_reset, self.key)
        return params, opt_state, info


# the handmade episode ends (T, N): none; actor 0's episode ends at step 1 (pieces of 2 and 1
# steps) and actor 1's at the rollout's last step (one piece, no bootstrap)
CASES = {"N1": (1, [[0], [0], [0]]), "N2": (2, [[0, 0], [0, 0], [0, 0]]),
         "N2-cut": (2, [[0, 0], [1, 0], [0, 1]])}


@pytest.mark.xdist_group("a3c_rnd")
@pytest.mark.parametrize("case_name", list(CASES))
def test_one_shared_adam_steps_each_piece_in_the_drawn_order(case_name):
    """Each actor's pieces (its steps cut at episode ends), each piece's gradient of 20 x its mean
    loss taken at the update's starting params, each group clipped on its own, applied round by
    round (every actor's k-th piece, in the round's drawn order) to one Adam per group that the
    actors share: the second step reads the moments and the count the first left. The moments
    show the loss's weights and the clips (they are linear in the clipped gradients); the steps
    show that each was taken with the moments before it. Twice, from one compiled program: with a
    clip no gradient reaches (every weight shows), and with one between the two groups' gradient
    norms (one group is clipped, the other is not, so a clip over both together, or none, gives
    other gradients)."""
    num_envs, ends = CASES[case_name]
    case = _Case(num_envs, ends)
    config, grads = case.config, case.grads
    if case_name == "N2-cut":
        assert [len(p) for p in case.pieces] == [2, 1]
    if num_envs == 2:
        assert case.orders[0] == [1, 0]  # an order that a fixed one would not follow
    norms = sorted([_norm(grads["policy"][0][0]), _norm(grads["novelty"][0][0])])
    assert norms[1] > 2 * norms[0], norms
    largest = max(_norm(g) for group in grads.values() for actor in group for g in actor)
    lr = config.learning_rate
    assert lr == 1e-4
    for clip in (2 * largest, float(np.sqrt(norms[0] * norms[1]))):
        runner = case.runner._replace(hyper=case.hyper._replace(max_grad_norm=np.float32(clip)))
        params, opt_state, info = case.learner(runner)
        want_params, want_states, taken = hand_update(runner.params, grads, case.orders, clip, lr)
        for group in ("policy", "novelty"):
            what = f"{case_name}, clip {clip:.3g}: {group}"
            _rel_close(opt_state[group], want_states[group], what + " state", MOMENT_REL)
            assert _adam(opt_state[group]).count.shape == ()  # one count, shared
            assert int(_adam(opt_state[group]).count) == taken == sum(len(p) for p in case.pieces)
            moved = jax.tree.map(np.subtract, *jax.device_get((params[group], runner.params[group])))
            want_moved = jax.tree.map(np.subtract, *jax.device_get((want_params[group], runner.params[group])))
            if group == "novelty":  # the target network never moves
                chex.assert_trees_all_equal(params[group]["target"], runner.params[group]["target"])
                moved, want_moved = moved["predictor"], want_moved["predictor"]
                adam = _adam(want_states[group])._replace(nu=_adam(want_states[group]).nu["predictor"])
            else:
                adam = _adam(want_states[group])
            _check_steps(moved, want_moved, adam, lr, what + " step")
            assert _norm(moved) > 0
        # grad_norm: the mean over the update's steps of the policy gradient's norm before clipping
        want_norm = np.mean([_norm(g) for actor in grads["policy"] for g in actor])
        np.testing.assert_allclose(float(info["grad_norm"]), want_norm, rtol=1e-5)


def test_pieces_and_their_weights():
    """A step that ends an episode is its piece's last; each of a piece's L steps weighs 20 / L,
    whatever T is."""
    done = jnp.array([[0, 0, 1], [1, 0, 0], [0, 0, 1], [0, 1, 0], [1, 0, 1]], jnp.float32)  # T = 5, N = 3
    np.testing.assert_array_equal(a3c.pieces(done), [[0, 0, 0], [0, 0, 1], [1, 0, 1], [1, 0, 2], [1, 1, 2]])
    assert [[len(p) for p in actor] for actor in hand_pieces(done)] == [[2, 3], [4, 1], [1, 2, 2]]
    np.testing.assert_allclose(a3c.piece_weights(a3c.pieces(done), 1),
                               [[0, 0, 0], [0, 0, 10], [20 / 3, 0, 10], [20 / 3, 0, 0], [20 / 3, 20, 0]], rtol=1e-6)
    np.testing.assert_array_equal(a3c.piece_weights(a3c.pieces(done), 3), np.zeros((5, 3)))


def test_apply_in_order_steps_each_active_actor_once_on_the_one_state():
    txs = {"w": optax.GradientTransformation(lambda p: jnp.zeros(()),
                                             lambda g, s, p: (jax.tree.map(jnp.subtract, g, p), 10 * s + g.sum()))}
    params = {"w": jnp.zeros(2), "frozen": jnp.ones(3)}
    grads = {"w": jnp.array([[1.0, 1.0], [2.0, 2.0], [3.0, 3.0], [4.0, 4.0]])}
    active = jnp.array([True, True, True, False])
    got, got_states = a3c.apply_in_order(txs, params, {"w": jnp.zeros(())}, grads, jnp.array([2, 3, 0, 1]), active)
    np.testing.assert_array_equal(got["w"], [2.0, 2.0])  # actor 1's, applied last (3 takes no step)
    np.testing.assert_array_equal(got["frozen"], [1.0, 1.0, 1.0])  # a group without an optimiser stays
    # one state, stepped by actor 2 (6), then 0 (10 * 6 + 2), then 1 (10 * 62 + 4): in that order
    np.testing.assert_array_equal(got_states["w"], 624.0)


def test_a2c_loss_with_step_weights_is_the_weighted_sum_of_its_steps():
    config = TrainConfig(env="maze-tiny", gamma=0.5)
    traj, bonus = _episodes([0, 1, 0, 0], [0.5, 0.5, -3, 0.25])
    args = (None, _FixedValues(), None, traj, jnp.zeros((1, 2)), jnp.zeros(1, bool), bonus, config)
    mean, info = a2c_loss(*args)
    uniform, info_w = a2c_loss(*args, step_weights=jnp.full((4, 1), 0.25))
    np.testing.assert_allclose(uniform, mean, rtol=1e-6)
    assert info_w == info  # the logged terms are the plain means
    first, _ = a2c_loss(*args, step_weights=jnp.array([[1.0], [0], [0], [0]]))
    # step 0 alone: r = [0.5, 1.5, ...], G_0 = 0.5 + 0.5 * 1.5 (the goal ends step 1), V(o_0) = 10,
    # a uniform policy over 4 actions
    error = 1.25 - 10.0
    np.testing.assert_allclose(first, np.log(4) * error + 0.5 * error**2 - 0.01 * np.log(4), rtol=1e-6)


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
    """Its checkpoint holds the one Adam state per group, with one count per seed."""
    config = TrainConfig(env="maze-tiny", learner="a3c", num_envs=2, rollout_len=2, total_steps=12, log_every=4)
    runs.run(config, tmp_path / "whole", quiet=True)

    def stop_after_first(self, *args):
        raise KeyboardInterrupt

    with monkeypatch.context() as m:
        m.setattr(Progress, "update", stop_after_first)
        runs.run(config, tmp_path / "parts", quiet=True)
    adam = runs.load_checkpoint(tmp_path / "parts")["runner"]["opt_state"]["policy"]["1"]["0"]
    assert adam["count"].shape == (1,) and adam["count"][0] >= 2  # seeds; at least one step per actor
    kernel = adam["mu"]["params"]["Dense_0"]["kernel"]
    assert kernel.shape == (1, 256, 4)  # seeds x the params' shape: no actor axis
    runs.run(runs.load_config(tmp_path / "parts"), tmp_path / "parts", quiet=True, resume=True)
    same = [c for c in runs.METRIC_COLUMNS if c not in ("steps_per_s", "wall_s")]
    rows = [list(csv.DictReader(open(tmp_path / d / "metrics.csv"))) for d in ("whole", "parts")]
    assert len(rows[0]) == len(rows[1]) == 3
    assert [[r[c] for c in same] for r in rows[0]] == [[r[c] for c in same] for r in rows[1]]


def test_the_a3c_run_committed_before_the_shared_adam_still_loads_its_config():
    """experiments/results/learner-a3c-tiny/a3c-per-actor-adam ran with an Adam per actor (no
    checkpoint is committed); its config.json reads as today's a3c config."""
    from pathlib import Path

    folder = Path(__file__).resolve().parents[1] / "experiments/results/learner-a3c-tiny/a3c-per-actor-adam"
    config = runs.load_config(folder)
    assert (config.learner, config.num_envs, config.learning_rate, config.max_grad_norm) == ("a3c", 16, 1e-4, 40.0)
