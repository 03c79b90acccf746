"""The A2C learner, the config, and the train and fork command lines."""

import csv
import dataclasses
import json

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import serialization
from helpers import RND_TINY, one_chunk

from simjax import runs, runtime
from simjax import train as cli
from simjax.agents import TrainConfig, make_trainer, n_step_returns, summarize, total_reward
from simjax.agents.a2c import Transition, a2c_loss
from simjax.envs import make
from simjax.runs import training
from simjax.runs.grid import batch_inputs, grid_of
from simjax.runs.progress import Progress


def test_n_step_returns_by_hand():
    g = 0.5
    rewards = jnp.array([[1.0], [0.0], [2.0], [0.0]])
    dones = jnp.array([[0.0], [1.0], [0.0], [1.0]])
    truncs = jnp.array([[0.0], [0.0], [0.0], [1.0]])  # step 1 terminates, step 3 is cut by time
    values = jnp.array([[10.0], [20.0], [30.0], [40.0], [50.0]])  # V(o_0..o_4)
    got = n_step_returns(rewards, dones, truncs, values, g)
    # t=3: truncation bootstraps from V(o_3) = 40, never from the next episode's V(o_4) = 50
    # t=2: 2 + .5 * 20;  t=1: termination, no bootstrap;  t=0: 1 + .5 * 0
    np.testing.assert_allclose(np.asarray(got)[:, 0], [1.0, 0.0, 12.0, 20.0])
    no_done = n_step_returns(rewards, jnp.zeros_like(dones), jnp.zeros_like(truncs), values, g)
    np.testing.assert_allclose(np.asarray(no_done)[-1, 0], 0.0 + g * 50.0)  # bootstraps V(o_T)


class _FixedValues:
    """A stand-in network for ``a2c_loss``: uniform logits and the given values."""

    def __init__(self, values, num_actions=3):
        self.values, self.num_actions = values, num_actions

    def apply(self, params, carry, obs, reset):
        return carry, jnp.zeros(self.values.shape[:2] + (self.num_actions,)), self.values


def test_a_non_episodic_bonus_return_runs_on_past_the_goal():
    """With bonus_episodic=False the bonus's return crosses the episode end that the task's
    return stops at. A bonus of 1 per step, the goal reached at t = 1: the return at t = 0 is
    2.75 (0.5 task + 2.25 bonus) non-episodic, 2.0 episodic, where the goal ends the bonus too."""
    g, T = 0.5, 3
    traj = Transition(obs=jnp.zeros((T, 1, 2)), reset=jnp.zeros((T, 1), bool), action=jnp.zeros((T, 1), jnp.int32),
                      reward=jnp.array([[0.0], [1.0], [0.0]]), done=jnp.array([[0.0], [1.0], [0.0]]),
                      truncation=jnp.zeros((T, 1)), metrics={})
    bonus = jnp.ones((T, 1))
    v_bonus = jnp.array([0.0, 0.0, 0.0, 4.0])  # only V_b(o_3), the value after the rollout, is not 0
    values = jnp.stack([jnp.zeros(T + 1), v_bonus], -1)[:, None, :]
    config = TrainConfig(env="maze-tiny", algo="rnd", gamma=g, bonus_episodic=False, entropy_coef=0.0)
    _, info = a2c_loss(None, _FixedValues(values), None, traj, jnp.zeros((1, 2)), jnp.zeros(1, bool), bonus, config)
    # G_b = [1 + .5 * 2.5, 1 + .5 * 3, 1 + .5 * 4] = [2.25, 2.5, 3] across the done at t = 1
    # G_e = [.5 * 1, 1, 0] (stops at the done)
    adv = np.array([0.5 + 2.25, 1.0 + 2.5, 0.0 + 3.0])
    np.testing.assert_allclose(info["policy_loss"], np.log(3) * adv.mean(), rtol=1e-6)  # -mean(log(1/3) A)
    np.testing.assert_allclose(info["value_loss"], np.mean([0.25 + 2.25**2, 1 + 2.5**2, 9.0]), rtol=1e-6)
    episodic = dataclasses.replace(config, bonus_episodic=True)
    _, info = a2c_loss(None, _FixedValues(values[..., 1]), None, traj, jnp.zeros((1, 2)), jnp.zeros(1, bool), bonus,
                       episodic)  # one head, rewards [1, 2, 1]: G = [1 + .5 * 2, 2, 1 + .5 * 4]
    np.testing.assert_allclose(info["policy_loss"], np.log(3) * np.mean([2.0, 2.0, 3.0]), rtol=1e-6)
    # RND's code: the task's return discounted on its own (here 0.25) and its advantage weighed 2 : 1
    rnd_code = dataclasses.replace(config, task_gamma=0.25, task_advantage_weight=2.0)
    _, info = a2c_loss(None, _FixedValues(values), None, traj, jnp.zeros((1, 2)), jnp.zeros(1, bool), bonus, rnd_code)
    # G_e = [.25 * 1, 1, 0]; G_b as above (gamma 0.5)
    adv = np.array([2 * 0.25 + 2.25, 2 * 1.0 + 2.5, 2 * 0.0 + 3.0])
    np.testing.assert_allclose(info["policy_loss"], np.log(3) * adv.mean(), rtol=1e-6)
    np.testing.assert_allclose(info["value_loss"], np.mean([0.25**2 + 2.25**2, 1 + 2.5**2, 9.0]), rtol=1e-6)


