"""Top-down drawing of a layout for people: walls in their texture's colour, spawns, items, agent."""

from __future__ import annotations

import math

import numpy as np

from simjax.envs import raycaster
from simjax.envs.maze import Layout

_ITEM_MARKERS = {raycaster.GOAL: ("*", 220, "goal"), raycaster.APPLE: ("o", 60, "apple (+1)"),
                 raycaster.LEMON: ("o", 60, "lemon (-1)"), raycaster.MELON: ("o", 160, "melon (+20)")}


def wall_colours(env) -> np.ndarray | None:
    """(T, 3) the colour of each wall texture index of ``env``'s look where it has its own (a
    DMLab look: each surface's mean colour), else None (``raycaster.TEXTURE_LOOKS``)."""
    return getattr(getattr(env, "look", None), "wall_rgb", None)


def draw_topdown(layout: Layout, ax=None, pose=None, trajectory=None, title: str | None = None,
                 spawns: bool = True, colours=None):
    """Draw ``layout`` on a matplotlib axis (made if not given) and return the axis.

    Walls take ``colours[texture]`` ((T, 3), e.g. ``wall_colours(env)``), by default their
    invented look's base colour (``raycaster.TEXTURE_LOOKS``).

    ``pose`` is an optional (x, y, heading) drawn as an arrow; ``trajectory`` an optional
    (K, 2) array of positions drawn as a line.
    """
    import matplotlib

    if ax is None:
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(6, 5))
    start, end = np.asarray(layout.walls.start), np.asarray(layout.walls.end)
    tex = np.asarray(layout.walls.texture)
    standing = layout.walls.standing()
    if colours is None:
        colours = [look[0] for look in raycaster.TEXTURE_LOOKS]
    for (x1, y1), (x2, y2), t in zip(start[standing], end[standing], tex[standing]):
        ax.plot([x1, x2], [y1, y2], color=tuple(float(c) for c in colours[t]), linewidth=3, solid_capstyle="butt")
    if spawns:
        xy = np.asarray(layout.spawns)
        ax.scatter(xy[:, 0], xy[:, 1], marker="x", color="tab:blue", s=25, label="spawn spots", zorder=3)
    items = layout.items
    pos, look = np.asarray(items.pos), np.asarray(items.look)
    for k in sorted(set(look.tolist())):
        at = pos[look == k]
        marker, size, name = _ITEM_MARKERS[k]
        ax.scatter(at[:, 0], at[:, 1], marker=marker, color=raycaster.SPRITE_LOOKS[k][0], edgecolor="black",
                   s=size, label=name, zorder=4)
    if trajectory is not None:
        traj = np.asarray(trajectory)
        ax.plot(traj[:, 0], traj[:, 1], color="tab:red", linewidth=1, alpha=0.7, label="trajectory")
    if pose is not None:
        x, y, h = (float(v) for v in pose)
        ax.arrow(x, y, 30 * math.cos(h), 30 * math.sin(h), width=6, color="tab:red", zorder=5)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    if title:
        ax.set_title(title, fontsize=9)
    return ax
