"""Task registry: ``make(name)`` builds any task by name.

MyWayHome (paper section 3.1, appendix B.1; the tasks in docs/worlds.md), each started as the
ICM code's scenario file starts it (``simjax.envs.doom.icm_scenarios``), which is where the paper
took its three settings from:
- ``maze-dense``: a uniformly random spot of the 17 and a uniformly random heading;
- ``maze-sparse``: always spot 10, the map's own player start in the far-left room, facing east
  with an angle drawn per episode from 0 to 3.6 degrees (Doom's angle units, as ACS draws it);
- ``maze-very-sparse``: always spot 15, the small room at the bottom of the map, facing west, 176.4
  to 183.6 degrees;
- ``maze-spot10-east`` and ``maze-spot16-east``: spot 10 or spot 16 facing exactly east, the
  starts that ``maze-very-sparse`` and ``maze-sparse`` had before 2026-12-04 (``simjax.config_history``:
  run folders written before then are read under these names), kept so those runs rebuild;
  spot 10 facing east is the paper's sparse start without its jitter, spot 16 no start of the paper's;
- ``maze-dense-invented-looks``, ``maze-sparse-invented-looks``, ... (any of the tasks above):
  the same tasks (map, spots, Doom's motion) drawn with ``raycaster``'s invented wall looks instead
  of Freedoom's textures and ViZDoom's light; a diagnostic world, to tell what the look does to
  learning from what the motion does, not one of the paper's;
- ``maze-very-sparse-flat-SILVER2-TLITE6_1`` (any of the tasks above, then ``-flat-`` and one or
  more of ``mywayhome_map.TEXTURE_NAMES`` joined by ``-``): ViZDoom's look with each named
  texture's texels replaced by their mean colour, its light, offsets and everything else as
  they are; a diagnostic world, to test which paint a novelty bonus follows, not one of the
  paper's;
- ``maze-tiny``: one 320x128 room with the goal 160 units from a fixed spot, random heading,
  50 steps; a seconds-long sanity check of the whole pipeline (used by the learning test).

The paper's other two worlds (``simjax.envs.dmlab.melon``, ``simjax.envs.dmlab.explore_goals``),
moving and picking up items as DeepMind Lab does (``simjax.envs.dmlab.pmove``) and drawn with
DeepMind Lab's textures, sky and item models (``simjax.envs.dmlab.look``):
- ``melon``: Stairway to Melon, apples (+1) down a dead end or a lemon (-1) on the way to the
  melon (+20, success); 525 steps, 3 actions (the paper's rules);
- ``melon-dmlab``: the same map under DMLab's level rules: the melon puts the agent back at the
  start with every fruit back and the episode goes on; 900 steps, 3 actions;
- ``explore-goals``: Explore Goal Locations Small as DeepMind Lab's level scripts have it: a new
  11x11 maze with up to 4 rooms every episode (DMLab's generator, ``simjax.envs.dmlab.dmlab_maze``),
  the goal fixed for the episode in a room, +10 per goal reached, then the agent alone
  respawns at a room's spawn point; 1350 steps, 3 actions;
- ``explore-goals-paper``: the paper's wording of it: a 9x9 maze without rooms, a new start and
  a new goal after each pickup; 1350 steps, 3 actions;
- ``melon-doom-motion``, ``melon-dmlab-doom-motion``, ``explore-goals-doom-motion`` and
  ``explore-goals-paper-doom-motion``: the same worlds as they were before 2026-12-07: moving
  and touching items with Doom's motion (``simjax.envs.doom.motion``, MyWayHome's) and drawn
  with ``raycaster``'s invented looks (``look="invented"``) instead of DMLab's
  (``simjax.config_history``: run folders written before then are read under these names),
  kept so those runs rebuild.

Any gymnax environment: ``gymnax:NAME`` (``simjax.envs.gymnax_adapter``), e.g.
``gymnax:CartPole-v1`` or ``gymnax:Breakout-MinAtar``.

Every env is a brax ``Env`` (``simjax.envs.base``) that auto-resets and reports its episodes
the same way (``simjax.envs.episodes``, which also holds ``rollout``, the stepping loop the
learner and the diagnostics share).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from simjax.envs.dmlab.explore_goals import ExploreGoalsEnv, ExploreGoalsPaperEnv
from simjax.envs.dmlab.melon import MelonLevelEnv, melon_env, melon_layout
from simjax.envs.doom import icm_scenarios, mywayhome_map
from simjax.envs.episodes import episode_metrics, given_actions, rollout, starts_episode, uniform_policy
from simjax.envs.maze import Layout, MazeEnv, MazeTask, goal_item, random_walks

GYMNAX_PREFIX = "gymnax:"


def mywayhome_layout(spawn_ids=None) -> Layout:
    ids = sorted(mywayhome_map.SPAWN_SPOTS) if spawn_ids is None else list(spawn_ids)
    spawn_xy = [mywayhome_map.SPAWN_SPOTS[i] for i in ids]
    return Layout.build(mywayhome_map.WALLS, [goal_item(mywayhome_map.GOAL_XY)], spawn_xy)


def mywayhome_look(layout: Layout, assets: dict | None = None, flat: tuple[str, ...] = ()):
    """MyWayHome's walls as ViZDoom draws them (Freedoom's textures, the map's x-offsets), from
    ``assets`` (default: the packaged ones), with each texture named in ``flat`` drawn as its
    texels' mean colour (its light, which Doom takes from the palette indices, unchanged)."""
    from simjax.envs.doom import doom_assets, doom_render

    assets = dict(doom_assets.load() if assets is None else assets)  # a copy: load() is cached
    for texture in flat:
        texels = np.asarray(assets[f"wall_{texture}"], np.float64)
        assets[f"wall_{texture}"] = np.broadcast_to(texels.mean((0, 1)), texels.shape)
    return doom_render.build_look(layout.walls, mywayhome_map.TEXTURE_NAMES, assets["wall_offset_x"],
                                  assets["wall_u_reversed"], assets=assets)