def test_reward_seam():
    np.testing.assert_allclose(total_reward(2.0, jnp.array([1.0, 0.0]), jnp.array([0.5, 0.25])), [2.5, 0.25])


@pytest.mark.parametrize("bad,match", [
    (dict(env="maze-nope"), "known tasks"),
    (dict(env="maze-very-sparse-flat-SILVER"), "texture names"),
    (dict(algo="ppo"), "known algos"),
    (dict(learning_rate=-1e-4), "--learning-rate"),
    (dict(task_scale=-1.0), "--task-scale"),
    (dict(num_envs=0), "--num-envs"),
    (dict(gamma=1.5), "--gamma"),
    (dict(total_steps=10), "less than one update"),
    (dict(algo="sim", obs_len=1), "--obs-len"),
    (dict(algo="sim", act_len=0), "--act-len"),
    (dict(obs_len=65), "--obs-len"),
    (dict(bonus_scale=-0.1), "--bonus-scale"),
    (dict(sim_combine="sum"), "--sim-combine"),
    (dict(sim_target="pixels"), "--sim-target"),
    (dict(forward_weight=1.5), "--forward-weight"),
    (dict(rl_weight=0.0), "--rl-weight"),
    (dict(algo="a2c", bonus_episodic=False), "--bonus-episodic"),
    (dict(algo="rnd", task_gamma=0.999), "--bonus-episodic false"),
    (dict(algo="rnd", task_advantage_weight=2.0), "--bonus-episodic false"),
    (dict(algo="rnd", bonus_episodic=False, task_gamma=1.5), "--task-gamma"),
    (dict(algo="rnd", bonus_episodic=False, task_advantage_weight=-1.0), "--task-advantage-weight"),
])
def test_config_rejects_bad_values(bad, match):
    with pytest.raises(ValueError, match=match):
        TrainConfig(**bad)


def test_a_config_is_checked_without_building_an_environment(monkeypatch, tmp_path):
    """Configs are made, replaced and loaded often; only the learner builds the task's env."""
    from simjax.envs import gymnax_adapter, maze

    def no_env(*args, **kwargs):
        raise AssertionError("a config built an environment")

    monkeypatch.setattr(maze.MazeEnv, "__init__", no_env)
    monkeypatch.setattr(gymnax_adapter.GymnaxEnv, "__init__", no_env)
    config = TrainConfig(env="maze-very-sparse", algo="sim")
    dataclasses.replace(config, bonus_scale=0.01)
    runs.write_config(tmp_path, config)
    assert runs.load_config(tmp_path) == config
    assert config.novelty.obs_len == config.obs_len and config.novelty.algo == "sim"
    with pytest.raises(AssertionError, match="built an environment"):
        make_trainer(config)


def test_every_stored_run_folder_still_loads():
    from pathlib import Path

    folders = [p.parent for p in Path(__file__).resolve().parent.parent.glob("experiments/results/**/config.json")]
    assert folders
    for folder in folders:
        runs.load_config(folder)


