"""Run folders: read back with ``restore``."""

import chex
import jax
import numpy as np
import pytest

from simjax import runs
from simjax.agents import TrainConfig


def _tiny(**kw):
    base = dict(env="maze-tiny", num_envs=4, rollout_len=5, total_steps=40, log_every=20)
    return TrainConfig(**{**base, **kw})


def test_restore_reads_a_run_back(tmp_path):
    config = _tiny(algo="rnd", num_seeds=2)
    runs.run(config, tmp_path / "run", quiet=True)
    restored = runs.restore(tmp_path / "run")
    assert restored.config == config and restored.env_steps == 40 and restored.seeds == [0, 1]
    saved = runs.load_checkpoint(tmp_path / "run")["runner"]
    policy = restored.policy()
    np.testing.assert_array_equal(policy["params"]["Dense_0"]["kernel"], saved["params"]["policy"]["params"]["Dense_0"]["kernel"])
    one = restored.runner(1)
    chex.assert_trees_all_equal(one.params["policy"], jax.tree.map(lambda x: x[1], policy))
    assert one.novelty.obs_stats.mean.shape == restored.env.observation_size
    assert restored.network is restored.trainer.network
    with pytest.raises(FileNotFoundError, match="no checkpoint.msgpack"):
        (tmp_path / "run" / "checkpoint.msgpack").unlink()
        runs.restore(tmp_path / "run")
    with pytest.raises(FileNotFoundError, match="not a run folder"):
        runs.restore(tmp_path)
