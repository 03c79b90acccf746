"""Draw the pictures of the worlds (README, docs/worlds.md): maps from above and first-person frames.

    python experiments/draw_figures.py
writes docs/mywayhome_topdown.png, docs/frames.png (MyWayHome), docs/melon.png (the melon map
and five views), docs/explore_goals.png (three generated mazes from above, each with the
agent's first frame) and docs/task_frames.png (one first-person frame from each task).
"""

from __future__ import annotations

import math
from pathlib import Path

import jax
import jax.numpy as jnp
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from simjax.envs import make  # noqa: E402
from simjax.envs.dmlab import melon  # noqa: E402
from simjax.envs.doom import mywayhome_map  # noqa: E402
from simjax.envs.doom.motion import Pose  # noqa: E402
from simjax.envs.topdown import draw_topdown, wall_colours  # noqa: E402

DOCS = Path(__file__).resolve().parent.parent / "docs"

VIEWS = [  # (caption, x, y, heading in degrees)
    ("sparse start (spot 10, facing east)", *mywayhome_map.SPAWN_SPOTS[10], 0.0),
    ("very sparse start (spot 15, facing west)", *mywayhome_map.SPAWN_SPOTS[15], 180.0),
    ("corridor, facing north", 464.0, -300.0, 90.0),
    ("goal corridor, facing the goal", 1040.0, -200.0, -90.0),
]


def main():
    DOCS.mkdir(exist_ok=True)
    env = make("maze-dense")
    fig, ax = plt.subplots(figsize=(7, 6))
    draw_topdown(env.layout, ax=ax, title="MyWayHome (one colour per wall texture)")
    for _caption, x, y, deg in VIEWS:
        ax.arrow(x, y, 30 * math.cos(math.radians(deg)), 30 * math.sin(math.radians(deg)), width=6, color="tab:red")
    for spot, (x, y) in mywayhome_map.SPAWN_SPOTS.items():
        ax.annotate(str(spot), (x, y), fontsize=6, xytext=(3, 3), textcoords="offset points")
    fig.tight_layout()
    fig.savefig(DOCS / "mywayhome_topdown.png", dpi=110)

    fig, axes = plt.subplots(1, len(VIEWS), figsize=(3 * len(VIEWS), 3.3))
    for ax, (caption, x, y, deg) in zip(axes, VIEWS):
        frame = env.render(Pose.at(jnp.array([x, y], jnp.float32), jnp.float32(math.radians(deg))))
        ax.imshow(frame, interpolation="nearest")
        ax.set_title(caption, fontsize=8)
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(DOCS / "frames.png", dpi=110)
    print(f"wrote {DOCS / 'mywayhome_topdown.png'} and {DOCS / 'frames.png'}")
    draw_melon()
    draw_explore_goals()
    draw_task_frames()


def _pose(x, y, deg):
    return Pose.at(jnp.array([x, y], jnp.float32), jnp.float32(math.radians(deg)))


MELON_VIEWS = [  # (caption, x, y, heading in degrees)
    ("start, facing north (the block)", *melon.START_XY, 90.0),
    ("turned east: 14 apples", 40.0, -480.0, 0.0),
    ("turned west: the lemon, the stairs", -40.0, -480.0, 180.0),
    ("up the stairs: the melon", -480.0, 480.0, 0.0),
    ("the apples' end: the cliff", 300.0, 480.0, 180.0),
]


def draw_melon():
    env = make("melon")
    fig, axes = plt.subplots(1, 1 + len(MELON_VIEWS), figsize=(3.2 * (1 + len(MELON_VIEWS)), 3.4),
                             gridspec_kw={"width_ratios": [1.6] + [1] * len(MELON_VIEWS)})
    draw_topdown(env.layout, ax=axes[0], title="melon (Stairway to Melon)", colours=wall_colours(env))
    for ax, (caption, x, y, deg) in zip(axes[1:], MELON_VIEWS):
        ax.imshow(env.render(_pose(x, y, deg)), interpolation="nearest")
        ax.set_title(caption, fontsize=8)
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(DOCS / "melon.png", dpi=110)
    print(f"wrote {DOCS / 'melon.png'}")


def draw_explore_goals(seeds=(0, 1, 2)):
    env = make("explore-goals")
    fig, axes = plt.subplots(2, len(seeds), figsize=(3.6 * len(seeds), 7), gridspec_kw={"height_ratios": [1.3, 1]})
    for col, seed in enumerate(seeds):
        state = jax.jit(env.reset)(jax.random.PRNGKey(seed))
        ms = state.pipeline_state
        x, y = (float(v) for v in ms.pose.pos)
        world = ms.world._replace(spawns=ms.world.spawns[ms.world.spawns[:, 0] < 1e8])  # the rooms' 'P' cells
        draw_topdown(world, ax=axes[0, col], pose=(x, y, float(ms.pose.heading)),
                     title=f"explore-goals (DMLab's maze), key {seed}", colours=wall_colours(env))
        if col < len(seeds) - 1:
            axes[0, col].get_legend().remove()
        axes[1, col].imshow(state.obs, interpolation="nearest")
        axes[1, col].set_title("the agent's first frame", fontsize=8)
        axes[1, col].axis("off")
    fig.tight_layout()
    fig.savefig(DOCS / "explore_goals.png", dpi=110)
    print(f"wrote {DOCS / 'explore_goals.png'}")


def draw_task_frames():
    tasks = [("maze-very-sparse", "maze-very-sparse: a start"),
             ("melon", "melon: the start"),
             ("explore-goals", "explore-goals: a start")]
    fig, axes = plt.subplots(1, len(tasks), figsize=(3 * len(tasks), 3.3))
    for ax, (task, caption) in zip(axes, tasks):
        ax.imshow(jax.jit(make(task).reset)(jax.random.PRNGKey(3)).obs, interpolation="nearest")
        ax.set_title(caption, fontsize=8)
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(DOCS / "task_frames.png", dpi=110)
    print(f"wrote {DOCS / 'task_frames.png'}")


if __name__ == "__main__":
    main()