def test_cli_fails_before_compiling(capsys, monkeypatch):
    monkeypatch.setattr(cli, "run", lambda *a, **k: pytest.fail("must not start a run"))
    with pytest.raises(SystemExit) as err:
        cli.main(["--env", "maze-nope"])
    assert err.value.code == 2
    assert "known tasks: maze-dense" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["--task-scale", "-1"])
    assert "--task-scale must be" in capsys.readouterr().err


def test_cli_refuses_to_overwrite_a_run(tmp_path, capsys):
    (tmp_path / "metrics.csv").write_text("env_steps\n")
    with pytest.raises(SystemExit):
        cli.parse_config(["--out", str(tmp_path)])
    assert "already holds a run" in capsys.readouterr().err


def test_cli_flags_cover_every_config_field():
    config, _, _ = cli.parse_config(["--env", "maze-dense", "--num-envs", "8", "--learning-rate", "3e-4",
                                     "--entropy-coef", "0.02", "--num-seeds", "2"])
    assert (config.env, config.num_envs, config.learning_rate, config.entropy_coef, config.num_seeds) == (
        "maze-dense", 8, 3e-4, 0.02, 2)


def _tiny_config(**kw):
    base = dict(env="maze-tiny", num_envs=8, rollout_len=5, total_steps=80, log_every=40, learning_rate=1e-3)
    return TrainConfig(**{**base, **kw})


# two seeds of each learner on the smallest batch that fills SIM's windows (8 steps of 2 envs):
# the tests below share each learner's programs (a2c, rnd, icm), and SIM's with the resumed run
def _small(algo, **kw):
    return _tiny_config(algo=algo, num_envs=2, rollout_len=4, total_steps=16, log_every=16, obs_len=3, act_len=2,
                        **{"num_seeds": 1 if algo == "sim" else 2, **kw})


def test_update_shapes_determinism_and_seeds_vmap():
    config = _small("a2c")
    trainer, runner, after, metrics = one_chunk(config)
    keys, hypers = batch_inputs(config, grid_of({}))
    # each member is what its own init gives (the orthogonal initialisers draw member by member)
    with runtime.matmul_precision(config.precision):
        chex.assert_trees_all_equal(jax.tree.map(lambda x: x[1], runner), jax.jit(trainer.init)(keys[1]))
    chex.assert_shape(runner.env_state.obs, (2, 2, 42, 42, 3))
    chex.assert_shape(runner.carry, ((2, 2, 256), (2, 2, 256)))
    chex.assert_shape(list(metrics.values()), (2,))
    chex.assert_tree_all_finite((after.params, {k: metrics[k] for k in training.FINITE_TERMS}))
    # parameters moved, the two seeds differ, and the same keys give bit-identical results
    assert not np.allclose(jax.tree.leaves(after.params)[0], jax.tree.leaves(runner.params)[0])
    leaf = np.asarray(jax.tree.leaves(after.params)[-1])
    assert not np.allclose(leaf[0], leaf[1])
    _, _, again, metrics2 = one_chunk(config)
    chex.assert_trees_all_equal(after.params, again.params)
    chex.assert_trees_all_equal(metrics, metrics2)


def random_policy_success(env_name, num_envs=64, steps=400, seed=0):
    """Success ratio of the uniform random policy, measured on the same task."""
    env = make(env_name)
    step = jax.vmap(env.step)

    def body(s, k):
        s = step(s, jax.random.randint(k, (num_envs,), 0, env.action_size))
        return s, (s.metrics["episode_done"], s.metrics["episode_success"])

    s0 = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(seed), num_envs))
    _, (done, success) = jax.jit(lambda s: jax.lax.scan(body, s, jax.random.split(jax.random.PRNGKey(seed + 1), steps)))(s0)
    return float(jnp.sum(success * done) / jnp.sum(done))


