"""E3B (``simjax.novelty.e3b``): the inverse covariance against float64 linear algebra, its reset
at episode ends, what pays and what does not, a rollout cut in two against the whole, and a
run through the command line that stops and resumes as the whole run."""

import csv

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import random_rollout

from simjax import runs, runtime
from simjax import train as cli
from simjax.agents import TrainConfig
from simjax.envs import make
from simjax.novelty import E3B, Novelty, NoveltySettings
from simjax.novelty.e3b import FEATURES, RIDGE, E3BState, scan_elliptical
from simjax.novelty.models import grey_stacks
from simjax.runs.grid import check_sweep
from simjax.runs.progress import Progress

A = 4
D = FEATURES
U = 2.0**-24  # float32's unit roundoff


def _features(key, k, d=D, scale=0.05):
    """k random feature vectors (k, d), of the squared norm E3B's encoder gives at init (~0.3-0.7)."""
    return scale * jax.random.normal(key, (k, d), jnp.float32)


def _inverse64(lam, phis):
    d = phis.shape[-1]
    phis = np.asarray(phis, np.float64)
    return np.linalg.inv(lam * np.eye(d) + phis.T @ phis)


@pytest.fixture(scope="module")
def scan_one():
    """``scan_elliptical`` for one environment, jitted once: (C^-1 (D, D), phi (T, D), starts (T,))."""

    @jax.jit
    def run(cov, phi, starts):
        state, bonus = scan_elliptical(E3BState(cov[None]), phi[:, None], starts[:, None])
        return state.cov_inverse[0], bonus[:, 0]

    return run


def _fresh(d=D):
    return jnp.eye(d, dtype=jnp.float32) / RIDGE


def test_cov_inverse_is_the_inverse_of_the_episodes_covariance(scan_one):
    """After k frames, C^-1 is (lambda I + sum phi phi^T)^-1 and each bonus phi^T C^-1 phi under
    the frames before it, both against float64. Each Sherman-Morrison step is a length-D matrix-
    vector product, a length-D dot and a rank-1 update: under gamma_D = D u of rounding per step,
    k steps stay under k (2 D + 4) u relative to ||C^-1|| (whose norm is 1/lambda); a step that
    dropped the 1 + b, or subtracted u u^T / b, is off by O(1)."""
    k = 24
    phi = _features(jax.random.PRNGKey(0), k)
    starts = jnp.zeros((k,), bool).at[0].set(True)
    cov, bonus = scan_one(_fresh(), phi, starts)
    chex.assert_type([cov, bonus], jnp.float32)
    phi, bonus = np.asarray(phi, np.float64), np.asarray(bonus)  # the reference in float64, on the host
    want = _inverse64(RIDGE, phi)
    bound = k * (2 * D + 4) * U
    err = np.linalg.norm(np.asarray(cov, np.float64) - want, 2) / np.linalg.norm(want, 2)
    assert err <= bound, (err, bound)
    # each frame's bonus, under the episode's frames before it (the first pays nothing)
    b64 = [0.0] + [float(phi[t] @ _inverse64(RIDGE, phi[:t]) @ phi[t]) for t in range(1, k)]
    scale = float(np.max(np.sum(phi**2, -1))) / RIDGE  # b <= |phi|^2 / lambda
    np.testing.assert_allclose(np.asarray(bonus, np.float64), b64, rtol=0, atol=bound * scale)
    assert bonus[0] == 0.0 and np.all(bonus[1:] > 0)


def test_an_episode_start_resets_the_covariance_and_pays_nothing(scan_one):
    """A frame that starts an episode: C^-1 = I / lambda before it is folded in, its bonus 0;
    the next frame pays as it would in a fresh episode, whatever came before the start."""
    k = 10
    phi = _features(jax.random.PRNGKey(1), k)
    starts = jnp.zeros((k,), bool).at[0].set(True).at[6].set(True)
    cov, bonus = scan_one(_fresh(), phi, starts)
    alone_cov, alone = scan_one(_fresh(), phi[6:], starts[6:])  # the second episode by itself
    assert bonus[6] == 0.0 and bonus[0] == 0.0 and float(bonus[5]) > 0
    np.testing.assert_allclose(bonus[6:], alone, rtol=1e-6)
    np.testing.assert_allclose(cov, alone_cov, rtol=0, atol=1e-6 / RIDGE)
    want = _inverse64(RIDGE, phi[6:])
    assert np.linalg.norm(np.asarray(cov, np.float64) - want, 2) <= 4 * (2 * D + 4) * U / RIDGE


