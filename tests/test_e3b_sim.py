"""E3B x SIM (``simjax.novelty.e3b_sim``, ``--algo e3b-sim``): the running statistics of SIM's
error against float64, and the bonus as NGU's product of E3B's episodic bonus and SIM's error,
normalised and clipped to [1, 5], against the two models run on their own."""

import csv

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import random_rollout

from simjax import runs
from simjax import train as cli
from simjax.agents import TrainConfig
from simjax.envs import make
from simjax.novelty import E3B, E3BSIM, SIM, Novelty, NoveltySettings, RunningMeanStd, check_observation
from simjax.novelty.e3b import E3BState
from simjax.novelty.e3b_sim import CLIP, multiplier
from simjax.runs.grid import check_sweep

A = 4
U = 2.0**-24  # float32's unit roundoff


def test_running_statistics_are_those_of_every_scored_error_so_far():
    """Three masked batches folded in one after another give the mean and variance of all their
    masked samples together (float64); a batch with nothing scored changes nothing. Each batch's
    mean and variance are sums of at most 24 float32 terms (relative error under 24 u each), and
    the parallel update adds a few roundings a batch: 1e-5 relative is 100x that."""
    rng = np.random.default_rng(0)
    batches = [rng.gamma(2.0, 0.3, (8, 3)).astype(np.float32) for _ in range(3)]
    masks = [rng.random((8, 3)) < 0.7 for _ in range(3)]
    masks[1][:] = False  # a rollout in which SIM scores nothing
    fold = jax.jit(RunningMeanStd.update)
    stats = RunningMeanStd.create()
    for x, m in zip(batches, masks):
        before = stats
        stats = fold(stats, x, m)
        if not m.any():
            chex.assert_trees_all_equal(stats, before)
    mean, var, count = stats
    every = np.concatenate([x[m] for x, m in zip(batches, masks)]).astype(np.float64)
    assert float(count) == len(every)
    np.testing.assert_allclose(float(mean), every.mean(), rtol=1e-5)
    np.testing.assert_allclose(float(var), every.var(), rtol=1e-5)


def test_the_multiplier_is_ngus_alpha_clipped_to_one_and_five():
    e = jnp.array([0.0, 1.0, 2.0, 3.0, 100.0])
    np.testing.assert_allclose(multiplier(e, 1.0, 4.0), [1.0, 1.0, 1.5, 2.0, CLIP], rtol=1e-6)


@pytest.fixture(scope="module")
def combined():
    """maze-tiny, T=8, N=2, an episode start at t=5 in env 0; SIM at H=3, L=2."""
    obs, reset, actions, last_obs, last_reset = random_rollout(make("maze-tiny"), jax.random.PRNGKey(0), T=8, N=2)
    rollout = (obs, reset.at[5, 0].set(True), actions, last_obs, last_reset)
    model = E3BSIM(E3B(A), SIM(A, obs_len=3, act_len=2))
    novelty = Novelty(model=model, bonus_scale=0.5)
    params, state = jax.jit(novelty.init)(jax.random.PRNGKey(0), obs[0])

    @jax.jit
    def run(params, state, *rollout):
        """The combination, and its two models on their own on the same timeline and frames."""
        loss, (bonus, metrics, new_state) = novelty.loss_and_bonus(params, state, *rollout)
        prepared = novelty.prepare(state, *rollout)
        tl, x = prepared.timeline, novelty._frames(prepared.timeline, prepared.obs_stats)
        b, _, e3b_loss, _, _ = model.e3b.apply_with_state(params["e3b"], E3BState(state.model.cov_inverse), tl, x)
        error, sim_scored, sim_loss, _ = model.sim.apply(params["sim"], tl, x)
        return (loss, bonus, metrics, new_state), (b, e3b_loss, error, sim_scored, sim_loss)

    return novelty, params, state, rollout, run


