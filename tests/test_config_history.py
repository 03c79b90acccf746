"""``simjax.config_history``: a config.json is read under the task names of today, whatever date
its tasks are named as of, and the old names build the worlds those runs trained in. No JAX
program is compiled."""

import json
import shutil
from pathlib import Path

import pytest

from simjax import runs
from simjax.config_history import LOOKS, RENAMED, TASKS_AS_OF, current_record, renamed
from simjax.envs import FLAT_MARK, MYWAYHOME_TASKS, check_name, make
from simjax.envs.dmlab import pmove
from simjax.envs.doom import motion

RESULTS = Path(__file__).resolve().parents[1] / "experiments" / "results"
DMLAB_WORLDS = ("melon", "melon-dmlab", "explore-goals", "explore-goals-paper")


def record(env, tasks_as_of=None):
    """A config.json's contents as written on a day whose tasks are as of ``tasks_as_of`` (None:
    before the date was written)."""
    out = {"config": {"env": env, "algo": "sim"}, "versions": {}}
    return out | ({"tasks_as_of": tasks_as_of} if tasks_as_of else {})


def env_of(rec):
    return current_record(rec)["config"]["env"]


def test_every_name_today_is_a_task_and_no_change_is_dated_after_today():
    for date, (names, _) in RENAMED.items():
        assert date <= TASKS_AS_OF
        for new in names.values():
            check_name(new)
    # the looks renamed with a name are simjax.envs' look suffixes: every MyWayHome task is a
    # base task or one in a look of LOOKS, and the flat looks' mark is one
    bases = {n for n in MYWAYHOME_TASKS if not any(n.endswith(look) for look in LOOKS)}
    assert all(n in bases or any(n == b + look for b in bases for look in LOOKS) for n in MYWAYHOME_TASKS)
    assert FLAT_MARK in LOOKS and len(bases) < len(MYWAYHOME_TASKS)


def test_a_record_without_a_date_gets_every_change():
    assert env_of(record("maze-very-sparse")) == "maze-spot10-east"
    assert env_of(record("maze-sparse-invented-looks")) == "maze-spot16-east-invented-looks"
    assert env_of(record("maze-very-sparse-flat-SILVER2-TLITE6_1")) == "maze-spot10-east-flat-SILVER2-TLITE6_1"
    # an old melon or explore-goals record: the Doom-motion world it trained in, each name exactly
    for name in DMLAB_WORLDS:
        assert env_of(record(name)) == f"{name}-doom-motion"
    assert env_of(record("maze-dense")) == "maze-dense" and env_of(record("maze-tiny")) == "maze-tiny"
    assert current_record(record("melon"))["tasks_as_of"] == TASKS_AS_OF


def test_a_record_of_2026_12_04_gets_only_the_later_change():
    # its MyWayHome names are today's already: maze-very-sparse is the ICM start
    assert env_of(record("maze-very-sparse", "2026-12-04")) == "maze-very-sparse"
    assert env_of(record("maze-sparse-invented-looks", "2026-12-04")) == "maze-sparse-invented-looks"
    assert env_of(record("maze-spot10-east", "2026-12-04")) == "maze-spot10-east"
    for name in DMLAB_WORLDS:
        assert env_of(record(name, "2026-12-04")) == f"{name}-doom-motion"


def test_a_record_of_today_is_read_as_written():
    for name in (*DMLAB_WORLDS, "maze-very-sparse", "maze-sparse-invented-looks", "melon-doom-motion"):
        assert env_of(record(name, TASKS_AS_OF)) == name


def test_prefixes_of_other_names_are_not_renamed():
    # "melon-dmlab" starts with "melon-" and "explore-goals-paper" with "explore-goals-"
    assert renamed("melon-dmlab") == "melon-dmlab-doom-motion"
    assert renamed("explore-goals-paper") == "explore-goals-paper-doom-motion"
    assert renamed("melon-doom-motion", "2026-12-04") == "melon-doom-motion"  # no name of then: as it is
    assert renamed("maze-very-sparse-x") == "maze-very-sparse-x"  # no look
    assert renamed("gymnax:CartPole-v1") == "gymnax:CartPole-v1"


def test_a_record_without_a_config_or_env_is_left_alone():
    assert current_record({"versions": {}}) == {"versions": {}}
    assert "env" not in current_record({"config": {"algo": "sim"}})["config"]


@pytest.mark.parametrize("name", DMLAB_WORLDS)
def test_the_old_names_build_the_worlds_with_dooms_motion(name):
    old, new = make(f"{name}-doom-motion"), make(name)
    assert type(old) is type(new) and old.task == new.task
    assert old.motion_params == motion.MotionParams() and old.motion_model is motion
    assert isinstance(new.motion_params, pmove.DmlabMotionParams)


def test_the_stored_melon_and_explore_goals_folders_load_as_the_doom_motion_worlds(tmp_path):
    old = {f.parent.name: f.parent for f in RESULTS.glob("before-vizdoom-world/*/config.json")}
    for folder, task in (("melon-sim", "melon"), ("explore-goals-a2c", "explore-goals")):
        assert json.loads((old[folder] / "config.json").read_text())["config"]["env"] == task
        assert runs.load_config(old[folder]).env == f"{task}-doom-motion"
    # the same record written on 2026-12-04 reads the same; one written today names today's world
    copy = tmp_path / "melon"
    shutil.copytree(old["melon-sim"], copy)
    rec = json.loads((copy / "config.json").read_text())
    for date, want in (("2026-12-04", "melon-doom-motion"), (TASKS_AS_OF, "melon")):
        (copy / "config.json").write_text(json.dumps(rec | {"tasks_as_of": date}))
        assert runs.load_config(copy).env == want