def test_a2c_learns_the_tiny_task_and_writes_a_run_folder(tmp_path):
    """The whole pipeline through the command line's own run(): A2C beats the random policy."""
    # two seeds and 8 envs each: how soon one seed's policy starts to learn varies (measured at
    # these settings, 14 seed-runs: 0.34-0.94 final success, seed 0 the slowest in both runs of
    # it); at 32 envs and one seed, seeds 0-2 ended at 0.40, 0.33 and 0.18 against a bar of 0.37
    config = TrainConfig(env="maze-tiny", num_envs=8, num_seeds=2, total_steps=120_000, log_every=20_000, learning_rate=1e-3)
    out = runs.run(config, tmp_path / "run", quiet=True)
    rows = list(csv.DictReader(open(out / "metrics.csv")))
    assert len(rows) == 2 * config.num_logs == 12
    for seed in (0, 1):
        mine = [r for r in rows if int(r["seed"]) == seed]
        assert [int(r["env_steps"]) for r in mine] == [20_000 * (i + 1) for i in range(6)]  # 125 updates of 8 x 20
    random_success = random_policy_success("maze-tiny")
    assert 0.05 < random_success < 0.4
    final = np.mean([float(r["success_ratio"]) for r in rows[-4:]])  # both seeds' last two rows
    first_length, last_length = (np.mean([float(r["mean_episode_length"]) for r in part]) for part in (rows[:2], rows[-2:]))
    # measured for seeds 0 and 1 in three runs whose frames differed in their last bits: 0.60-0.66
    # against the random policy's 0.12; episodes of 46-47 steps in the first row, 32-34 in the last
    print(f"final success {final:.3f} (random {random_success:.3f}), episode length {first_length:.1f} -> {last_length:.1f}")
    assert final > random_success + 0.25, (final, random_success)
    assert last_length < first_length - 5, (first_length, last_length)
    # the run folder: config, checkpoint with the trained parameters, learning curve
    saved = json.load(open(out / "config.json"))["config"]
    assert saved["env"] == "maze-tiny" and saved["learning_rate"] == 1e-3
    ckpt = serialization.msgpack_restore((out / "checkpoint.msgpack").read_bytes())
    assert ckpt["env_steps"] == 120_000 and ckpt["seeds"] == [0, 1]
    kernel = ckpt["runner"]["params"]["policy"]["params"]["Encoder_0"]["PatchConv_0"]["kernel"]
    assert kernel.shape == (2, 3, 3, 3, 16)  # leading axis: seeds
    assert (out / "curve.png").stat().st_size > 10_000


@pytest.mark.xdist_group("rnd_tiny_run")  # helpers.RND_TINY: the programs of the fork's source run
def test_a_stopped_run_keeps_what_it_wrote(tmp_path, monkeypatch):
    calls = []

    def stop_after_first(self, *args):
        calls.append(args)
        raise KeyboardInterrupt

    monkeypatch.setattr(Progress, "update", stop_after_first)
    out = runs.run(TrainConfig(**RND_TINY, total_steps=40), tmp_path / "run")
    rows = list(csv.DictReader(open(out / "metrics.csv")))
    assert len(calls) == 1 and [(int(r["env_steps"]), int(r["seed"])) for r in rows] == [(20, 0), (20, 1)]
    ckpt = serialization.msgpack_restore((out / "checkpoint.msgpack").read_bytes())
    assert ckpt["env_steps"] == 20
    assert (out / "curve.png").exists() and not list(out.glob("*.tmp"))


def test_summarize_reports_nan_without_episodes():
    chunk = {k: jnp.float32(0.0) for k in ("episodes", "successes", "length_sum", "return_sum", "policy_loss",
                                           "value_loss", "entropy", "value_mean", "grad_norm",
                                           "bonus_mean", "forward_loss", "inverse_loss")}
    assert np.isnan(summarize(chunk)["success_ratio"])
    chunk.update(episodes=jnp.float32(4.0), successes=jnp.float32(1.0), length_sum=jnp.float32(100.0))
    s = summarize(chunk)
    assert float(s["success_ratio"]) == 0.25 and float(s["mean_episode_length"]) == 25.0


def test_progress_eta_counts_every_seed(capsys):
    # 500 of 1,000 steps per seed left, 2 seeds, 100 steps/s over both: 10 s to go
    Progress(1000, quiet=False, num_seeds=2).update(500, 100.0, 0.5, 300.0)
    line = capsys.readouterr().err
    assert "500/1,000 steps per seed" in line and "ETA 0:00:10" in line