def test_a_feature_seen_again_pays_less_and_a_new_direction_pays_as_at_the_start(scan_one):
    """b of a repeat of phi falls from |phi|^2 / lambda to |phi|^2 / (lambda + |phi|^2); a phi
    orthogonal to every feature seen pays |phi|^2 / lambda, as the episode's first would."""
    phi1, phi2 = _features(jax.random.PRNGKey(2), 2)
    phi2 = phi2 - (phi2 @ phi1) / (phi1 @ phi1) * phi1  # orthogonal to phi1
    seq = jnp.stack([phi1, phi1, phi1, phi2])
    starts = jnp.array([True, False, False, False])
    _, bonus = scan_one(_fresh(), seq, starts)
    n1, n2 = float(phi1 @ phi1), float(phi2 @ phi2)
    np.testing.assert_allclose(bonus[1], n1 / (RIDGE + n1), rtol=1e-5)  # seen once
    np.testing.assert_allclose(bonus[2], n1 / (RIDGE + 2 * n1), rtol=1e-5)  # seen twice
    assert float(bonus[2]) < float(bonus[1]) < 0.25 * n1 / RIDGE
    np.testing.assert_allclose(bonus[3], n2 / RIDGE, rtol=1e-5)  # a new direction: as at the start


# ------------------------------------------------------------------------- through Novelty

@pytest.fixture(scope="module")
def rollout():
    """A random-action rollout of maze-tiny, T=8, N=2, with an episode start at t=5 in env 0."""
    obs, reset, actions, last_obs, last_reset = random_rollout(make("maze-tiny"), jax.random.PRNGKey(0), T=8, N=2)
    return obs, reset.at[5, 0].set(True), actions, last_obs, last_reset


@pytest.fixture(scope="module")
def e3b(rollout):
    novelty = Novelty(model=E3B(A), bonus_scale=0.5)
    params, state = jax.jit(novelty.init)(jax.random.PRNGKey(0), rollout[0][0])
    return novelty, params, state, jax.jit(novelty.loss_and_bonus)


