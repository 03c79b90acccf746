"""Run folders: read back with ``restore``, the TensorBoard copy of metrics.csv, and a run that
diverges."""

import csv
import glob
import json
import os
import shutil
import signal
import struct
import subprocess
import sys
import time

import chex
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import RND_TINY, flags

from simjax import runs, runtime
from simjax import sweep as sweep_cli
from simjax import train as cli
from simjax.agents import TrainConfig
from simjax.networks.layers import operand_dtype
from simjax.runs import training


@pytest.mark.xdist_group("rnd_tiny_run")  # helpers.RND_TINY
def test_restore_reads_a_run_back_from_its_checkpoint_or_from_its_export_alone(tmp_path, capsys):
    config = TrainConfig(**RND_TINY, total_steps=40)
    run = runs.run(config, tmp_path / "run", quiet=True)
    restored = runs.restore(run)
    assert restored.config == config and restored.env_steps == 40 and restored.seeds == [0, 1]
    saved = runs.load_checkpoint(run)["runner"]
    policy = restored.policy()
    np.testing.assert_array_equal(policy["params"]["Dense_0"]["kernel"], saved["params"]["policy"]["params"]["Dense_0"]["kernel"])
    one = restored.runner(1)
    chex.assert_trees_all_equal(one.params["policy"], jax.tree.map(lambda x: x[1], policy))
    assert one.novelty.obs_stats.mean.shape == restored.env.observation_size
    assert restored.network is restored.trainer.network
    trajectories = _experiment("trajectories")
    assert trajectories.main([str(run), "--envs", "2"]) == 0
    drawn = capsys.readouterr().out

    # without the checkpoint: the export, every file of it small enough to copy off a GPU machine
    assert [f.name for f in (run / "export").iterdir()] == ["40-1-of-1.msgpack"]
    assert (run / "export" / "40-1-of-1.msgpack").stat().st_size < 16 * 2**20
    (run / "checkpoint.msgpack").rename(tmp_path / "checkpoint.msgpack")
    back = runs.restore(run)
    assert back.exported and (back.config, back.env_steps, back.seeds) == (config, 40, [0, 1])
    chex.assert_trees_all_equal(back.policy(), policy)
    chex.assert_trees_all_equal(back.novelty(1), (one.params["novelty"], one.novelty.obs_stats))
    with pytest.raises(FileNotFoundError, match="not the whole runner state"):
        back.runner()
    assert trajectories.main([str(run), "--envs", "2"]) == 0
    assert capsys.readouterr().out == drawn
    with pytest.raises(SystemExit):  # it would train again from step 0 over the export
        cli.main(["--resume", str(run), "--quiet"])
    assert "has its export but no checkpoint.msgpack" in capsys.readouterr().err
    with pytest.raises(FileNotFoundError, match="a fork goes on from the whole state"):
        runs.fork(run, tmp_path / "fork", {"total_steps": 80})
    with pytest.raises(FileNotFoundError, match="no checkpoint.msgpack and no export/"):
        shutil.rmtree(run / "export")
        runs.restore(run)
    with pytest.raises(FileNotFoundError, match="not a run folder"):
        runs.restore(tmp_path)


def _experiment(name: str):
    """experiments/NAME.py as a module (the folder is not a package)."""
    import importlib
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "experiments"))
    try:
        return importlib.import_module(name)
    finally:
        sys.path.pop(0)


def test_spots_passed_counts_the_spots_an_episode_came_near_before_it_ended():
    """Two envs' first episodes on a line past three spots 100 units apart: env 0 passes the
    first two (64 units is within, 65 not), env 1 ends after one step, by the first spot only."""
    trajectories = _experiment("trajectories")
    spots = {1: (0.0, 0.0), 2: (100.0, 64.0), 3: (200.0, 65.0)}
    path = np.stack([np.arange(0.0, 250.0, 10.0), np.zeros(25)], axis=-1)  # (K, 2) along y = 0
    pos = np.stack([path, path], axis=1)  # (K, 2 envs, 2)
    alive = np.ones((25, 2), bool)
    alive[1:, 1] = False  # env 1's episode ended at its first step: later positions are another's
    np.testing.assert_array_equal(trajectories.spots_passed(pos, alive, spots), [2, 1])


