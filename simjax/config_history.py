"""What a run folder's config.json meant when it was written, read under today's settings.

Two kinds of change are recorded here, so that every tool that reads a folder (resuming, forking,
evaluating, the diagnostics, and experiments/paper, which reads config.json without importing JAX)
rebuilds the run it was:

- Settings added after a folder was written: a config.json without one trained with the value
  in ``TRAINED_BEFORE_THE_FLAG`` (the code's fixed value then), whatever today's default is.
- Tasks that changed under their name (``RENAMED``). The world a run trained in is kept under a
  new name, and a config.json names the tasks as of a date (``"tasks_as_of"``, ``TASKS_AS_OF``
  when it is written; none before 2026-12-04): one written before a change is read under the
  names its tasks have since, each change after its date applied in turn.

  - 2026-12-04: MyWayHome's sparse and very sparse tasks took the starts of the ICM code's
    scenario files (``simjax.envs.doom.icm_scenarios``), which the paper used. Before that,
    ``maze-very-sparse`` started at spot 10 facing exactly east (the paper's *sparse* start
    without its 0-3.6 degree jitter) and ``maze-sparse`` at spot 16 facing east (no setting of
    the paper's): ``maze-spot10-east`` and ``maze-spot16-east`` now, in any look
    (``-invented-looks``, ``-flat-TEX...``), the look kept.
  - 2026-12-07: the DMLab worlds (``melon``, ``melon-dmlab``, ``explore-goals``,
    ``explore-goals-paper``) took DeepMind Lab's player motion and pickup rule
    (``simjax.envs.dmlab.pmove``) and DeepMind Lab's look (its textures, sky and item models,
    ``simjax.envs.dmlab.look``). Before that they moved and touched items as MyWayHome does
    (Doom's motion) and were drawn with ``raycaster``'s invented looks: ``melon-doom-motion``,
    ``melon-dmlab-doom-motion``, ``explore-goals-doom-motion`` and
    ``explore-goals-paper-doom-motion`` now, which keep both. These names have no other looks,
    so only the exact names are read so (``melon-dmlab`` is no look of ``melon``).

Only the standard library.
"""

from __future__ import annotations

TASKS_AS_OF = "2026-12-07"
# the date a change took effect (ISO, so that the strings sort as the dates) -> the names a
# config.json written before it gave tasks -> their names since, and whether a name in another
# look (the name, then one of LOOKS) is renamed too, its look kept
RENAMED: dict[str, tuple[dict[str, str], bool]] = {
    "2026-12-04": ({"maze-very-sparse": "maze-spot10-east", "maze-sparse": "maze-spot16-east"}, True),
    "2026-12-07": ({"melon": "melon-doom-motion", "melon-dmlab": "melon-dmlab-doom-motion",
                    "explore-goals": "explore-goals-doom-motion",
                    "explore-goals-paper": "explore-goals-paper-doom-motion"}, False),
}
# how a task name goes on when it names a task in another look (simjax.envs: MyWayHome's
# "-invented-looks" and "-flat-" names)
LOOKS = ("-invented-looks", "-flat-")
# a config.json without one of these settings was trained with this value
TRAINED_BEFORE_THE_FLAG = {"ec_beta": 0.5, "precision": "highest",  # precision: JAX's default, on CPUs float32
                           "learner": "a2c", "reward_clip": False, "bootstrap_time_limit": True,
                           "task_gamma": None, "task_advantage_weight": 1.0}  # one discount, one weight


def renamed(name: str, tasks_as_of: str | None = None) -> str:
    """Today's name of the task that a config.json naming its tasks as of ``tasks_as_of`` (None:
    written before any date was recorded) calls ``name``."""
    for date, (names, in_any_look) in sorted(RENAMED.items()):
        if tasks_as_of is not None and date <= tasks_as_of:
            continue
        for old, new in names.items():
            rest = name[len(old):]
            if name.startswith(old) and (rest == "" or in_any_look and rest.startswith(LOOKS)):
                name = new + rest
                break
    return name


def current_record(record: dict) -> dict:
    """config.json's contents (``record``, as read) as today's code reads them: a copy whose
    config has every setting it trained with and its task under today's name."""
    config = record.get("config")
    if not isinstance(config, dict):
        return record
    config = config | {k: v for k, v in TRAINED_BEFORE_THE_FLAG.items() if k not in config}
    if "env" in config:
        config["env"] = renamed(config["env"], record.get("tasks_as_of"))
    return {**record, "config": config, "tasks_as_of": max(record.get("tasks_as_of") or TASKS_AS_OF, TASKS_AS_OF)}
