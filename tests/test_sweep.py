"""Sweeps: SIM's H and L as traced values (padded, masked windows), the hoisted LSTM input
projection, one compiled program per sweep, its run folder, and bad sweep values."""

import csv
import json
import logging
import os
import subprocess
import sys
import textwrap

import chex
import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from simjax import runs
from simjax.agents import TrainConfig
from simjax.novelty import SIM, NoveltyHyper, build_timeline, init_memory
from simjax.novelty.base import normalize_frames
from simjax.novelty.networks import WindowLSTM
from simjax.plotting import read_members
from simjax.runs.grid import check_sweep
from simjax.sweep import parse_sweep

A, T, N = 4, 6, 2


def _timeline(history, rollouts=3, seed=0):
    """A timeline after ``rollouts`` random rollouts with episode starts sprinkled in."""
    rng = np.random.default_rng(seed)
    memory = init_memory(history, N, (42, 42, 3))
    for _ in range(rollouts):
        obs = jnp.asarray(rng.integers(0, 256, (T, N, 42, 42, 3)), jnp.uint8)
        reset = jnp.asarray(rng.random((T, N)) < 0.15)
        actions = jnp.asarray(rng.integers(0, A, (T, N)), jnp.int32)
        tl, memory = build_timeline(memory, obs, reset, actions, obs[-1], jnp.zeros(N, bool))
    return tl


def _cut(tl, history):
    """The same timeline as a model with a shorter memory ``history`` keeps it."""
    off = tl.history - history
    return tl._replace(frames=tl.frames[off:], actions=tl.actions[off:], segment=tl.segment[off:],
                       valid=tl.valid[off:], history=history)


def _hyper(H, L, lam=0.2):
    return NoveltyHyper(jnp.float32(0.001), jnp.float32(0.99), jnp.float32(lam), jnp.int32(H), jnp.int32(L))


@pytest.mark.parametrize("sequence", ["lstm", "ff"])
def test_padded_windows_with_traced_lengths_give_the_model_built_for_them(sequence):
    wide = SIM(A, obs_len=5, act_len=4, sequence=sequence)
    tl = _timeline(wide.history)
    x = normalize_frames(tl.frames, None)
    params = jax.jit(lambda x: wide.init(jax.random.PRNGKey(0), tl, x))(x)  # one program, not op by op

    def wide_loss(p, H, L):
        error, scored, loss, metrics = wide.apply(p, tl, x, _hyper(H, L))
        return loss, (error, scored, metrics)

    # one compiled program for every (H, L): lengths are traced
    wide_grad = jax.jit(jax.grad(wide_loss, has_aux=True))
    for H, L in [(2, 4), (4, 1), (5, 4)]:  # each length at its least, padded and unpadded
        small = SIM(A, obs_len=H, act_len=L, sequence=sequence)
        tl_s, x_s = _cut(tl, small.history), x[wide.history - small.history:]
        # the small model's parameters: the wide one's, its window-sized layers cut to the real slots
        p = jax.device_get(params["sim"]["params"])  # cut on the host: eager slices compile one by one
        inv = p["Inverse"]
        cut = {"Inverse": {
            "kernel": inv["kernel"].reshape(-1, 4, A)[:, 4 - (H - 1):].reshape(-1, (H - 1) * A),
            "bias": inv["bias"].reshape(4, A)[4 - (H - 1):].reshape(-1)}}
        if sequence == "ff":
            cut["FrameFF"] = {"kernel": p["FrameFF"]["kernel"][(5 - H) * 256:], "bias": p["FrameFF"]["bias"]}
            cut["ActionFF"] = {"kernel": p["ActionFF"]["kernel"][(4 - L) * 128:], "bias": p["ActionFF"]["bias"]}
        small_params = {**params, "sim": {"params": {**p, **cut}}}

        def small_loss(q, small=small, tl_s=tl_s, x_s=x_s):
            error, scored, loss, metrics = small.apply(q, tl_s, x_s)
            return loss, (error, scored, metrics)

        g_small, (e_small, s_small, m_small) = jax.jit(jax.grad(small_loss, has_aux=True))(small_params)
        g_wide, (e_wide, s_wide, m_wide) = wide_grad(params, H, L)
        np.testing.assert_array_equal(s_wide, s_small)
        assert bool(s_small.any()) and not bool(s_small.all())  # episode starts mask some targets
        np.testing.assert_allclose(e_wide, e_small, rtol=1e-5, atol=1e-5)
        chex.assert_trees_all_close(m_wide, m_small, rtol=1e-5, atol=1e-6)
        gw, gs = g_wide["sim"]["params"], g_small["sim"]["params"]
        for name in set(gs) - set(cut):  # every layer but the cut ones: the same gradient
            chex.assert_trees_all_close(gw[name], gs[name], rtol=1e-4, atol=1e-6)
        kernel = np.asarray(gw["Inverse"]["kernel"]).reshape(-1, 4, A)
        np.testing.assert_allclose(kernel[:, 4 - (H - 1):].reshape(-1, (H - 1) * A), gs["Inverse"]["kernel"],
                                   rtol=1e-4, atol=1e-6)
        if H < 5:
            assert float(np.abs(kernel[:, : 4 - (H - 1)]).max()) == 0.0  # padding slots learn nothing
    assert wide_grad._cache_size() == 1


