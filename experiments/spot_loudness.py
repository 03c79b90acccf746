"""Where on MyWayHome does a random-network target pay most for nothing new? The spread of the
RND target (SIM's and RND's prediction target) over random walks from each of the map's 17
spawn spots, in each of its two worlds and through both of the novelty models' frame pipelines.

    python experiments/spot_loudness.py [--walks 16] [--steps 40] [--targets 4] [--worlds A,B,...]
        [--assets NPZ] [--slopes 0.01,0.2]

*Spread* is half the summed variance of the target's 64 outputs over a set of frames: the error
of a model that predicts their mean target, averaged over ``--targets`` random targets. A
prediction-error bonus pays about (1 - the model's relative accuracy) times the spread where
the agent is, so a loud spot keeps paying after it has long stopped being new, and a quiet one
pays little even before it has been seen.

Worlds: MyWayHome as ViZDoom draws it (``maze-dense``) and with the invented looks
(``maze-dense-invented-looks``), or the MyWayHome tasks ``--worlds`` names (e.g. a
``maze-dense-flat-...`` world, ``simjax.envs``); the same walks (keys, actions, motion) in all.
``--assets NPZ`` adds ``maze-dense`` drawn from another conversion of Freedoom's graphics
(``tools/freedoom_assets.py --iwad FREEDOOM2.WAD --out NPZ``: another freedoom2.wad's textures,
palette and light tables on the same map), labelled with the file's name, and prints how each
wall texture's contrast differs between the two. Pipelines:
``norm``, the runs' default (``--obs-norm true``): frames normalised per pixel by the
statistics of all the walks' frames of that world together, as a run's running statistics
would be; ``raw``: pixels / 255 (``--obs-norm false``); ``grey``: the mean of the three channels
/ 255, as ICM's preprocessing and the original ICM code's 42x42 grey frames (fed to the target
as three equal channels).

Prints per spot: its distance to the goal and the spread in each (world, pipeline), then per
column the ratio of the loudest spot to the quietest and the rank of spot 26, the last spot
before the goal (1 = loudest of the 17).

``--slopes``: the target's leaky-ReLU slope below zero, one column set per slope (the runs use
flax's 0.01; RND's code, TensorFlow's default 0.2). With more than one, it also prints, per
(world, pipeline), Spearman's rank correlation of the 17 spots' spreads between the first slope
and each other, and the spots that move most in rank: whether the slope reorders the spots.

``--per-texture``: which of the map's wall textures make a spot loud. ViZDoom's look through
the runs' default pipeline (``norm``, its statistics recomputed for each world), once as it is
and once per texture with that texture's texels replaced by their mean colour (its light,
geometry and offsets unchanged); prints the spread at the spots SIM's episodes pass and end
in and at spot 26, the loudest over the quietest spot, spot 26's rank and the quietest spot; and
the texture's contrast: the standard deviation of its texels' grey level and of its columns'
mean grey level (a pattern that changes as the view pans).
"""

from __future__ import annotations

import argparse
import copy
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from precision_check import ranks, spearman  # noqa: E402

from simjax.envs import FLAT_MARK, check_name, is_mywayhome, make, mywayhome_base, mywayhome_look, mywayhome_spot, random_walks  # noqa: E402
from simjax.envs.doom import mywayhome_map  # noqa: E402
from simjax.novelty.base import RunningMeanStd, normalize_frames, spread, to_unit  # noqa: E402
from simjax.novelty.networks import RNDTarget  # noqa: E402

WORLDS = ("maze-dense", "maze-dense-invented-looks")
GOAL_SPOT = 26  # the spot nearest the goal, at the head of its corridor


def drawn_from(env, assets: Path):
    """``env`` (ViZDoom's look) drawn from the Freedoom graphics in ``assets`` (an .npz)."""
    from simjax.envs.doom import doom_assets

    out = copy.copy(env)
    out.look = mywayhome_look(env.layout, doom_assets.load(assets))
    out.label = assets.stem
    return out