@pytest.mark.xdist_group("e3b_tiny")
def test_shapes_dtypes_and_the_first_frames_covariance(rollout, e3b):
    novelty, params, state, loss_and_bonus = e3b
    obs = rollout[0]
    T, N = rollout[2].shape
    chex.assert_shape(state.model.cov_inverse, (N, D, D))
    chex.assert_type(state.model.cov_inverse, jnp.float32)
    phi0 = np.asarray(jax.jit(lambda p, o: novelty.model.features(p, novelty.model.first_stacks(o)))(params, obs[0]))
    cov = np.asarray(state.model.cov_inverse, np.float64)
    for n in range(N):  # the first frame is in every environment's C from the start
        want = _inverse64(RIDGE, phi0[n : n + 1])
        assert np.linalg.norm(cov[n] - want, 2) <= (2 * D + 4) * U / RIDGE
    loss, (bonus, metrics, new_state) = loss_and_bonus(params, state, *rollout)
    chex.assert_shape(bonus, (T, N))
    chex.assert_type([bonus, loss], jnp.float32)
    chex.assert_tree_all_finite((loss, bonus, metrics, new_state))
    chex.assert_trees_all_equal_shapes_and_dtypes(state, new_state)
    assert np.asarray(bonus)[4, 0] == 0.0  # o_5 starts an episode: the transition into it pays nothing
    # transition t pays for the frame it reaches, o_{t+1}, against its episode's o_0 ... o_t
    def features_and_segments(p, state, *rollout):
        tl = novelty.prepare(state, *rollout).timeline
        return novelty.model.features(p, grey_stacks(tl, 4)), tl.segment[tl.history :]  # of o_0 ... o_T

    phi, segment = jax.jit(features_and_segments)(params, state, *rollout)
    phi, segment, bonus = np.asarray(phi, np.float64), np.asarray(segment), np.asarray(bonus)
    for n in range(N):
        for t in range(T):
            seen = phi[: t + 1, n][segment[: t + 1, n] == segment[t + 1, n]]
            want = 0.0 if not len(seen) else phi[t + 1, n] @ _inverse64(RIDGE, seen) @ phi[t + 1, n]
            assert abs(float(bonus[t, n]) / 0.5 - want) <= (t + 2) * (2 * D + 4) * U * (phi[t + 1, n] @ phi[t + 1, n]) / RIDGE
    assert bonus.min() >= 0.0 and bonus.max() > 0.0
    assert float(metrics["forward_loss"]) == 0.0 and float(metrics["inverse_loss"]) > 0.0
    # the loss trains the encoder and the inverse head; the bonus carries no gradient
    grads = jax.jit(jax.grad(lambda p: loss_and_bonus(p, state, *rollout)[0]))(params)
    assert all(np.abs(g).max() > 0 for g in jax.tree.leaves(jax.device_get(grads)))
    bonus_grads = jax.jit(jax.grad(lambda p: jnp.sum(novelty.loss_and_bonus(p, state, *rollout)[1][0])))(params)
    assert all(np.abs(g).max() == 0.0 for g in jax.tree.leaves(jax.device_get(bonus_grads)))


@pytest.mark.xdist_group("e3b_tiny")
def test_one_rollout_equals_the_same_steps_cut_in_two(rollout, e3b):
    """Two rollouts of 4 steps, the state carried between them, give the 8-step rollout's bonus
    and covariance. The encoder sees batches of other sizes, so its float32 sums may round apart
    (each feature a sum of 3 x 3 x 32 products: 288 u relative); 1e-4 covers that through the
    bonus's few steps of C^-1."""
    novelty, params, state, loss_and_bonus = e3b
    obs, reset, actions, last_obs, last_reset = rollout
    _, (whole, _, after) = loss_and_bonus(params, state, *rollout)
    part = jax.jit(novelty.loss_and_bonus)
    _, (first, _, mid) = part(params, state, obs[:4], reset[:4], actions[:4], obs[4], reset[4])
    _, (second, _, end) = part(params, mid, obs[4:], reset[4:], actions[4:], last_obs, last_reset)
    np.testing.assert_allclose(jnp.concatenate([first, second]), whole, rtol=1e-4, atol=1e-7)
    np.testing.assert_allclose(end.model.cov_inverse, after.model.cov_inverse, rtol=0, atol=1e-4 / RIDGE)
    chex.assert_trees_all_equal(end.memory, after.memory)


@pytest.mark.xdist_group("e3b_tiny")
def test_a3c_pieces_take_the_loss_of_their_transitions(rollout, e3b):
    """A3C's pieces (``targets``): the loss of all of them is the whole loss, of none is 0, and
    the bonus and state do not depend on them."""
    novelty, params, state, _ = e3b
    prepared = novelty.prepare(state, *rollout)

    @jax.jit
    def loss(targets):
        value, (error, _, _, model_state) = novelty.model_loss(params, state.model, prepared, targets=targets)
        return value, error, model_state

    whole = jax.jit(lambda: novelty.model_loss(params, state.model, prepared))()
    every, error, model_state = loss(jnp.ones(rollout[1].shape, bool))
    np.testing.assert_allclose(every, whole[0], rtol=1e-6)
    chex.assert_trees_all_close((error, model_state), (whole[1][0], whole[1][3]), rtol=1e-6)
    early = jnp.zeros(rollout[1].shape, bool).at[:3].set(True)
    assert float(loss(jnp.zeros(rollout[1].shape, bool))[0]) == 0.0
    assert float(loss(early)[0]) != float(every)