def test_the_bonus_is_e3bs_times_sims_normalised_clipped_error(combined):
    novelty, params, state, rollout, run = combined
    T, N = rollout[2].shape
    (loss, bonus, metrics, new_state), alone = run(params, state, *rollout)
    chex.assert_shape(bonus, (T, N))
    chex.assert_type([bonus, loss], jnp.float32)
    chex.assert_tree_all_finite((loss, bonus, metrics, new_state))
    chex.assert_trees_all_equal_shapes_and_dtypes(state, new_state)
    b, e3b_loss, error, sim_scored, sim_loss = (np.asarray(a, np.float64) for a in alone)
    sim_scored = sim_scored.astype(bool)
    # the first rollout: the statistics are those of its own scored errors
    mu, var = error[sim_scored].mean(), error[sim_scored].var()
    alpha = np.where(sim_scored, np.clip(1 + (error - mu) / np.sqrt(var + 1e-8), 1.0, CLIP), 1.0)
    # the two models' float32 programs are compiled apart from the combination's: 1e-5 relative
    # is far above their sums' rounding (each a few hundred terms: 300 u = 2e-5 at worst per
    # sum, far less in the mean), and alpha's normalisation multiplies it by at most |e - mu| / sigma
    np.testing.assert_allclose(np.asarray(bonus, np.float64), 0.5 * b * alpha, rtol=1e-4, atol=1e-9)
    np.testing.assert_allclose(float(loss), sim_loss + e3b_loss, rtol=1e-5)
    for n in range(N):
        np.testing.assert_allclose(float(new_state.model.error_mean[n]), mu, rtol=1e-5)
        np.testing.assert_allclose(float(new_state.model.error_var[n]), var, rtol=1e-4)
        assert float(new_state.model.error_count[n]) == sim_scored.sum()
    # what the comparison covers: transitions SIM does not score pay E3B's bonus alone, others
    # pay more where SIM's error is above its mean, and E3B's zero at an episode start stays zero
    paying = b > 0
    assert np.any(paying & ~sim_scored) and np.any(paying & (alpha > 1.0)) and np.any(paying & sim_scored & (alpha == 1.0))
    assert float(bonus[4, 0]) == 0.0  # o_5 starts an episode
    ratio = np.asarray(bonus, np.float64)[paying] / (0.5 * b[paying])
    assert ratio.min() >= 1.0 - 1e-4 and ratio.max() <= CLIP * (1 + 1e-4)
    # the loss trains both models (all but SIM's fixed target), the bonus carries no gradient
    grads = jax.device_get(jax.jit(jax.grad(lambda p: novelty.loss_and_bonus(p, state, *rollout)[0]))(params))
    assert all(np.abs(g).max() > 0 for g in jax.tree.leaves(grads["e3b"]))
    assert all(np.abs(g).max() > 0 for g in jax.tree.leaves(grads["sim"]["sim"]))
    assert all(np.abs(g).max() == 0 for g in jax.tree.leaves(grads["sim"]["target"]))


def test_the_statistics_carry_into_the_next_rollout(combined):
    """The second rollout's statistics fold its errors into the first's (the count adds up) and
    normalise its bonus. The same steps replayed as the second rollout: its windows now reach
    into the first's frames, so SIM scores more of them."""
    novelty, params, state, rollout, run = combined
    (_, _, _, mid), first = run(params, state, *rollout)
    (_, bonus, _, end), alone = run(params, mid, *rollout)
    b, _, error, scored, _ = (np.asarray(a, np.float64) for a in alone)
    scored, scored_first = scored.astype(bool), np.asarray(first[3], bool)
    assert float(end.model.error_count[0]) == scored_first.sum() + scored.sum() > float(mid.model.error_count[0])
    both = np.concatenate([np.asarray(first[2], np.float64)[scored_first], error[scored]])
    np.testing.assert_allclose(float(end.model.error_mean[0]), both.mean(), rtol=1e-5)
    np.testing.assert_allclose(float(end.model.error_var[0]), both.var(), rtol=1e-4)
    alpha = np.where(scored, np.clip(1 + (error - both.mean()) / np.sqrt(both.var() + 1e-8), 1.0, CLIP), 1.0)
    np.testing.assert_allclose(np.asarray(bonus, np.float64), 0.5 * b * alpha, rtol=1e-4, atol=1e-9)


def test_config_and_flags():
    config = TrainConfig(algo="e3b-sim")
    assert config.bonus_scale == 1e-6
    assert config.novelty.uses_rnd_target and not NoveltySettings(algo="e3b-sim", sim_target="embed").uses_rnd_target
    config, grid = check_sweep(dict(env="maze-tiny", algo="e3b-sim"), {"act_len": [1, 3]})  # SIM's L sweeps
    assert [p["act_len"] for p in grid] == [1, 3]
    with pytest.raises(ValueError, match="--algo e3b-sim with --sim-target embed"):
        check_observation(NoveltySettings(algo="e3b-sim"), (16, 16, 3))
    assert "e3b-sim" in cli.build_parser().format_help()


def test_train_e3b_sim_end_to_end(tmp_path):
    """``python -m simjax.train --algo e3b-sim`` on maze-tiny writes rows with a bonus and keeps
    the covariances and the error statistics in its checkpoint."""
    out = tmp_path / "run"
    assert cli.main(["--algo", "e3b-sim", "--env", "maze-tiny", "--num-envs", "2", "--rollout-len", "4",
                     "--total-steps", "32", "--log-every", "16", "--bonus-scale", "0.01", "--obs-len", "3",
                     "--act-len", "2", "--quiet", "--out", str(out)]) == 0
    rows = list(csv.DictReader(open(out / "metrics.csv")))
    assert [int(r["env_steps"]) for r in rows] == [16, 32]
    assert all(float(r["bonus_mean"]) > 0 and float(r["forward_loss"]) > 0 for r in rows)
    model = runs.load_checkpoint(out)["runner"]["novelty"]["model"]
    assert np.asarray(model["cov_inverse"]).shape[:2] == (1, 2)
    assert np.all(np.asarray(model["error_count"]) > 0)
