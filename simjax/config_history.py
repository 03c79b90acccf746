"""What a run folder's config.json meant when it was written, read under today's settings.

Two kinds of change are recorded here, so that every tool that reads a folder (resuming, forking,
evaluating, the diagnostics, and experiments/paper, which reads config.json without importing JAX)
rebuilds the run it was:

- Settings added after a folder was written: a config.json without one trained with the value
  in ``TRAINED_BEFORE_THE_FLAG`` (the code's fixed value then), whatever today's default is.
- Task names whose start changed. On 2026-12-04 MyWayHome's sparse and very sparse tasks took
  the starts of the ICM code's scenario files (``simjax.envs.doom.icm_scenarios``), which the
  paper used. Before that, ``maze-very-sparse`` started at spot 10 facing exactly east (the
  paper's *sparse* start without its 0-3.6 degree jitter) and ``maze-sparse`` at spot 16 facing
  east (no setting of the paper's). Those two starts are tasks of their own now,
  ``maze-spot10-east`` and ``maze-spot16-east``. A config.json written since says so
  (``"tasks_as_of": TASKS_AS_OF``); one without it names its task the old way and is read under
  today's name, its look (``-invented-looks``, ``-flat-TEX...``) kept.

Only the standard library.
"""

from __future__ import annotations

TASKS_AS_OF = "2026-12-04"
# the name a task had in a config.json without "tasks_as_of" -> its name today
RENAMED = {"maze-very-sparse": "maze-spot10-east", "maze-sparse": "maze-spot16-east"}
# a config.json without one of these settings was trained with this value
TRAINED_BEFORE_THE_FLAG = {"ec_beta": 0.5, "precision": "highest",  # precision: JAX's default, on CPUs float32
                           "learner": "a2c", "reward_clip": False, "bootstrap_time_limit": True,
                           "task_gamma": None, "task_advantage_weight": 1.0}  # one discount, one weight


def renamed(name: str) -> str:
    """Today's name of the task a config.json written before TASKS_AS_OF calls ``name``."""
    for old, new in RENAMED.items():
        if name == old or name.startswith(old + "-"):  # the base task, or it in another look
            return new + name[len(old):]
    return name


def current_record(record: dict) -> dict:
    """config.json's contents (``record``, as read) as today's code reads them: a copy whose
    config has every setting it trained with and its task under today's name."""
    config = record.get("config")
    if not isinstance(config, dict):
        return record
    config = config | {k: v for k, v in TRAINED_BEFORE_THE_FLAG.items() if k not in config}
    if "tasks_as_of" not in record and "env" in config:
        config["env"] = renamed(config["env"])
    return {**record, "config": config, "tasks_as_of": record.get("tasks_as_of", TASKS_AS_OF)}
