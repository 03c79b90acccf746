"""The evaluation command (simjax.evaluate) on a tiny trained run: both backends, the JSON it
writes, determinism, its refusals, and that the ViZDoom backend shows the policy the frames
simjax draws. Skipped where vizdoom is not installed."""

import json
import math
import shutil

import jax
import numpy as np
import pytest
from PIL import Image

pytest.importorskip("vizdoom")

from simjax import evaluate, runs  # noqa: E402
from simjax.agents import TrainConfig  # noqa: E402
from simjax.envs import make  # noqa: E402
from simjax.envs.doom import vizdoom_ref as vr  # noqa: E402

FIELDS = {"run", "env", "backend", "seed_index", "seed", "env_steps", "eval_seed", "greedy", "max_steps",
          "policy", "random", "command", "date", "versions", "video"}


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """A maze-dense run of two seeds trained for one 8-step update: a checkpoint to evaluate."""
    config = TrainConfig(env="maze-dense", num_envs=2, rollout_len=4, total_steps=8, log_every=8, num_seeds=2)
    return runs.run(config, tmp_path_factory.mktemp("eval") / "run", quiet=True)


def _check(record, backend, max_steps, episodes):
    assert set(record) == FIELDS
    assert record["backend"] == backend and record["env"] == "maze-dense" and record["env_steps"] == 8
    assert record["max_steps"] == max_steps and record["versions"]["vizdoom"] == vr.vzd.__version__
    assert "--max-steps" in record["command"]
    for name in ("policy", "random"):
        r = record[name]
        assert r["episodes"] == episodes and 0.0 <= r["success_ratio"] <= 1.0
        lo, hi = r["success_95"]
        assert 0.0 <= lo <= r["success_ratio"] <= hi <= 1.0
        assert 1 <= r["mean_episode_length"] <= max_steps
        assert sum(r["ends"]["nearest_spot"].values()) == episodes  # every episode ends somewhere
        assert 0.0 <= r["ends"]["goal_distance_mean"] < 1500.0  # the map spans about 1,100 units


def test_simjax_backend_all_seeds_and_determinism(run_dir, capsys):
    args = [str(run_dir), "--backend", "simjax", "--episodes", "2", "--max-steps", "20", "--quiet"]
    assert evaluate.main(args + ["--all-seeds"]) == 0
    out = capsys.readouterr().out
    assert "policy" in out and "random" in out and "95% interval" in out
    first = [json.loads((run_dir / f"evaluate-simjax-seed{k}.json").read_text()) for k in (0, 1)]
    for k, record in enumerate(first):
        _check(record, "simjax", 20, 2)
        assert record["seed_index"] == record["seed"] == k
    assert evaluate.main(args + ["--seed-index", "0"]) == 0  # the same eval seed: the same episodes
    again = json.loads((run_dir / "evaluate-simjax-seed0.json").read_text())
    assert (again["policy"], again["random"]) == (first[0]["policy"], first[0]["random"])


def test_a_folder_with_the_export_and_no_checkpoint_evaluates_as_the_checkpoint_does(run_dir, tmp_path):
    """What a GPU run brings back: config.json and export/ (the checkpoint is too large to copy)."""
    exported = tmp_path / "run"
    exported.mkdir()
    shutil.copy(run_dir / "config.json", exported / "config.json")
    shutil.copytree(run_dir / "export", exported / "export")
    args = ["--backend", "simjax", "--episodes", "2", "--max-steps", "20", "--quiet", "--seed-index", "1"]
    assert evaluate.main([str(run_dir), *args]) == 0
    assert evaluate.main([str(exported), *args]) == 0
    records = [json.loads((d / "evaluate-simjax-seed1.json").read_text()) for d in (run_dir, exported)]
    drop = ("run", "command", "date")
    assert [{k: v for k, v in r.items() if k not in drop} for r in records][1:] == [
        {k: v for k, v in records[0].items() if k not in drop}]
    assert records[1]["env_steps"] == 8 and records[1]["seed"] == 1