def test_an_export_is_split_into_files_under_the_limit_and_read_back_whole(tmp_path, monkeypatch):
    from simjax.runs import folder

    rng = np.random.default_rng(0)
    draw = lambda *shape: rng.standard_normal(shape).astype(np.float32)
    runner = {"params": {"policy": {"params": {"Dense_0": {"kernel": draw(2, 300, 1000), "bias": draw(2, 1000)}}},
                         "novelty": {"target": {"w": draw(2, 40, 50)}}},
              "novelty": {"obs_stats": {"mean": draw(2, 7), "count": np.ones(2, np.float32)}, "memory": draw(2, 9)},
              "opt_state": {"mu": draw(2, 300, 1000)}}
    monkeypatch.setattr(folder, "EXPORT_PART_BYTES", 500_000)  # a kernel of a member, 1.2 MB, is cut in three
    folder.write_export(tmp_path, runner, 40, [0, 1])
    files = sorted(f.name for f in (tmp_path / "export").iterdir())
    assert files == [f"40-{k}-of-6.msgpack" for k in range(1, 7)]  # per member 3: a cut each, the small arrays beside the last
    from flax import serialization

    for f in files:
        arrays = serialization.msgpack_restore((tmp_path / "export" / f).read_bytes())["arrays"]
        assert sum(np.asarray(a).nbytes for a in arrays.values()) <= 500_000
    exported = {k: runner[k] for k in ("params",)} | {"novelty": {"obs_stats": runner["novelty"]["obs_stats"]}}
    back = folder.load_export(tmp_path)
    assert (back["env_steps"], back["seeds"]) == (40, [0, 1])
    chex.assert_trees_all_equal(back["runner"], exported)  # not Adam's moments, not the novelty memory
    # a kill while the next export is written leaves part of it: the whole one before it is read
    shutil.copy(tmp_path / "export" / files[0], tmp_path / "export" / "80-1-of-6.msgpack")
    assert folder.load_export(tmp_path)["env_steps"] == 40
    folder.write_export(tmp_path, runner, 120, [0, 1])  # a whole new one replaces every older file
    assert sorted(f.name for f in (tmp_path / "export").iterdir()) == [f"120-{k}-of-6.msgpack" for k in range(1, 7)]
    (tmp_path / "export" / "120-3-of-6.msgpack").write_bytes(b"\x05")
    with pytest.raises(ValueError, match="120-3-of-6.msgpack is damaged"):
        folder.load_export(tmp_path)


def read_events(folder) -> dict:
    """{(tag, step): value} of the scalars in a folder's TensorBoard event files (TFRecords:
    length, its CRC, an Event protocol buffer, its CRC)."""
    from tensorboardX.proto import event_pb2

    scalars = {}
    for path in glob.glob(str(folder / "events.out.tfevents.*")):
        data, i = open(path, "rb").read(), 0
        while i < len(data):
            (n,) = struct.unpack("<Q", data[i:i + 8])
            event = event_pb2.Event.FromString(data[i + 12:i + 12 + n])
            i += 12 + n + 4
            for value in event.summary.value:
                scalars[(value.tag, event.step)] = value.simple_value
    return scalars