@pytest.mark.parametrize("total,log_every", [(30_000, 25_000), (1_000_000, 25_000), (320, 25_000), (99_999, 7_000)])
def test_run_length_is_close_to_what_was_asked(total, log_every):
    c = TrainConfig(total_steps=total, log_every=log_every)
    trained = c.num_logs * c.updates_per_log * c.steps_per_update
    assert total <= trained < total + c.num_logs * c.steps_per_update
    if total >= log_every:  # rows come about every log_every steps (a shorter run has one row)
        assert abs(c.updates_per_log * c.steps_per_update - log_every) <= log_every / 2
    else:
        assert c.num_logs == 1


def test_bonus_scale_defaults_to_the_papers_per_method():
    assert [TrainConfig(algo=a).bonus_scale for a in ("a2c", "sim", "rnd", "icm")] == [0.0, 0.001, 0.01, 0.01]
    assert TrainConfig(algo="sim", bonus_scale=0.01).bonus_scale == 0.01
    assert TrainConfig(algo="sim").policy_weight == 0.1 and TrainConfig(algo="a2c").policy_weight == 1.0


def test_cli_novelty_flags_and_their_errors(capsys, monkeypatch):
    monkeypatch.setattr(cli, "run", lambda *a, **k: pytest.fail("must not start a run"))
    config, _, _ = cli.parse_config(["--algo", "sim", "--obs-len", "4", "--act-len", "1", "--sim-inverse", "false",
                                     "--sim-combine", "itr", "--bonus-norm", "on"])
    assert (config.obs_len, config.act_len, config.sim_inverse, config.sim_combine, config.bonus_norm) == (
        4, 1, False, "itr", True)
    for bad, message in ((["--algo", "sim", "--act-len", "0"], "--act-len (L) must lie"),
                         (["--sim-inverse", "maybe"], "expected true or false"),
                         (["--bonus-scale", "-1"], "--bonus-scale must be"),
                         (["--resume", "/nonexistent/run"], "not a run folder"),
                         (["--resume", "/nonexistent/run", "--num-envs", "4"], "give no run settings"),
                         (["--resume", "/nonexistent/run", "--out", "elsewhere"], "give no run settings")):
        with pytest.raises(SystemExit) as err:
            cli.main(bad)
        assert err.value.code == 2
        assert message in capsys.readouterr().err


def test_integer_flags_take_whole_numbers_written_as_floats(capsys):
    config, _, _ = cli.parse_config(["--total-steps", "4e6", "--num-envs", "16", "--log-every", "2.5e4"])
    assert (config.total_steps, config.num_envs, config.log_every) == (4_000_000, 16, 25_000)
    assert isinstance(config.total_steps, int)
    for bad in ("2.5", "1e-3", "inf", "many"):
        with pytest.raises(SystemExit):
            cli.parse_config(["--total-steps", bad])
        assert f"expected a whole number such as 4000000 or 4e6, got '{bad}'" in capsys.readouterr().err