def test_hoisted_input_projection_is_flax_lstm_cell():
    """WindowLSTM (x W_ih once per timeline entry, h W_hh in the scan) against flax's
    OptimizedLSTMCell run step by step over the same windows, with the same weights."""
    S, B, D, Hd = 5, 3, 7, 8
    x = jax.random.normal(jax.random.PRNGKey(0), (S, B, D))
    start = jnp.array([True, True, False, False, False])  # a window padded by one slot
    lstm = WindowLSTM(Hd)
    params = lstm.init(jax.random.PRNGKey(1), jnp.zeros((S, B, 4 * Hd)), start)["params"]
    params = {**params, "input": lstm.init(jax.random.PRNGKey(2), x, method=WindowLSTM.project)["params"]["input"]}
    params["bias"] = jax.random.normal(jax.random.PRNGKey(3), (4 * Hd,))
    mine = lstm.apply({"params": params}, lstm.apply({"params": params}, x, method=WindowLSTM.project), start)

    w_in, w_h, b = (np.split(np.asarray(a), 4, axis=-1) for a in (params["input"]["kernel"], params["recurrent"],
                                                                  params["bias"]))
    cell_params = {f"i{g}": {"kernel": w_in[n]} for n, g in enumerate("ifgo")}
    cell_params |= {f"h{g}": {"kernel": w_h[n], "bias": b[n]} for n, g in enumerate("ifgo")}
    cell = nn.OptimizedLSTMCell(Hd)
    carry = (jnp.zeros((B, Hd)), jnp.zeros((B, Hd)))
    for s in range(S):
        if start[s]:
            carry = (jnp.zeros((B, Hd)), jnp.zeros((B, Hd)))
        carry, h = cell.apply({"params": cell_params}, carry, x[s])
    np.testing.assert_allclose(mine, h, rtol=1e-5, atol=1e-6)
    fresh = cell.apply({"params": cell_params}, (jnp.zeros((B, Hd)),) * 2, x[1])[1]
    assert not np.allclose(h, fresh)  # the later slots mattered


@pytest.mark.parametrize("argv,message", [
    (["--algo", "sim", "--act-len", "0,1"], "--act-len (L) must lie in [1,"),
    (["--algo", "sim", "--obs-len", "1,5"], "--obs-len (H) must lie in [2,"),
    (["--algo", "sim", "--act-len", ","], "--act-len has an empty list"),
    (["--algo", "sim", "--num-envs", "8,16"], "--num-envs cannot be swept"),
    (["--algo", "sim", "--sim-combine", "full,itr"], "--sim-combine cannot be swept"),
    (["--algo", "rnd", "--act-len", "1,2"], "sweeping --act-len changes nothing for --algo rnd"),
    (["--algo", "ec", "--forward-weight", "0.1,0.2"], "sweeping --forward-weight changes nothing for --algo ec"),
    (["--algo", "sim", "--bonus-scale", "0.01,-1"], "--bonus-scale must be a finite number >= 0"),
    (["--algo", "sim", "--act-len", "2,2"], "--act-len repeats a value"),
    (["--env", "maze-nowhere", "--algo", "sim", "--act-len", "1,2"], "maze-nowhere"),
])
def test_bad_sweeps_fail_before_compiling_and_name_the_flag(argv, message, capsys, tmp_path):
    with pytest.raises(SystemExit) as err:
        parse_sweep(argv + ["--out", str(tmp_path / "sweep")])
    assert err.value.code == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "sweep").exists()


def test_the_grid_and_the_run_config():
    config, grid = check_sweep({"algo": "sim", "obs_len": 4}, {"act_len": [3, 1, 2], "bonus_scale": [0.01, 0.001]})
    assert (config.act_len, config.obs_len) == (3, 4)  # windows for the largest L
    assert len(grid) == 6 and grid[0] == {"act_len": 3, "bonus_scale": 0.01} and grid[-1] == {"act_len": 2,
                                                                                            "bonus_scale": 0.001}


class _Compiles(logging.Handler):
    """Counts XLA compilations of the training chunk (jax_log_compiles' messages)."""

    def __init__(self):
        super().__init__()
        self.chunks = 0

    def emit(self, record):
        text = record.getMessage()
        if text.startswith("Compiling") and "chunk_and_summarize" in text:
            self.chunks += 1


def _tiny(**kw):
    return dict(env="maze-tiny", algo="sim", num_envs=2, rollout_len=4, total_steps=16, log_every=8, obs_len=3,
                num_seeds=2) | kw


# one seed, two rows of two updates: the plain run of L = 2 below is then the resumed-run test's
# SIM programs (tests/test_agents.py), loaded from the session's cache when that test compiled them
_ONE_PROGRAM = dict(num_seeds=1, total_steps=32, log_every=16)


