"""The gymnax adapter: any gymnax environment through the same learner."""

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import walk

from simjax import train as cli
from simjax.agents import TrainConfig, make_trainer, summarize
from simjax.envs import check_name, make
from simjax.envs.gymnax_adapter import GymnaxEnv


@pytest.mark.parametrize("name,shape,actions", [("CartPole-v1", (4,), 2), ("Breakout-MinAtar", (10, 10, 4), 3),
                                               ("Catch-bsuite", (10, 5, 1), 3)])
def test_adapter_shapes_dtypes_and_determinism(name, shape, actions):
    env = make("gymnax:" + name)
    assert env.observation_size == shape and env.action_size == actions
    keys = jax.random.split(jax.random.PRNGKey(0), 4)
    reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
    s = reset(keys)
    chex.assert_shape(s.obs, (4,) + shape)
    chex.assert_type(s.obs, jnp.float32)
    s2 = step(s, jnp.array([0, 1, 1, 0]))
    chex.assert_shape([s2.reward, s2.done, s2.info["truncation"]], (4,))
    chex.assert_type([s2.reward, s2.done, s2.info["truncation"]], jnp.float32)
    chex.assert_tree_all_finite(s2.obs)
    chex.assert_trees_all_equal(s2, step(reset(keys), jnp.array([0, 1, 1, 0])))
    other = reset(jax.random.split(jax.random.PRNGKey(1), 4))
    assert not np.array_equal(np.asarray(other.obs), np.asarray(s.obs))


def test_frames_without_a_channel_axis_are_one_channel_images():
    """bsuite's Catch and DeepSea give (H, W) frames; the learner's networks read (H, W, C).
    (FrozenLake's scalar cell index becomes a vector of one.)"""
    assert make("gymnax:DeepSea-bsuite").observation_size == (8, 8, 1)
    frozen = make("gymnax:FrozenLake-misc")
    assert frozen.observation_size == (1,)
    chex.assert_shape(frozen.step(frozen.reset(jax.random.PRNGKey(0)), jnp.int32(1)).obs, (1,))
    config = TrainConfig(env="gymnax:Catch-bsuite", num_envs=4, rollout_len=5, total_steps=20, log_every=20)
    trainer = make_trainer(config)
    after, metrics = jax.jit(trainer.run_chunk)(jax.jit(trainer.init)(jax.random.PRNGKey(0)))
    chex.assert_tree_all_finite((after.params, metrics))
    assert "PatchConv_0" in after.params["policy"]["params"]["Encoder_0"]  # read as an image


def test_adapter_auto_resets_and_marks_truncation_and_termination():
    # a 5-step time limit: alternating pushes keep the pole up that long, so every end is a truncation
    env = GymnaxEnv("CartPole-v1", max_steps_in_episode=5)
    states = jax.jit(lambda k, a: walk(env, k, a))(jax.random.PRNGKey(0), jnp.tile(jnp.array([0, 1]), 10))
    done = np.asarray(states.done)
    assert np.flatnonzero(done).tolist() == [4, 9, 14, 19]
    assert (np.asarray(states.info["truncation"])[done > 0] == 1).all()
    assert (np.asarray(states.metrics["episode_length"])[done > 0] == 5).all()
    assert (np.asarray(states.metrics["episode_return"])[done > 0] == 5).all()
    assert int(states.pipeline_state.steps[4]) == 0  # the state after an end is a new episode's
    # pushing one way only topples the pole: a termination, not a truncation
    states = jax.jit(lambda k, a: walk(GymnaxEnv("CartPole-v1"), k, a))(jax.random.PRNGKey(0), jnp.ones(60, jnp.int32))
    done = np.asarray(states.done)
    t = int(np.argmax(done))
    assert done[t] == 1 and 5 < t < 40 and states.info["truncation"][t] == 0
    assert states.metrics["episode_length"][t] == t + 1