def compare_textures(assets: Path) -> None:
    """Per wall texture of the map: whether ``assets`` has the packaged texels, and both
    versions' contrast (std of the texels' grey level and of the columns' mean grey level)."""
    from simjax.envs.doom import doom_assets

    other, ours = doom_assets.load(assets), doom_assets.load()
    print(f"texture   same texels  texel grey std {assets.stem} / packaged  column-mean grey std  mean grey")
    for name in mywayhome_map.TEXTURE_NAMES:
        a, b = (np.asarray(x[f"wall_{name}"], np.float64).mean(-1) for x in (other, ours))
        same = a.shape == b.shape and np.array_equal(a, b)
        print(f"{name:9s} {str(same):>11s}  {a.std():16.1f} / {b.std():5.1f}  {a.mean(0).std():14.1f} / {b.mean(0).std():5.1f}"
              f"  {a.mean():5.1f} / {b.mean():5.1f}")


def look_name(task) -> str:
    """``task``'s look: what its name adds to its MyWayHome task's ('ViZDoom look' for none)."""
    if not isinstance(task, str):
        return task.label
    return task[len(mywayhome_base(task)) + 1:] or "ViZDoom look"


def world_frames(task, spots, walks: int, steps: int) -> list:
    """Per spot: the frames (walks * steps, 42, 42, 3) of ``walks`` random walks from it in
    ``task`` (a task name or an env)."""
    one_spot = mywayhome_spot(make(task) if isinstance(task, str) else task, spots[0])

    @jax.jit
    def frames(spawn, key):  # one compiled program for every spot: the spawn point is traced
        walk_env = copy.copy(one_spot)
        walk_env.layout = one_spot.layout._replace(spawns=spawn[None])
        obs, *_ = random_walks(walk_env, key, walks, steps)
        return obs.reshape((-1,) + obs.shape[2:])

    return [frames(jnp.asarray(mywayhome_map.SPAWN_SPOTS[s], jnp.float32), jax.random.PRNGKey(50 + j))
            for j, s in enumerate(spots)]


def per_texture(args, spots, targets, apply) -> None:
    from simjax.envs.doom import doom_assets

    def grey(texture):  # (H, W) the texture's texels, mean of R, G, B, 0..255
        return np.asarray(assets[f"wall_{texture}"], np.float64).mean(-1)

    shown = (24, 22, 16, GOAL_SPOT)
    print(f"ViZDoom's look, normalised per pixel; spread of the RND target (mean of {args.targets} random targets) over "
          f"{args.walks} random walks of {args.steps} steps per spot, each texture in turn replaced by its mean colour")
    print("flattened   " + "".join(f"spot {s}".rjust(9) for s in shown)
          + "  max/min  rank of 26  quietest  texels' grey std  column means' std")
    assets = doom_assets.load()
    for texture in (None, *mywayhome_map.TEXTURE_NAMES):
        world = WORLDS[0] if texture is None else f"{WORLDS[0]}{FLAT_MARK}{texture}"  # the flat-textures task
        frames = world_frames(world, spots, args.walks, args.steps)
        stats = RunningMeanStd.create(frames[0].shape[1:]).update(jnp.concatenate(frames))
        v = np.asarray([np.mean([spread(apply(p, normalize_frames(f, stats))) for p in targets]) for f in frames])
        rank = int((v > v[spots.index(GOAL_SPOT)]).sum()) + 1
        ratio = v.max() / max(v.min(), 1e-12)  # a spot that sees nothing but the flattened texture is near 0
        print(f"{texture or 'none':10s}  " + "".join(f"{v[spots.index(s)]:9.2f}" for s in shown)
              + (f"  {ratio:7.1f}" if ratio < 1e4 else "    >1e4") + f"  {rank:10d}  {spots[int(v.argmin())]:8d}"
              + ("" if texture is None else f"  {grey(texture).std():16.1f}  {grey(texture).mean(0).std():17.1f}"))