@pytest.mark.xdist_group("sim_tiny_run")  # its plain run's programs are the resumed-run test's
def test_a_sweep_is_one_program_and_each_point_is_the_run_of_its_own(tmp_path, monkeypatch):
    config, grid = check_sweep(_tiny(**_ONE_PROGRAM), {"act_len": [1, 2, 3]})
    counter = _Compiles()
    logging.getLogger("jax").addHandler(counter)
    monkeypatch.setenv("JAX_LOG_COMPILES", "1")
    jax.config.update("jax_log_compiles", True)
    try:
        runs.run(config, tmp_path / "sweep", quiet=True, sweep={"act_len": [1, 2, 3]})
    finally:
        jax.config.update("jax_log_compiles", False)
        logging.getLogger("jax").removeHandler(counter)
    assert counter.chunks == 1  # 3 points, one compiled training program

    out = tmp_path / "sweep"
    record = json.loads((out / "config.json").read_text())
    assert record["sweep"] == {"act_len": [1, 2, 3]} and len(record["grid"]) == 3
    header = next(csv.reader(open(out / "metrics.csv")))
    assert header[:3] == ["act_len", "env_steps", "seed"]
    members = read_members(out)
    assert sorted(members) == [(((("act_len", float(L)),), 0)) for L in (1, 2, 3)]
    assert all(len(cols["env_steps"]) == 2 for cols in members.values())
    assert (out / "curve.png").exists() and (out / "checkpoint.msgpack").exists()
    # the points differ: L changes the forward loss from the first rows on
    first = {L: members[((("act_len", float(L)),), 0)]["forward_loss"][0] for L in (1, 2, 3)}
    assert len(set(first.values())) == 3, first

    # a plain run of L = 2 (windows built for L = 2): the sweep's L = 2 member, to float tolerance
    runs.run(TrainConfig(**_tiny(act_len=2, **_ONE_PROGRAM)), tmp_path / "plain", quiet=True)
    (((), seed), plain), = read_members(tmp_path / "plain").items()
    mine = members[((("act_len", 2.0),), seed)]
    for column in ("policy_loss", "value_loss", "entropy", "forward_loss", "inverse_loss", "bonus_mean"):
        np.testing.assert_allclose(mine[column], plain[column], rtol=2e-4, atol=1e-6, err_msg=column)


def test_a_sweep_resumes_where_it_stopped(tmp_path):
    sweep = {"entropy_coef": [0.01, 0.05]}
    config, _ = check_sweep(_tiny(algo="a2c", total_steps=24, num_seeds=1), sweep)
    runs.run(config, tmp_path / "whole", quiet=True, sweep=sweep)
    short = TrainConfig(**{**config.__dict__, "total_steps": 8})
    runs.run(short, tmp_path / "parts", quiet=True, sweep=sweep)
    rows = list(csv.reader(open(tmp_path / "parts" / "metrics.csv")))
    assert len(rows) == 3  # header + one row per point
    (tmp_path / "parts" / "config.json").write_text((tmp_path / "whole" / "config.json").read_text())
    runs.run(runs.load_config(tmp_path / "parts"), tmp_path / "parts", quiet=True, resume=True,
             sweep=runs.folder.load_sweep(tmp_path / "parts"))
    drop = ("steps_per_s", "wall_s")
    rows = [[{k: v for k, v in r.items() if k not in drop} for r in csv.DictReader(open(tmp_path / d / "metrics.csv"))]
            for d in ("whole", "parts")]
    assert len(rows[0]) == 6 and rows[0] == rows[1]
    with pytest.raises(ValueError, match="is a sweep"):  # a fork continues one run, not a grid
        runs.fork(tmp_path / "whole", tmp_path / "fork", {"total_steps": 48})


def test_sharded_over_two_devices_gives_the_same_metrics(tmp_path):
    """Two CPU devices (a subprocess: the device count is fixed when XLA starts): the members
    sharded over both give the numbers they give on one."""
    script = textwrap.dedent(f"""
        import csv, jax
        from simjax import runs
        from simjax.runs.grid import check_sweep
        assert len(jax.local_devices()) == 2
        sweep = {{"entropy_coef": [0.01, 0.05]}}  # A2C: the smallest training program to compile
        config, _ = check_sweep(dict(env="maze-tiny", algo="a2c", num_envs=2, rollout_len=4, total_steps=16,
                                     log_every=8, num_seeds=1), sweep)
        for name, devices in (("two", None), ("one", jax.local_devices()[:1])):
            runs.run(config, {str(tmp_path)!r} + "/" + name, quiet=True, sweep=sweep, devices=devices)
    """)
    env = os.environ | {"XLA_FLAGS": os.environ.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=2"}
    subprocess.run([sys.executable, "-c", script], check=True, env=env, timeout=600)
    drop = ("steps_per_s", "wall_s")
    rows = [[{k: v for k, v in r.items() if k not in drop} for r in csv.DictReader(open(tmp_path / d / "metrics.csv"))]
            for d in ("two", "one")]
    assert len(rows[0]) == 4
    for a, b in zip(*rows):
        assert a.keys() == b.keys()
        np.testing.assert_allclose([float(a[k]) for k in a], [float(b[k]) for k in b], rtol=1e-5, atol=1e-7)