def test_a_damaged_checkpoint_is_a_one_line_error_naming_its_file(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(cli, "run", lambda *a, **k: pytest.fail("must not start a run"))
    runs.write_config(tmp_path, TrainConfig(env="maze-tiny"))
    runs.write_checkpoint(tmp_path, {"params": np.zeros((64, 64), np.float32)}, 40, [0])
    assert runs.load_checkpoint(tmp_path)["env_steps"] == 40
    whole = (tmp_path / "checkpoint.msgpack").read_bytes()
    assert b"float32" in whole
    for damaged in (whole[: len(whole) // 2], b"", b"\x05", whole.replace(b"float32", b"zzzat32")):
        (tmp_path / "checkpoint.msgpack").write_bytes(damaged)
        with pytest.raises(SystemExit) as err:
            cli.main(["--resume", str(tmp_path)])
        assert err.value.code == 2
        message = capsys.readouterr().err.strip().splitlines()[-1]
        assert f"{tmp_path / 'checkpoint.msgpack'} is damaged" in message and "Traceback" not in message


@pytest.mark.parametrize("algo", [pytest.param("sim", marks=pytest.mark.xdist_group("sim_tiny_run")), "rnd", "icm"])
def test_novelty_learner_updates_both_parts_and_never_the_target(algo):
    _, runner, after, metrics = one_chunk(_small(algo))  # sim: the resumed-run test's programs
    chex.assert_tree_all_finite((after.params, {k: metrics[k] for k in training.FINITE_TERMS}))
    before_p, after_p = runner.params, after.params
    for part in ("policy", "novelty"):  # both trained by the one optimiser
        moved = [not np.array_equal(a, b) for a, b in zip(jax.tree.leaves(before_p[part]), jax.tree.leaves(after_p[part]))]
        assert sum(moved) > len(moved) // 2, part
    if "target" in before_p["novelty"]:
        chex.assert_trees_all_equal(before_p["novelty"]["target"], after_p["novelty"]["target"])
    assert np.all(metrics["bonus_mean"] > 0.0) and np.all(metrics["forward_loss"] > 0.0)
    assert bool(after.novelty.memory.valid.all())  # 8 steps filled the memory of every env


def test_with_zero_bonus_the_policy_trains_exactly_as_plain_a2c():
    """eq. (8) scales the RL loss by eta; the policy group's clip and Adam epsilon are scaled with
    it, so a novelty learner whose bonus is 0 takes A2C's policy steps (to float rounding)."""
    policies = []
    for algo in ("a2c", "rnd"):  # the programs of the two tests above (the bonus's scale is traced)
        _, runner, after, _ = one_chunk(_small(algo, bonus_scale=0.0))
        policies.append((runner.params["policy"], after.params["policy"]))
    (before, a2c), (rnd_before, rnd) = policies
    chex.assert_trees_all_equal(before, rnd_before)
    moved = jax.tree.map(lambda a, b: float(np.max(np.abs(a - b))), a2c, before)
    assert max(jax.tree.leaves(moved)) > 1e-4  # 2 updates of lr 1e-3 moved the policy
    chex.assert_trees_all_close(a2c, rnd, atol=1e-6, rtol=0)


@pytest.mark.xdist_group("sim_tiny_run")  # its programs are the SIM novelty learner test's
def test_a_resumed_run_is_the_run_it_would_have_been(tmp_path, monkeypatch):
    """Stopped by Ctrl-C between checkpoints (it saves then), or killed with rows written after
    its last checkpoint (they are dropped and trained again): resumed, it is the whole run."""
    import shutil

    config = _tiny_config(algo="sim", num_envs=2, rollout_len=4, total_steps=48, log_every=16, obs_len=3, act_len=2)
    written = []  # the steps of each checkpoint written
    monkeypatch.setattr(training, "write_checkpoint", lambda out, r, steps, seeds: written.append(steps)
                        or runs.write_checkpoint(out, r, steps, seeds))
    calls = []

    def kill_after_second(self, *args):  # a copy of the folder as a kill -9 after the second row leaves it
        calls.append(args)
        if len(calls) == 2:
            shutil.copytree(tmp_path / "whole", tmp_path / "killed")

    with monkeypatch.context() as m:
        m.setattr(Progress, "update", kill_after_second)
        runs.run(config, tmp_path / "whole", quiet=True, checkpoint_every=3600)
    assert written == [0, 48]  # the start and the end: no interval passed between
    assert runs.load_checkpoint(tmp_path / "killed")["env_steps"] == 0
    assert len(list(csv.reader(open(tmp_path / "killed" / "metrics.csv")))) == 3  # header + 2 rows after it

    def stop_after_first(self, *args):
        raise KeyboardInterrupt

    written.clear()
    with monkeypatch.context() as m:
        m.setattr(Progress, "update", stop_after_first)
        runs.run(config, tmp_path / "parts", quiet=True)
    assert written == [0, 16]  # the start, and the stop: the default interval had not passed
    assert len(list(csv.reader(open(tmp_path / "parts" / "metrics.csv")))) == 2  # header + 1 row
    written.clear()
    runs.run(runs.load_config(tmp_path / "parts"), tmp_path / "parts", quiet=True, resume=True, checkpoint_every=0)
    assert written == [16, 32, 48]  # on resuming, then after every row
    runs.run(runs.load_config(tmp_path / "killed"), tmp_path / "killed", quiet=True, resume=True)
    same = [c for c in runs.METRIC_COLUMNS if c not in ("steps_per_s", "wall_s")]
    rows = [list(csv.DictReader(open(tmp_path / d / "metrics.csv"))) for d in ("whole", "parts", "killed")]
    assert [len(r) for r in rows] == [3, 3, 3]
    assert [[r[c] for c in same] for r in rows[0]] == [[r[c] for c in same] for r in rows[1]] == [
        [r[c] for c in same] for r in rows[2]]
    chex.assert_trees_all_equal(*(runs.load_checkpoint(tmp_path / d)["runner"] for d in ("whole", "parts", "killed")))


@pytest.mark.xdist_group("rnd_tiny_run")  # helpers.RND_TINY
def test_a_fork_goes_on_from_its_source_with_the_changed_settings(tmp_path, capsys):
    from simjax import fork

    config = TrainConfig(**RND_TINY, total_steps=40)
    runs.run(config, tmp_path / "src", quiet=True)
    before = (tmp_path / "src" / "checkpoint.msgpack").read_bytes()
    for bad, message in ((["--num-envs", "8"], "cannot change --num-envs"), (["--total-steps", "40"], "larger"),
                         ([], "at least one"), (["--bonus-scale", "-1"], "--bonus-scale"),
                         (["--out", "x"], "unrecognized arguments: --out")):
        with pytest.raises(SystemExit):
            fork.main([str(tmp_path / "src"), str(tmp_path / "bad"), *bad])
        assert message in capsys.readouterr().err and not (tmp_path / "bad").exists()
    assert fork.main([str(tmp_path / "src"), str(tmp_path / "dst"), "--bonus-episodic", "false",
                      "--bonus-scale", "0.5", "--total-steps", "80"]) == 0
    assert (tmp_path / "src" / "checkpoint.msgpack").read_bytes() == before  # the source is never written
    record = json.loads((tmp_path / "dst" / "fork.json").read_text())
    assert record["env_steps"] == 40 and record["changed"]["bonus_scale"] == [0.01, 0.5]
    # only the bonus's value head and its Adam moments are new
    assert record["new_leaves"] and all("IntrinsicValue" in p for p in record["new_leaves"])
    new = runs.load_config(tmp_path / "dst")
    assert (new.bonus_episodic, new.bonus_scale, new.total_steps) == (False, 0.5, 80)
    src = runs.load_checkpoint(tmp_path / "src")["runner"]
    dst = runs.load_checkpoint(tmp_path / "dst")["runner"]
    np.testing.assert_array_equal(dst["params"]["policy"]["params"]["Dense_1"]["kernel"],
                                  src["params"]["policy"]["params"]["Dense_1"]["kernel"])
    chex.assert_trees_all_equal(dst["novelty"], src["novelty"])
    # the second value head: (256, 1) a seed, the one head's tree plus it (old checkpoints load)
    src_heads, dst_heads = (r["params"]["policy"]["params"] for r in (src, dst))
    assert set(dst_heads) - set(src_heads) == {"IntrinsicValue"} and set(src_heads) <= set(dst_heads)
    assert dst_heads["IntrinsicValue"]["kernel"].shape == (2, 256, 1)
    runs.run(new, tmp_path / "dst", quiet=True, resume=True)  # and it trains on from step 40
    rows = list(csv.DictReader(open(tmp_path / "dst" / "metrics.csv")))
    assert sorted((int(r["env_steps"]), int(r["seed"])) for r in rows) == [(s, i) for s in (20, 40, 60, 80) for i in (0, 1)]
    trained = runs.load_checkpoint(tmp_path / "dst")["runner"]["params"]["policy"]["params"]["IntrinsicValue"]
    chex.assert_tree_all_finite(trained)
    for seed in (0, 1):  # the non-episodic bonus trains its own head
        assert not np.array_equal(trained["kernel"][seed], dst_heads["IntrinsicValue"]["kernel"][seed])
