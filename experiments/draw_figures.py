"""Draw the README's figures: the MyWayHome map from above and first-person frames.

    python experiments/draw_figures.py   # writes docs/mywayhome_topdown.png, docs/frames.png
"""

from __future__ import annotations

import math
from pathlib import Path

import jax.numpy as jnp
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from simjax.envs import make, mywayhome_map  # noqa: E402
from simjax.envs.motion import Pose  # noqa: E402
from simjax.envs.topdown import draw_topdown  # noqa: E402

DOCS = Path(__file__).resolve().parent.parent / "docs"

VIEWS = [  # (caption, x, y, heading in degrees)
    ("very sparse start (spot 10)", *mywayhome_map.SPAWN_SPOTS[10], 0.0),
    ("sparse start (spot 16)", *mywayhome_map.SPAWN_SPOTS[16], 0.0),
    ("corridor, facing north", 464.0, -300.0, 90.0),
    ("goal corridor, facing the goal", 1040.0, -200.0, -90.0),
]


def main():
    DOCS.mkdir(exist_ok=True)
    env = make("maze-dense")
    fig, ax = plt.subplots(figsize=(7, 6))
    draw_topdown(env.layout, ax=ax, title="MyWayHome (walls in their texture colours)")
    for caption, x, y, deg in VIEWS:
        ax.arrow(x, y, 30 * math.cos(math.radians(deg)), 30 * math.sin(math.radians(deg)), width=6, color="tab:red")
    for spot, (x, y) in mywayhome_map.SPAWN_SPOTS.items():
        ax.annotate(str(spot), (x, y), fontsize=6, xytext=(3, 3), textcoords="offset points")
    fig.tight_layout()
    fig.savefig(DOCS / "mywayhome_topdown.png", dpi=110)

    fig, axes = plt.subplots(1, len(VIEWS), figsize=(3 * len(VIEWS), 3.3))
    for ax, (caption, x, y, deg) in zip(axes, VIEWS):
        frame = env.render(Pose(jnp.array([x, y], jnp.float32), jnp.float32(math.radians(deg)), jnp.zeros(2)))
        ax.imshow(frame, interpolation="nearest")
        ax.set_title(caption, fontsize=8)
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(DOCS / "frames.png", dpi=110)
    print(f"wrote {DOCS / 'mywayhome_topdown.png'} and {DOCS / 'frames.png'}")


if __name__ == "__main__":
    main()