def test_the_covariance_stays_float32_under_bfloat16():
    """--precision bfloat16 rounds the encoder's products, never C^-1's: the state comes back
    float32 and equal to what float32 arithmetic gives for the same features."""
    phi = _features(jax.random.PRNGKey(3), 12)
    starts = jnp.zeros((12,), bool).at[0].set(True)
    run = jax.jit(lambda p: scan_elliptical(E3BState(_fresh()[None]), p[:, None], starts[:, None]))
    plain = run(phi)
    with runtime.matmul_precision("bfloat16"):
        rounded = jax.jit(lambda p: scan_elliptical(E3BState(_fresh()[None]), p[:, None], starts[:, None]))(phi)
    chex.assert_type(rounded[0].cov_inverse, jnp.float32)
    chex.assert_trees_all_equal(rounded, plain)  # the same float32 program: bfloat16 operands would round


# ----------------------------------------------------------------------------- configuration

def test_config_and_flags():
    config = TrainConfig(algo="e3b")
    assert config.bonus_scale == 1e-6 and config.novelty.e3b_ridge == RIDGE
    assert TrainConfig(algo="e3b", e3b_ridge=0.5).novelty.e3b_ridge == 0.5
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="--e3b-ridge"):
            TrainConfig(algo="e3b", e3b_ridge=bad)
    with pytest.raises(ValueError, match="--e3b-ridge"):
        NoveltySettings(algo="e3b", e3b_ridge=0.0)
    with pytest.raises(ValueError, match="sweeping --forward-weight changes nothing for --algo e3b"):
        check_sweep(dict(env="maze-tiny", algo="e3b"), {"forward_weight": [0.1, 0.2]})
    config, grid = check_sweep(dict(env="maze-tiny", algo="e3b"), {"bonus_scale": [1e-6, 1e-5]})
    assert [p["bonus_scale"] for p in grid] == [1e-6, 1e-5]
    assert "e3b" in cli.build_parser().format_help()


def test_train_e3b_end_to_end_and_a_stopped_run_resumes_as_the_whole(tmp_path, monkeypatch):
    """``python -m simjax.train --algo e3b`` on maze-tiny: rows with a bonus, the covariances in
    the checkpoint; the same run stopped after its first row and resumed is the whole run."""
    flags = ["--algo", "e3b", "--env", "maze-tiny", "--num-envs", "2", "--rollout-len", "4", "--total-steps", "48",
             "--log-every", "16", "--bonus-scale", "0.01", "--quiet"]
    whole, parts = tmp_path / "whole", tmp_path / "parts"
    assert cli.main([*flags, "--out", str(whole)]) == 0
    rows = list(csv.DictReader(open(whole / "metrics.csv")))
    assert [int(r["env_steps"]) for r in rows] == [16, 32, 48]
    assert all(float(r["bonus_mean"]) > 0 and float(r["inverse_loss"]) > 0 for r in rows)
    ckpt = runs.load_checkpoint(whole)
    cov = np.asarray(ckpt["runner"]["novelty"]["model"]["cov_inverse"])
    assert cov.shape == (1, 2, D, D) and cov.dtype == np.float32  # (seed, env, D, D)

    def stop_after_first(self, *args):
        raise KeyboardInterrupt

    with monkeypatch.context() as m:
        m.setattr(Progress, "update", stop_after_first)
        cli.main([*flags, "--out", str(parts)])
    assert runs.load_checkpoint(parts)["env_steps"] == 16
    assert len(list(csv.reader(open(parts / "metrics.csv")))) == 2  # header + the first row
    assert cli.main(["--resume", str(parts), "--quiet"]) == 0
    same = [c for c in runs.METRIC_COLUMNS if c not in ("steps_per_s", "wall_s")]
    a, b = ([[r[c] for c in same] for r in csv.DictReader(open(d / "metrics.csv"))] for d in (whole, parts))
    assert a == b
    chex.assert_trees_all_equal(runs.load_checkpoint(parts)["runner"], ckpt["runner"])