def test_unknown_or_continuous_gymnax_envs_are_clear_errors(capsys, monkeypatch):
    with pytest.raises(ValueError, match="unknown gymnax environment 'Nope-v0'; gymnax knows: CartPole-v1"):
        check_name("gymnax:Nope-v0")
    with pytest.raises(ValueError, match="action space"):
        make("gymnax:Pendulum-v1")
    with pytest.raises(ValueError, match="or gymnax:NAME"):
        check_name("cartpole")
    # on the command line: argparse's one-line refusal, before anything is written or compiled
    monkeypatch.setattr(cli, "run", lambda *a, **k: pytest.fail("must not start a run"))
    with pytest.raises(SystemExit) as err:
        cli.main(["--env", "gymnax:Pendulum-v1", "--out", "/nonexistent/run"])
    assert err.value.code == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines[-1].startswith("python -m simjax.train: error: gymnax:Pendulum-v1 has a Box action space")
    assert not any("Traceback" in line for line in lines)


def test_novelty_models_refuse_observations_they_cannot_read(capsys):
    """Checked where the env is built (the learner), which the command line does before
    anything is written or compiled."""
    with pytest.raises(ValueError, match=r"--algo sim reads image observations .* gives shape \(4,\)"):
        make_trainer(TrainConfig(env="gymnax:CartPole-v1", algo="sim"))
    with pytest.raises(ValueError, match="RND target needs frames of at least 36x36"):
        make_trainer(TrainConfig(env="gymnax:Breakout-MinAtar", algo="rnd"))
    with pytest.raises(SystemExit):
        cli.parse_config(["--env", "gymnax:Breakout-MinAtar", "--algo", "sim"])
    assert "--sim-target embed" in capsys.readouterr().err
    make_trainer(TrainConfig(env="gymnax:Breakout-MinAtar", algo="sim", sim_target="embed"))  # these fit
    make_trainer(TrainConfig(env="gymnax:Breakout-MinAtar", algo="icm"))


@pytest.mark.parametrize("algo,extra", [("icm", {}), ("sim", {"sim_target": "embed", "obs_len": 3, "act_len": 2})])
def test_novelty_learners_run_on_minatar_frames(algo, extra):
    config = TrainConfig(env="gymnax:Breakout-MinAtar", algo=algo, num_envs=4, rollout_len=5, total_steps=40,
                         log_every=20, **extra)
    trainer = make_trainer(config)
    runner = jax.jit(trainer.init)(jax.random.PRNGKey(0))
    after, metrics = jax.jit(trainer.run_chunk)(runner)
    chex.assert_tree_all_finite((after.params, metrics))
    assert float(jnp.mean(metrics["bonus_mean"])) > 0
    assert not np.allclose(jax.tree.leaves(after.params["novelty"])[0], jax.tree.leaves(runner.params["novelty"])[0])


def test_a2c_on_cartpole_beats_the_random_policy_clearly():
    env = make("gymnax:CartPole-v1")
    step = jax.vmap(env.step)

    def random_body(s, k):
        s = step(s, jax.random.randint(k, (64,), 0, 2))
        return s, (s.metrics["episode_done"], s.metrics["episode_return"])

    s0 = jax.vmap(env.reset)(jax.random.split(jax.random.PRNGKey(0), 64))
    _, (done, ret) = jax.jit(lambda s: jax.lax.scan(random_body, s, jax.random.split(jax.random.PRNGKey(1), 500)))(s0)
    random_return = float(jnp.sum(ret * done) / jnp.sum(done))
    assert 15 < random_return < 30  # CartPole's random policy: about 22

    config = TrainConfig(env="gymnax:CartPole-v1", num_envs=16, rollout_len=20, total_steps=96_000,
                         log_every=32_000, learning_rate=1e-3)
    trainer = make_trainer(config)
    runner = jax.jit(trainer.init)(jax.random.PRNGKey(0))
    chunk = jax.jit(lambda r: (lambda out: (out[0], summarize(out[1])))(trainer.run_chunk(r)))
    for _ in range(config.num_logs):
        runner, metrics = chunk(runner)
    final = float(metrics["mean_extrinsic_return"])
    assert final > 2.5 * random_return, (final, random_return)