def _mywayhome(name: str, base: str, textured: bool = True, flat: tuple[str, ...] = ()) -> MazeEnv:
    """Task ``name``: MyWayHome started as task ``base`` (a key of _MYWAYHOME), in ViZDoom's look
    (with the ``flat`` textures painted their mean colour), or the invented looks."""
    spots, angles = _MYWAYHOME[base]
    rule = dict(random_heading=True) if angles is None else dict(random_heading=False, angle_range=angles)
    layout = mywayhome_layout(spots)
    return MazeEnv(layout, MazeTask(name, **rule), look=mywayhome_look(layout, flat=flat) if textured else None)


def mywayhome_spot(env: MazeEnv, spot: int) -> MazeEnv:
    """``env``'s world (its look, camera, motion and light) with every episode starting at
    MyWayHome's spawn spot ``spot``, facing a random way: for the diagnostics' walks."""
    return MazeEnv(mywayhome_layout([spot]), MazeTask(f"spot-{spot}", random_heading=True), camera=env.camera,
                   motion_params=env.motion_params, look=env.look, light=env.light)


def tiny_layout() -> Layout:
    room = [(0, 0, 320, 0, 8), (320, 0, 320, 128, 7), (320, 128, 0, 128, 8), (0, 128, 0, 0, 0)]
    return Layout.build(room, [goal_item((200.0, 64.0))], spawn_xy=[(40.0, 64.0)])


FLAT_MARK = "-flat-"


def _icm(start: icm_scenarios.EnterStart):
    """(spawn spots, angle range) of one of the ICM scenarios' fixed-spot starts."""
    low, high = start.spots
    if low != high:
        raise ValueError("only a fixed spot is a task's start here; dense draws a spot of all 17")
    return [low], start.angles


# MyWayHome's tasks: (spawn spots, None for all 17; Doom angle range, inclusive, or None for a
# uniformly random heading)
_MYWAYHOME = {
    "maze-dense": (None, None),
    "maze-sparse": _icm(icm_scenarios.SPARSE),
    "maze-very-sparse": _icm(icm_scenarios.VERY_SPARSE),
    "maze-spot10-east": ([10], (0, 0)),
    "maze-spot16-east": ([16], (0, 0)),
}
MYWAYHOME_TASKS = (*_MYWAYHOME, *(f"{name}-invented-looks" for name in _MYWAYHOME))


def mywayhome_base(name: str) -> str:
    """The MyWayHome task whose start task ``name`` has (``name`` without its look), e.g.
    ``maze-very-sparse`` for ``maze-very-sparse-flat-SILVER2``; a ValueError for another world."""
    base = name.removesuffix("-invented-looks").partition(FLAT_MARK)[0]
    if base not in _MYWAYHOME:
        raise ValueError(f"{name!r} is not a MyWayHome task")
    return base


def _mywayhome_task(name: str) -> Callable[[], MazeEnv]:
    """The builder of ``name``, one of MYWAYHOME_TASKS."""
    base = name.removesuffix("-invented-looks")
    return lambda: _mywayhome(name, base, textured=name == base)