def test_vizdoom_backend_and_video(run_dir, tmp_path):
    video = tmp_path / "episodes.gif"
    args = [str(run_dir), "--backend", "vizdoom", "--episodes", "2", "--max-steps", "20", "--quiet",
            "--seed-index", "1", "--video", str(video), "--video-episodes", "1"]
    assert evaluate.main(args) == 0
    record = json.loads((run_dir / "evaluate-vizdoom-seed1.json").read_text())
    _check(record, "vizdoom", 20, 2)
    assert record["seed"] == 1 and record["video"] == str(video)
    with Image.open(video) as gif:
        assert 1 <= gif.n_frames <= 20


def test_a_folder_written_before_the_icm_starts_evaluates_and_resumes_with_the_start_it_trained_with(run_dir, tmp_path):
    # a config.json of before 2026-12-04: no "tasks_as_of", and maze-very-sparse meant spot 10 facing east
    old = tmp_path / "old"
    shutil.copytree(run_dir, old, ignore=shutil.ignore_patterns("evaluate-*"))
    record = json.loads((old / "config.json").read_text())
    del record["tasks_as_of"]
    record["config"]["env"] = "maze-very-sparse"
    (old / "config.json").write_text(json.dumps(record))
    restored = runs.restore(old)
    assert restored.config.env == "maze-spot10-east"
    pose = jax.jit(restored.env.reset)(jax.random.PRNGKey(0)).pipeline_state.pose
    np.testing.assert_allclose(np.asarray(pose.pos), [240.0, -176.0])
    assert int(pose.angle) == 0
    assert evaluate.main([str(old), "--backend", "vizdoom", "--episodes", "1", "--random-episodes", "0",
                          "--max-steps", "3", "--quiet"]) == 0
    evaluated = json.loads((old / "evaluate-vizdoom-seed0.json").read_text())
    assert evaluated["env"] == "maze-spot10-east"
    assert evaluated["policy"]["ends"]["nearest_spot"] == {"10": 1}  # 3 steps from spot 10 stay near it
    config = runs.load_config(old)
    runs.run(TrainConfig(**{**config.__dict__, "total_steps": 16}), old, quiet=True, resume=True)
    record = json.loads((old / "config.json").read_text())  # rewritten under today's name
    assert record["config"]["env"] == "maze-spot10-east" and "tasks_as_of" in record
    steps = sorted({int(float(line.split(",")[0])) for line in (old / "metrics.csv").read_text().splitlines()[1:]})
    assert steps == [8, 16]


@pytest.mark.parametrize("bad, message", [
    (["--backend", "vizdoom", "--episodes", "0"], "--episodes must be at least 1"),
    (["--backend", "doom"], "invalid choice: 'doom'"),
    (["--backend", "simjax", "--max-steps", "600"], "--max-steps must lie in [1, 525]"),
    (["--backend", "simjax", "--seed-index", "2"], "the run has 2 seed(s)"),
])
def test_bad_flags_are_refused_before_compiling(run_dir, bad, message, capsys, monkeypatch):
    monkeypatch.setattr(evaluate, "restore", lambda *a: pytest.fail("must not load or compile"))
    with pytest.raises(SystemExit):
        evaluate.main([str(run_dir), *bad])
    assert message in capsys.readouterr().err