@pytest.mark.xdist_group("rnd_tiny_run")  # helpers.RND_TINY
def test_tensorboard_holds_the_values_of_metrics_csv(tmp_path):
    pytest.importorskip("tensorboardX")
    out = tmp_path / "run"
    assert cli.main([*flags(RND_TINY), "--total-steps", "60", "--out", str(out), "--quiet", "--tensorboard"]) == 0
    rows = list(csv.DictReader(open(out / "metrics.csv")))
    assert len(rows) == 6
    checked = 0
    for seed in (0, 1):
        events = read_events(out / "tensorboard" / f"seed{seed}")
        mine = [r for r in rows if int(r["seed"]) == seed]
        for row in mine:
            step = int(row["env_steps"])
            for column in runs.METRIC_COLUMNS[2:]:
                value = float(row[column])
                if np.isfinite(value):
                    assert events[(column, step)] == np.float32(value), (seed, step, column)
                    checked += 1
                else:  # no point where the CSV says nan (no episode ended in that row)
                    assert (column, step) not in events
        assert len(events) == sum(np.isfinite(float(r[c])) for r in mine for c in runs.METRIC_COLUMNS[2:])
    assert checked > 50


def test_a_diverging_run_stops_at_its_first_non_finite_row_and_keeps_the_last_finite_checkpoint(tmp_path, capsys):
    out = tmp_path / "run"
    # lr 1e10: the first row is finite, the second not (measured: 1e9 and 1e10 do that, 1e12 is
    # non-finite in the first row, 1e8 overflows to 1e17 and stays finite since the policy LSTM
    # takes its input projection out of the scan)
    code = cli.main(["--env", "maze-tiny", "--total-steps", "1280", "--log-every", "640", "--learning-rate", "1e10",
                     "--max-grad-norm", "1e9", "--precision", "highest", "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert code == 1
    assert "error: training diverged in the updates up to 1,280 agent steps" in err, err
    assert "seed 0: policy_loss nan" in err and "grad_norm nan" in err and "policy parameters" in err
    assert "up to 640 steps" in err and "Traceback" not in err
    rows = list(csv.DictReader(open(out / "metrics.csv")))
    assert [int(r["env_steps"]) for r in rows] == [640]  # the NaN row is not written
    ckpt = runs.load_checkpoint(out)
    assert ckpt["env_steps"] == 640
    chex.assert_tree_all_finite(ckpt["runner"]["params"])


def _processes_naming(text: str) -> list[int]:
    """The pids of the live processes whose command line contains ``text``."""
    found = []
    for cmdline in glob.glob("/proc/[0-9]*/cmdline"):
        try:
            with open(cmdline, "rb") as f:
                args = f.read().replace(b"\0", b" ").decode(errors="replace")
        except OSError:  # it ended while we looked
            continue
        if text in args:
            found.append(int(cmdline.split("/")[2]))
    return found


def test_a_stop_arriving_while_a_row_and_its_checkpoint_are_written_waits_for_both():
    from simjax.runs.folder import stops_deferred

    events = []

    def stop(signum, frame):
        events.append(signal.Signals(signum).name)
        raise KeyboardInterrupt

    previous = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        with pytest.raises(KeyboardInterrupt):
            with stops_deferred():
                signal.raise_signal(signal.SIGTERM)
                events.append("row written")
                events.append("checkpoint written")
        assert events == ["row written", "checkpoint written", "SIGTERM"]
        assert signal.getsignal(signal.SIGTERM) is stop  # the handler before the block is back
        with stops_deferred():
            events.append("nothing pending")
        assert events[-1] == "nothing pending"
        with pytest.raises(OSError, match="disk full"):  # a failing block's own error goes on
            with stops_deferred():
                signal.raise_signal(signal.SIGTERM)
                raise OSError("disk full")
        assert events[-1] == "nothing pending" and signal.getsignal(signal.SIGTERM) is stop
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def test_a_stop_during_an_atomic_write_leaves_the_new_file_and_no_temporary(tmp_path, monkeypatch):
    from pathlib import Path

    from simjax.runs.folder import atomic_write

    real_write = Path.write_bytes

    def write_then_get_stopped(self, data):
        signal.raise_signal(signal.SIGINT)  # Ctrl-C halfway through the write
        return real_write(self, data)

    target = tmp_path / "checkpoint.msgpack"
    target.write_bytes(b"old")
    monkeypatch.setattr(Path, "write_bytes", write_then_get_stopped)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            atomic_write(target, b"new")
    finally:
        signal.signal(signal.SIGINT, previous)
    assert target.read_bytes() == b"new" and [p.name for p in tmp_path.iterdir()] == ["checkpoint.msgpack"]


@pytest.mark.xdist_group("rnd_tiny_run")  # helpers.RND_TINY
def test_sigterm_stops_a_run_as_ctrl_c_does_keeping_rows_and_checkpoint(tmp_path):
    # what `timeout` or a job scheduler sends; the command loads RND_TINY's programs from the session's cache
    out = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "-m", "simjax.train", *flags(RND_TINY), "--total-steps", "100000000",
                             "--out", str(out), "--quiet"],
                            start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.time() + 300
        while not ((out / "metrics.csv").exists() and len((out / "metrics.csv").read_text().splitlines()) >= 5):  # 2 rows a seed
            assert proc.poll() is None and time.time() < deadline, proc.stderr.read().decode()
            time.sleep(0.2)
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(timeout=120)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert code == 130, proc.stderr.read().decode()
    assert _processes_naming(str(out)) == []  # nothing left training
    rows = list(csv.DictReader(open(out / "metrics.csv")))
    assert runs.load_checkpoint(out)["env_steps"] == int(rows[-1]["env_steps"]) >= 40
    assert (out / "curve.png").exists() and not list(out.glob("*.tmp"))


def test_a_checkpoint_whose_poses_store_their_heading_still_restores(tmp_path):
    # poses that hold a heading beside the angle it is derived from
    from simjax.envs.doom import motion

    pose = motion.Pose.at(np.array([3.0, 4.0], np.float32), 1.0)
    old = {"pose": {"pos": pose.pos, "heading": pose.heading, "vel": pose.vel, "angle": pose.angle,
                    "turn_tics": pose.turn_tics}}
    runs.write_checkpoint(tmp_path, old, 40, [0])
    back = runs.load_checkpoint(tmp_path, {"pose": pose})["runner"]["pose"]
    assert isinstance(back, motion.Pose) and int(back.angle) == int(pose.angle)
    assert float(back.heading) == float(pose.heading) == pytest.approx(1.0, abs=1e-4)


def test_precision_is_a_run_setting_recorded_in_config_json(tmp_path, capsys):
    config, _, _ = cli.parse_config(["--env", "maze-tiny", "--precision", "high", "--out", str(tmp_path / "new")])
    assert config.precision == "high" and TrainConfig().precision == "highest"
    runs.write_config(tmp_path, config)
    record = json.loads((tmp_path / "config.json").read_text())
    assert record["config"]["precision"] == "high" and runs.load_config(tmp_path).precision == "high"
    # a config.json from before the flag: it trained at JAX's default, which on the CPU is float32
    del record["config"]["precision"]
    (tmp_path / "config.json").write_text(json.dumps(record))
    assert runs.load_config(tmp_path).precision == "highest"
    for parse, argv in ((cli.parse_config, ["--precision", "fast"]), (sweep_cli.parse_sweep, ["--precision", "high,fast"])):
        with pytest.raises(SystemExit):
            parse(argv)
        assert "invalid choice: 'fast'" in capsys.readouterr().err
    assert set(runtime.MATMUL_PRECISIONS) == set(dict(TrainConfig.__dataclass_fields__)["precision"].metadata["choices"])
    with pytest.raises(ValueError, match="--precision must be one of"):
        runtime.matmul_precision("fast")


def test_the_commands_train_in_bfloat16_on_a_cpu_with_bfloat16_dots_unless_told_otherwise(tmp_path, monkeypatch):
    """Given no --precision, the training and sweep commands take bfloat16 on a CPU that multiplies
    bfloat16 in hardware (AMX or AVX-512 BF16, read from cpuinfo's flags; the tests' backend is the
    CPU, and both answers are tried whatever this machine has) and record it; without, highest; a
    given one wins; TrainConfig stays float32."""
    assert jax.default_backend() == "cpu"
    cpuinfo = tmp_path / "cpuinfo"
    for listed, native in [("fpu avx512f avx512_vnni amx_tile amx_bf16 amx_int8", True), ("fpu avx512f avx512_bf16", True),
                          ("fpu avx512f avx512_vnni avx2", False), ("fpu avx512_bf16x amx_bf", False)]:
        cpuinfo.write_text(f"processor\t: 0\nmodel name\t: x\nflags\t\t: {listed}\n\nprocessor\t: 1\nflags\t\t: {listed}\n")
        assert runtime.cpu_has_bfloat16_dots(str(cpuinfo)) is native, listed
    assert runtime.cpu_has_bfloat16_dots(str(tmp_path / "none")) is False
    monkeypatch.setattr(runtime, "cpu_has_bfloat16_dots", lambda: False)
    assert cli.parse_config(["--env", "maze-tiny", "--out", str(tmp_path / "z")])[0].precision == "highest"
    monkeypatch.setattr(runtime, "cpu_has_bfloat16_dots", lambda: True)
    assert runtime.command_default_precision() == "bfloat16"
    config, _, _ = cli.parse_config(["--env", "maze-tiny", "--out", str(tmp_path / "a")])
    assert config.precision == "bfloat16" and TrainConfig(env="maze-tiny").precision == "highest"
    runs.write_config(tmp_path, config)
    assert json.loads((tmp_path / "config.json").read_text())["config"]["precision"] == "bfloat16"
    config, _, _ = cli.parse_config(["--env", "maze-tiny", "--precision", "highest", "--out", str(tmp_path / "b")])
    assert config.precision == "highest"
    config, grid, _, _, _ = sweep_cli.parse_sweep(["--env", "maze-tiny", "--bonus-scale", "0.1,0.2", "--algo", "rnd",
                                                   "--out", str(tmp_path / "c")])
    assert config.precision == "bfloat16" and all(TrainConfig(**{**config.__dict__, **p}).precision == "bfloat16"
                                                  for p in grid)


def test_a_run_is_traced_at_its_recorded_precision_whatever_jax_global_setting(tmp_path, monkeypatch):
    """The command's programs are traced (so compiled) inside ``runtime.matmul_precision``: it
    wins over JAX_DEFAULT_MATMUL_PRECISION (the global value set here) and leaves it as it was."""
    seen = []

    class Traced(Exception):
        pass

    def first_inputs(*args):  # the fresh run's init is traced with these, right after
        seen.append((jax.config.jax_default_matmul_precision, operand_dtype()))
        raise Traced

    monkeypatch.setattr(training, "batch_inputs", first_inputs)
    out = tmp_path / "run"
    previous = jax.config.jax_default_matmul_precision
    jax.config.update("jax_default_matmul_precision", "bfloat16")  # what JAX_DEFAULT_MATMUL_PRECISION=bfloat16 sets
    try:
        with pytest.raises(Traced):
            cli.main(["--env", "maze-tiny", "--precision", "bfloat16", "--out", str(out), "--quiet"])
        with pytest.raises(Traced):  # the folder has no checkpoint yet: resumed, it starts again, at config.json's precision
            cli.main(["--resume", str(out), "--quiet"])
        assert jax.config.jax_default_matmul_precision == "bfloat16" and operand_dtype() == jnp.float32
    finally:
        jax.config.update("jax_default_matmul_precision", previous)
    # resumed as it was configured: bfloat16 operands in the networks, float32 products elsewhere
    assert seen == [(runtime.MATMUL_PRECISIONS["bfloat16"], jnp.bfloat16)] * 2 == [("float32", jnp.bfloat16)] * 2