def reordered(columns: dict, spots: list, slopes: list) -> None:
    """Per (world, pipeline): Spearman between the first slope's spot ranking and each other's,
    and the spots whose rank moves most."""
    print(f"does the slope reorder the spots? Spearman of the spots' spreads against slope {slopes[0]:g}")
    for (look, pipe, v), other in columns.items():
        if v == slopes[0]:
            continue
        base = columns[(look, pipe, slopes[0])]
        moved = ranks(other) - ranks(base)
        top = np.argsort(-np.abs(moved), kind="stable")[:3]
        print(f"  {look}, {pipe}: slope {v:g}: Spearman {spearman(base, other):.3f}; loudest {spots[int(base.argmax())]}"
              f" -> {spots[int(other.argmax())]}; spread x{np.median(other / base):.2f} (median); moved most: "
              + ", ".join(f"spot {spots[i]} {ranks(base)[i]}->{ranks(other)[i]}" for i in top))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--walks", type=int, default=16, help="random walks per spot")
    parser.add_argument("--steps", type=int, default=40, help="steps per walk")
    parser.add_argument("--targets", type=int, default=4, help="random targets to average over")
    parser.add_argument("--per-texture", action="store_true", help="each wall texture's part in the spread (see above)")
    parser.add_argument("--worlds", default=",".join(WORLDS), help="MyWayHome tasks to compare, comma-separated")
    parser.add_argument("--assets", type=Path, help="also maze-dense drawn from this .npz of Freedoom's graphics")
    parser.add_argument("--slopes", default="0.01",
                        help="the target's leaky-ReLU slopes, comma-separated (the runs: 0.01; RND's code: 0.2)")
    args = parser.parse_args(argv)
    try:
        slopes = [float(v) for v in args.slopes.split(",")]
    except ValueError:
        parser.error(f"--slopes: not numbers: {args.slopes!r}")
    if any(not 0.0 <= v < 1.0 for v in slopes) or len(set(slopes)) != len(slopes):
        parser.error(f"--slopes: need distinct slopes in [0, 1), got {args.slopes!r}")
    if args.per_texture and len(slopes) > 1:
        parser.error("--per-texture takes one slope")
    if min(args.walks, args.steps, args.targets) < 1:
        parser.error("need --walks, --steps and --targets >= 1")
    worlds = args.worlds.split(",")
    for task in worlds:
        try:
            check_name(task)
        except ValueError as err:
            parser.error(str(err))
        if not is_mywayhome(task):
            parser.error(f"--worlds: {task!r} is not a MyWayHome task")
    if args.assets is not None and not args.assets.is_file():
        parser.error(f"--assets: no file {args.assets}")
    start = time.time()
    spots = sorted(mywayhome_map.SPAWN_SPOTS)
    # the slope has no parameters: the same random targets under each slope
    targets = [RNDTarget().init(jax.random.PRNGKey(100 + i), jnp.zeros((1, 42, 42, 3))) for i in range(args.targets)]
    applies = {v: jax.jit(lambda params, x, v=v: RNDTarget(leaky_slope=v).apply(params, x)) for v in slopes}
    if args.per_texture:
        per_texture(args, spots, targets, applies[slopes[0]])
        print(f"({time.time() - start:.0f} s)")
        return 0

    columns = {}
    if args.assets is not None:
        worlds.append(drawn_from(make("maze-dense"), args.assets))
    for task in worlds:
        frames = world_frames(task, spots, args.walks, args.steps)
        stack = jnp.concatenate(frames)
        stats = RunningMeanStd.create(stack.shape[1:]).update(stack)
        pipelines = {"norm": lambda f, st=stats: normalize_frames(f, st), "raw": lambda f: normalize_frames(f, None),
                     "grey": lambda f: jnp.repeat(to_unit(f).mean(-1, keepdims=True), 3, axis=-1)}
        for name, pipeline in pipelines.items():
            for v, apply in applies.items():
                columns[(look_name(task), name, v)] = np.asarray(
                    [np.mean([spread(apply(p, pipeline(f))) for p in targets]) for f in frames])

    goal = np.asarray(mywayhome_map.GOAL_XY)
    print(f"spread of the RND target (half its summed variance, mean of {args.targets} random targets) over "
          f"{args.walks} random walks of {args.steps} steps from each spawn spot")
    print("spot  to goal  " + "  ".join(
        (f"{t}, {p}" + (f", {v:g}" if len(slopes) > 1 else "")).rjust(24) for t, p, v in columns))
    for j, s in enumerate(spots):
        dist = np.linalg.norm(np.asarray(mywayhome_map.SPAWN_SPOTS[s]) - goal)
        print(f"{s:4d}  {dist:7.0f}  " + "  ".join(f"{v[j]:24.3f}" for v in columns.values()))
    g = spots.index(GOAL_SPOT)
    print("max/min       " + "  ".join(f"{v.max() / v.min():24.1f}" for v in columns.values()))
    print(f"rank of {GOAL_SPOT}    " + "  ".join(f"{int((v > v[g]).sum()) + 1:24d}" for v in columns.values()))
    if len(slopes) > 1:
        reordered(columns, spots, slopes)
    if args.assets is not None:
        compare_textures(args.assets)
    print(f"({time.time() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
