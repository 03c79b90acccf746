"""Does a trained novelty model point the way out? Its error (the bonus before beta) on short
random walks from each of MyWayHome's 17 spawn spots, next to how often the run's own policy
came near each spot.

    python experiments/novelty_map.py RUN_DIR [--walks 16] [--steps 60]

For a run on a MyWayHome task (``simjax.envs.is_mywayhome``: any look) with a novelty model (sim,
rnd, icm, ec, e3b). From every spawn spot, ``--walks`` uniform random walks of ``--steps`` steps
(random headings) are scored by the run's novelty model (its checkpoint's, or its export's)
with its own running observation statistics; only transitions whose window lies wholly inside
the walk count. EC's error is its novelty beta - C(M, e) (the bonus before alpha), each walk
with an episodic memory of its own that starts with the walk's first frame, as an episode's
does; E3B's is its elliptical bonus b, each walk with a covariance of its own that starts with
the walk's first frame (so a spot scores how varied a walk from it looks, not how often the
policy has been there). The policy's side: 16 episodes per seed from the run's own task, and the fraction of them
that came within 96 units of each spot.

Prints per spot: distance from the run's start (its task's spawn spot; spot 10, the map's own
player start, for maze-dense, whose episodes start anywhere), the policy's visit
fraction, the mean error per seed and, for models with a fixed RND target (sim, rnd), the
target's *spread* there: half its summed variance over the walks' frames, which is the error
of a model that predicts the spot's mean target. A room whose spread is high pays a high
bonus at the same relative accuracy (the frames are normalised with the run's global running
statistics, so a room of bright walls over a dark floor is "louder"). Then per seed the
Spearman correlation between visit fraction and error. A model that has learnt where the policy has been scores rarely visited
spots higher (a negative correlation). Writes RUN_DIR/novelty_map.png: mean error per 32-unit
square of the walks, one panel per seed; and RUN_DIR/novelty_map.csv: the table above, one row
per spot and seed. The model is scored in float32 whatever the run's ``--precision``: two runs'
maps then differ by what their models learnt, not by how they are evaluated.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from precision_check import spearman  # noqa: E402
from trajectories import episodes, first_episode  # noqa: E402

from simjax.envs import is_mywayhome, mywayhome_spot, random_walks  # noqa: E402
from simjax.envs.doom import mywayhome_map  # noqa: E402
from simjax.novelty.base import Timeline, build_timeline, init_memory, normalize_frames, spread  # noqa: E402
from simjax.novelty.networks import RNDTarget  # noqa: E402
from simjax.runs import restore  # noqa: E402

NEAR = 96.0  # units: "came near a spot"
CELL = 32.0  # units: the map's squares


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", type=Path)
    parser.add_argument("--walks", type=int, default=16, help="random walks per spawn spot")
    parser.add_argument("--steps", type=int, default=60, help="steps per walk")
    args = parser.parse_args(argv)
    try:
        restored = restore(args.run)
    except FileNotFoundError as err:
        parser.error(str(err))
    config = restored.config
    if not is_mywayhome(config.env) or config.algo == "a2c":
        parser.error("needs a run on a MyWayHome task (maze-dense, -sparse, -very-sparse, ..., in any look) "
                     "with a novelty model (sim, rnd, icm, ec)")
    trainer = restored.trainer
    model = trainer.novelty.model
    if args.steps <= model.history + 1:
        parser.error(f"--steps must exceed the model's window ({model.history + 1} frames)")
    novelty_params, obs_stats = restored.novelty()  # every seed's; the export has them without the checkpoint

    spots = sorted(mywayhome_map.SPAWN_SPOTS)
    xy = np.asarray([mywayhome_map.SPAWN_SPOTS[s] for s in spots])
    # the policy's side: which spots its own episodes come near
    env = restored.env
    one_spot = env.layout.spawns.shape[0] == 1
    start = np.asarray(env.layout.spawns[0] if one_spot else mywayhome_map.SPAWN_SPOTS[10])
    policy_run = jax.jit(lambda p, k: episodes(env, trainer.network, p, k, 16))
    visits = []
    for i in range(config.num_seeds):
        params = restored.policy(i)
        pos, alive, _ = jax.device_get(policy_run(params, jax.random.PRNGKey(123)))
        near = np.zeros(len(spots))
        for n in range(pos.shape[1]):
            p = first_episode(pos, alive, n)
            near += (np.linalg.norm(p[:, None] - xy[None], axis=-1).min(axis=0) < NEAR)
        visits.append(near / pos.shape[1])

    # the model's side: error on random walks from every spot, with the run's frame statistics,
    # drawn and moved as the run's own world draws and moves them
    obs, actions, last_obs, pos, ends = [], [], [], [], []
    for j, s in enumerate(spots):
        walk_env = mywayhome_spot(env, s)
        o, a, lo, p, d = jax.jit(lambda k, e=walk_env: random_walks(e, k, args.walks, args.steps))(
            jax.random.PRNGKey(1000 + j))
        obs.append(o), actions.append(a), last_obs.append(lo), pos.append(p), ends.append(d)
    obs, actions = jnp.concatenate(obs, axis=1), jnp.concatenate(actions, axis=1)
    last_obs, pos = jnp.concatenate(last_obs, axis=0), np.concatenate(pos, axis=1)
    # a walk that touches the goal ends its episode: it counts up to the step before
    ongoing = np.cumsum(np.concatenate(ends, axis=1), axis=0) == 0
    n = obs.shape[1]
    reset = jnp.zeros(actions.shape, bool).at[0].set(True)
    memory = init_memory(model.history, n, obs.shape[2:], obs.dtype)
    walks, _ = build_timeline(memory, obs, reset, actions, last_obs, jnp.zeros((n,), bool))
    full = np.arange(args.steps) >= model.history  # the whole window lies in the walk

    has_target = "target" in novelty_params and getattr(model, "target", "rnd") == "rnd"

    @jax.jit
    def score(params, obs_stats, frames, actions, segment, valid):  # the walks as arguments, not constants XLA would fold
        tl = Timeline(frames, actions, segment, valid, history=model.history)
        x = normalize_frames(tl.frames, obs_stats if config.obs_norm else None)
        if getattr(model, "stateful", False):  # EC, E3B: each walk its own episodic state, holding the walk's first frame
            state = model.init_state(params, tl.frames[tl.history], jax.random.PRNGKey(7))
            error, scored, _, _, _ = model.apply_with_state(params, state, tl, x)
        else:
            error, scored, _, _ = model.apply(params, tl, x)
        target = RNDTarget().apply(params["target"], x[tl.history + 1 :]) if has_target else None
        return error, scored, target

    errors, spreads = [], []
    for i in range(config.num_seeds):
        params, stats = jax.tree.map(lambda x, i=i: x[i], (novelty_params, obs_stats))
        error, scored, target = jax.device_get(score(params, stats, walks.frames, walks.actions, walks.segment, walks.valid))
        mask = np.asarray(scored) & full[:, None] & ongoing
        errors.append((np.asarray(error), mask))
        if has_target:  # half the target's summed variance over each spot's scored frames
            t = np.asarray(target).reshape(args.steps, len(spots), args.walks, -1)
            m = mask.reshape(args.steps, len(spots), args.walks)
            spreads.append(np.asarray([spread(t[:, j][m[:, j]]) for j in range(len(spots))]))

    seeds = restored.seeds
    print(f"{args.run.name} at {restored.env_steps:,} agent steps per seed; {args.walks} random walks "
          f"of {args.steps} steps per spot; visits: share of 16 policy episodes within {NEAR:.0f} units")
    header = "spot  from start  " + "  ".join(
        f"visits s{s}  error s{s}" + (f"  spread s{s}" if has_target else "") for s in seeds)
    print(header)
    per_spot = []
    for error, mask in errors:
        e = error.reshape(args.steps, len(spots), args.walks)
        m = mask.reshape(args.steps, len(spots), args.walks)
        per_spot.append(np.asarray([e[:, j][m[:, j]].mean() for j in range(len(spots))]))
    for j, s in enumerate(spots):
        dist = np.linalg.norm(xy[j] - start)
        cols = "  ".join(f"{visits[i][j]:9.2f}  {per_spot[i][j]:8.3f}"
                         + (f"  {spreads[i][j]:9.2f}" if has_target else "") for i in range(len(seeds)))
        print(f"{s:4d}  {dist:10.0f}  {cols}")
    for i, s in enumerate(seeds):
        dist = np.linalg.norm(xy - start, axis=1)
        print(f"seed {s}: Spearman(visits, error) {spearman(visits[i], per_spot[i]):+.2f}, "
              f"Spearman(distance from start, error) {spearman(dist, per_spot[i]):+.2f}")
    table = args.run / "novelty_map.csv"  # the numbers above, for comparing runs (experiments/precision_check.py)
    with open(table, "w") as f:
        f.write("spot,seed,visits,error" + (",spread" if has_target else "") + "\n")
        for i, seed in enumerate(seeds):
            for j, s in enumerate(spots):
                f.write(f"{s},{seed},{visits[i][j]:.6g},{per_spot[i][j]:.6g}"
                        + (f",{spreads[i][j]:.6g}" if has_target else "") + "\n")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from simjax.envs.topdown import draw_topdown

    x0, y0, x1, y1 = mywayhome_map.BBOX
    shape = (int(np.ceil((y1 - y0) / CELL)), int(np.ceil((x1 - x0) / CELL)))
    target_pos = pos[1:]  # the error of step t belongs to the frame it led to
    fig, axes = plt.subplots(1, len(seeds), figsize=(7 * len(seeds), 6.5), squeeze=False)
    for ax, seed, (error, mask) in zip(axes[0], seeds, errors):
        cells = np.floor((target_pos[mask] - np.asarray([x0, y0])) / CELL).astype(int)
        grid_sum, grid_n = np.zeros(shape), np.zeros(shape)
        np.add.at(grid_sum, (cells[:, 1], cells[:, 0]), error[mask])
        np.add.at(grid_n, (cells[:, 1], cells[:, 0]), 1)
        grid = np.where(grid_n > 0, grid_sum / np.maximum(grid_n, 1), np.nan)
        image = ax.imshow(grid, origin="lower", cmap="viridis",
                          extent=(x0, x0 + shape[1] * CELL, y0, y0 + shape[0] * CELL))
        draw_topdown(env.layout, ax=ax,
                     title=f"{args.run.name}, seed {seed}: novelty error on random walks")
        fig.colorbar(image, ax=ax, label="error (bonus / beta)", orientation="horizontal", shrink=0.6, pad=0.03)
    fig.tight_layout()
    out = args.run / "novelty_map.png"
    fig.savefig(out, dpi=100)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
