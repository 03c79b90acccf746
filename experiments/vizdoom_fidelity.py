"""The fidelity table and side-by-side figure of docs/worlds.md: simjax's MyWayHome against real ViZDoom.

    python experiments/vizdoom_fidelity.py [--walks 64] [--steps 100] [--first-seed 0]

Plays seeded uniform-random walks in ViZDoom (``simjax.envs.doom.fidelity``), replays them in
simjax from the same start, and writes ``experiments/results/vizdoom-fidelity/summary.json``
(heading error, position error after 25 and 100 steps, per-pixel difference of the 42x42
frames at the same poses, depth agreement), and ``docs/vizdoom_side_by_side.png``: the same
poses in both worlds. The per-pixel difference is also given for simjax's invented looks
(``raycaster``, the world before the Freedoom textures) at the same poses.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from simjax.envs import make, mywayhome_layout  # noqa: E402
from simjax.envs.doom import fidelity, vizdoom_ref  # noqa: E402
from simjax.envs.doom.motion import Pose  # noqa: E402
from simjax.envs.maze import MazeEnv, MazeTask  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--walks", type=int, default=64)
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=ROOT / "experiments" / "results" / "vizdoom-fidelity")
    args = parser.parse_args()
    t0 = time.time()
    env = make("maze-dense")
    walks = fidelity.viz_walks(args.walks, args.steps, args.first_seed)
    motion_err = fidelity.motion_errors(walks, fidelity.replay(env, walks))
    frame_err = fidelity.frame_and_depth_errors(env, walks, every=5)
    summary = fidelity.summary(walks, motion_err, frame_err)

    invented = MazeEnv(mywayhome_layout(), MazeTask("invented-looks"))
    render = jax.jit(jax.vmap(lambda p, h: invented.render(Pose.at(p, h))))
    xy = jnp.asarray(np.stack([p[0] for p in frame_err["poses"]]), jnp.float32)
    heading = jnp.asarray(np.radians([p[1] for p in frame_err["poses"]]), jnp.float32)
    old = np.abs(np.asarray(render(xy, heading), np.float64) - frame_err["theirs"]).mean()
    summary.update({
        "steps": args.steps, "first_seed": args.first_seed, "frames_compared": len(frame_err["poses"]),
        "pixel_mae_invented_looks": float(old), "pixel_mae_p95": float(np.percentile(frame_err["pixel_mae"], 95)),
        "vizdoom": vizdoom_ref.vzd.__version__,
        "date": time.strftime("%Y-%m-%d"), "seconds": round(time.time() - t0, 1),
        "command": f"python experiments/vizdoom_fidelity.py --walks {args.walks} --steps {args.steps} "
                   f"--first-seed {args.first_seed}",
    })
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(json.dumps(summary, indent=2))
    draw(walks, env, invented, ROOT / "docs" / "vizdoom_side_by_side.png")


def draw(walks, env, invented, path: Path, count: int = 6):
    """ViZDoom's 160x120 frame, the same area-averaged to 42x42, simjax's frame and the
    invented looks, at the start poses of the first ``count`` walks."""
    fig, axes = plt.subplots(4, count, figsize=(2.2 * count, 7.2))
    rows = ("ViZDoom 160x120", "ViZDoom, area-averaged to 42x42", "simjax (Freedoom textures)", "simjax, invented looks")
    for j, w in enumerate(walks[:count]):
        t = min(20, len(w["frames"]) - 1)
        pose = Pose.at(jnp.asarray(w["xy"][t], jnp.float32), jnp.float32(math.radians(w["angle_deg"][t])))
        images = (w["frames"][t], vizdoom_ref.resize42(w["frames"][t]), env.render(pose), invented.render(pose))
        for i, img in enumerate(images):
            axes[i, j].imshow(np.asarray(img), interpolation="nearest")
            axes[i, j].set_xticks([])
            axes[i, j].set_yticks([])
            if j == 0:
                axes[i, j].set_ylabel(rows[i], fontsize=7)
        axes[0, j].set_title(f"({w['xy'][t][0]:.0f}, {w['xy'][t][1]:.0f}), {w['angle_deg'][t]:.0f} deg", fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