def test_missing_runs_checkpoints_and_other_tasks_are_refused(run_dir, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(evaluate, "restore", lambda *a: pytest.fail("must not load or compile"))
    with pytest.raises(SystemExit):
        evaluate.main([str(tmp_path / "nowhere"), "--backend", "simjax"])
    assert "no such run folder" in capsys.readouterr().err
    bare = tmp_path / "bare"
    bare.mkdir()
    shutil.copy(run_dir / "config.json", bare / "config.json")
    with pytest.raises(SystemExit):
        evaluate.main([str(bare), "--backend", "vizdoom"])
    err = capsys.readouterr().err
    assert "has no checkpoint.msgpack and no export/" in err and "not kept in git" in err and "--resume" in err
    tiny = tmp_path / "tiny"
    tiny.mkdir()
    runs.write_config(tiny, TrainConfig(env="maze-tiny"))
    (tiny / "checkpoint.msgpack").write_bytes(b"")
    with pytest.raises(SystemExit):
        evaluate.main([str(tiny), "--backend", "vizdoom"])
    err = capsys.readouterr().err
    assert "plays MyWayHome" in err and "maze-tiny" in err
    with pytest.raises(SystemExit):
        evaluate.main([str(tiny), "--backend", "simjax"])
    assert f"{tiny / 'checkpoint.msgpack'} is damaged" in capsys.readouterr().err


def test_where_they_end_counts_nearest_spots_and_the_goal_distance():
    spots = {13: (0.0, 0.0), 24: (100.0, 0.0), 26: (0.0, 300.0)}
    ends = np.array([[1.0, 2.0], [-3.0, 0.0], [95.0, 1.0], [0.0, 290.0], [2.0, -1.0]])
    out = evaluate.where_they_end(ends, (0.0, 400.0), spots)
    assert out["nearest_spot"] == {"13": 3, "24": 1, "26": 1}
    assert list(out["nearest_spot"]) == ["13", "24", "26"]  # most first, then by spot
    expected = np.mean([np.hypot(*(e - (0.0, 400.0))) for e in ends])
    assert math.isclose(out["goal_distance_mean"], expected, rel_tol=1e-12)


def test_simjax_episodes_end_before_each_lanes_last_step_of_its_first_episode():
    """3 steps x 3 lanes: lane 0 ends at step 1, lane 1 at step 2 (then resets), lane 2 never."""
    done = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], bool)
    success = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 0]], bool)
    length = np.array([[1, 1, 1], [2, 2, 2], [9, 3, 3]], np.int32)
    xy = np.arange(3 * 3 * 2, dtype=np.float32).reshape(3, 3, 2)  # (T, N, 2) before each step
    views = np.zeros((3, 1, 42, 42, 3), np.uint8)
    got_success, got_length, recorded, ends = evaluate.simjax_episodes(
        lambda *a: (done, success, length, views, xy), None, None, False, 3, 3, 1)
    assert got_success.tolist() == [True, False, False] and got_length.tolist() == [2, 3, 3]
    np.testing.assert_array_equal(ends, [xy[1, 0], xy[2, 1], xy[2, 2]])
    np.testing.assert_array_equal(recorded[0][1], xy[:2, 0])


def test_wilson_interval():
    assert evaluate.wilson(0, 10)[0] == 0.0 and evaluate.wilson(10, 10)[1] == 1.0
    lo, hi = evaluate.wilson(50, 100)
    assert math.isclose(lo, 0.4038, abs_tol=1e-4) and math.isclose(hi, 0.5962, abs_tol=1e-4)


def test_the_policy_sees_in_vizdoom_what_simjax_draws_at_the_same_pose():
    """The first frame the ViZDoom backend hands the policy (random spots, and spot 16 placed by
    the patched wad) against simjax's render at the pose ViZDoom reports."""
    seen = []

    def choose(i):
        return lambda view: seen.append((view, game.pose())) or 3

    ends = []
    with vr.MyWayHome(seed=0, depth=False) as game:
        for start in (None, None, vr.TASK_SCENARIOS["maze-spot16-east"][1]):
            ends.append(evaluate.vizdoom_episodes(game, start, choose, [len(seen)], steps=1, record=0)[3])
    # an episode of one step ends where it stood before that step: where its frame was seen
    np.testing.assert_array_equal(np.concatenate(ends), [pose[:2] for _, pose in seen])
    env = make("maze-dense")
    reset_to = jax.jit(env.reset_to)
    for view, (x, y, angle) in seen:
        ours = np.asarray(reset_to(jax.random.PRNGKey(0), np.array([x, y], np.float32), math.radians(angle)).obs)
        assert view.shape == ours.shape == (42, 42, 3) and view.dtype == np.uint8
        assert np.abs(view.astype(int) - ours.astype(int)).mean() < 15