def _flat_parts(name: str) -> tuple[str, tuple[str, ...]] | None:
    """(task, textures) of a ``TASK-flat-TEX1-TEX2`` name, None for any other name; a
    ValueError if the task is not one of MyWayHome's textured tasks or a texture is unknown."""
    base, mark, rest = name.partition(FLAT_MARK)
    if not mark:
        return None
    if base not in _MYWAYHOME:
        raise ValueError(f"{name!r}: only {', '.join(_MYWAYHOME)} can have flat textures, not {base!r}")
    textures = tuple(rest.split("-"))
    unknown = [t for t in textures if t not in mywayhome_map.TEXTURE_NAMES]
    if unknown or len(set(textures)) != len(textures):
        raise ValueError(f"{name!r}: after {FLAT_MARK!r}, distinct texture names joined by '-' "
                         f"({', '.join(mywayhome_map.TEXTURE_NAMES)}); got {', '.join(map(repr, textures))}")
    return base, textures


def is_mywayhome(name: str) -> bool:
    """Whether task ``name`` is MyWayHome (its map and spawn spots), in any look."""
    return name in MYWAYHOME_TASKS or name.partition(FLAT_MARK)[0] in _MYWAYHOME


_REGISTRY: dict[str, Callable[[], MazeEnv]] = {
    **{name: _mywayhome_task(name) for name in MYWAYHOME_TASKS},
    "maze-tiny": lambda: MazeEnv(tiny_layout(), MazeTask("maze-tiny", random_heading=True, max_steps=50)),
    "melon": melon_env,
    "melon-dmlab": MelonLevelEnv,
    "explore-goals": ExploreGoalsEnv,
    "explore-goals-paper": ExploreGoalsPaperEnv,
    "melon-doom-motion": lambda: melon_env(motion="doom", look="invented"),
    "melon-dmlab-doom-motion": lambda: MelonLevelEnv(motion="doom", look="invented"),
    "explore-goals-doom-motion": lambda: ExploreGoalsEnv(motion="doom", look="invented"),
    "explore-goals-paper-doom-motion": lambda: ExploreGoalsPaperEnv(motion="doom", look="invented"),
}

TASK_NAMES = tuple(_REGISTRY)


def check_name(name: str) -> None:
    """Raise a ValueError naming the known tasks if ``name`` is not one of them (for
    ``gymnax:NAME``, if gymnax is missing or does not know NAME)."""
    if name.startswith(GYMNAX_PREFIX):
        from simjax.envs.gymnax_adapter import check_gymnax_name

        check_gymnax_name(name[len(GYMNAX_PREFIX):])
    elif _flat_parts(name) is None and name not in _REGISTRY:
        raise ValueError(
            f"unknown task {name!r}; known tasks: {', '.join(TASK_NAMES)}, TASK{FLAT_MARK}TEXTURE[-TEXTURE...] "
            "for MyWayHome with flat textures, or gymnax:NAME for a gymnax environment"
        )


# tasks whose episodes always run to their step limit (no goal or death ends one early)
FIXED_LENGTH_TASKS = frozenset({"melon-dmlab", "explore-goals", "explore-goals-paper", "melon-dmlab-doom-motion",
                                "explore-goals-doom-motion", "explore-goals-paper-doom-motion"})


def episodes_end_early(name: str) -> bool:
    """Whether an episode of task ``name`` can end before its step limit (the maze-* goal, the
    melon; gymnax environments terminate on their own)."""
    check_name(name)
    return name not in FIXED_LENGTH_TASKS


def make(name: str):
    """Build the task registered under ``name``, or the gymnax environment ``gymnax:NAME``."""
    check_name(name)
    if name.startswith(GYMNAX_PREFIX):
        from simjax.envs.gymnax_adapter import GymnaxEnv

        return GymnaxEnv(name[len(GYMNAX_PREFIX):])
    flat = _flat_parts(name)
    if flat is not None:
        base, textures = flat
        return _mywayhome(name, base, flat=textures)
    return _REGISTRY[name]()


__all__ = ["make", "check_name", "TASK_NAMES", "MYWAYHOME_TASKS", "is_mywayhome", "mywayhome_base", "FLAT_MARK", "FIXED_LENGTH_TASKS",
           "episodes_end_early", "MazeEnv", "MazeTask",
           "Layout", "mywayhome_spot", "ExploreGoalsEnv", "ExploreGoalsPaperEnv", "mywayhome_layout", "tiny_layout", "melon_layout",
           "random_walks", "rollout", "given_actions", "starts_episode", "episode_metrics", "uniform_policy"]
