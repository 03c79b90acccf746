"""What a task name meant when a run folder was written.

On 2026-12-04 MyWayHome's sparse and very sparse tasks took the starts of the ICM code's scenario
files (``simjax.envs.doom.icm_scenarios``), which the paper used. Before that, ``maze-very-sparse``
started at spot 10 facing exactly east (the paper's *sparse* start without its 0-3.6 degree
jitter) and ``maze-sparse`` at spot 16 facing east (no setting of the paper's). Those two starts
are tasks of their own now, ``maze-spot10-east`` and ``maze-spot16-east``.

A run folder's config.json written since then says so (``"tasks_as_of": TASKS_AS_OF``); one without
it names its task the old way, and ``current_record`` reads it under today's name, its look
(``-invented-looks``, ``-flat-TEX...``) kept, so that resuming, forking, evaluating and the tables
rebuild the start it trained with. Only the standard library: experiments/paper reads configs
without importing JAX.
"""

from __future__ import annotations

TASKS_AS_OF = "2026-12-04"
# the name a task had in a config.json without "tasks_as_of" -> its name today
RENAMED = {"maze-very-sparse": "maze-spot10-east", "maze-sparse": "maze-spot16-east"}


def renamed(name: str) -> str:
    """Today's name of the task a config.json written before TASKS_AS_OF calls ``name``."""
    for old, new in RENAMED.items():
        if name == old or name.startswith(old + "-"):  # the base task, or it in another look
            return new + name[len(old):]
    return name


def current_record(record: dict) -> dict:
    """config.json's contents with the task under today's name (a copy; ``record`` as read).
    A record written since TASKS_AS_OF is returned as it is."""
    if "tasks_as_of" in record or "env" not in record.get("config", {}):
        return record
    return {**record, "config": {**record["config"], "env": renamed(record["config"]["env"])},
            "tasks_as_of": TASKS_AS_OF}
