"""Does what a policy learnt in simjax hold in the real game? Evaluate a run's policy beside a
uniform random one, in ViZDoom's MyWayHome or in simjax's own env.

    python -m simjax.evaluate RUN --backend vizdoom --episodes 200 [--video FILE.gif]
    python -m simjax.evaluate RUN --backend simjax --episodes 200 [--all-seeds]

Both backends play the run's task (``config.env``) from its own starts until the goal is touched
or the 525-step limit (``--max-steps`` cuts episodes shorter, for smoke checks), and count the
successes and episode lengths of the policy (actions sampled from its distribution as in
training, ``--greedy`` for argmax; LSTM state carried through an episode) and of the uniform
random policy, over the same episode starts (the same seeds draw them). ``vizdoom`` plays the
real game one episode at a time, 4 tics a step (``simjax.envs.doom.vizdoom_ref``), showing the policy
the 160x120 frame area-averaged to 42x42, which is what simjax's renderer draws; it needs vizdoom
and one of the MyWayHome tasks. ``simjax`` plays all episodes at once (``jax.vmap`` over lanes,
``lax.scan`` over steps) and counts each lane's first episode.

Prints a table (success ratio with its 95% Wilson interval, mean episode length) and writes
``RUN/evaluate-<backend>.json`` (``-seedK`` added for runs of several seeds) with the numbers,
the command, the date, the versions and the run's step count at its checkpoint (or export/). On MyWayHome
it also says where the episodes end (each one's position before its last step): their mean
distance from the goal and how many end nearest each of the map's 17 spawn spots, so that a
policy that never succeeds can still be compared across the two backends.
"""

from __future__ import annotations

import argparse
import datetime as dt
import importlib.metadata
import json
import math
import shlex
import sys
from pathlib import Path

import numpy as np

from simjax import flags, runtime
from simjax.runs.folder import EXPORT, atomic_write, has_export, load_checkpoint, load_config, load_export, restore

BACKENDS = ("vizdoom", "simjax")
VIDEO_FRAMES = 150  # at most this many GIF frames per episode (longer episodes are subsampled)
VIEW_SCALE = 5  # the 42x42 view is drawn 210x210 in the GIF


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m simjax.evaluate", description=__doc__.split("\n\n")[0])
    parser.add_argument("run", type=Path, help="run folder (config.json, and checkpoint.msgpack or export/)")
    parser.add_argument("--backend", choices=BACKENDS, required=True,
                        help="vizdoom: the real game; simjax: simjax's own env")
    parser.add_argument("--episodes", type=flags.whole_number, default=200, help="policy episodes per seed (default 200)")
    parser.add_argument("--random-episodes", type=flags.whole_number, default=None,
                        help="uniform random policy episodes (default: --episodes; 0: none)")
    parser.add_argument("--max-steps", type=flags.whole_number, default=None,
                        help="cut episodes after this many steps (default: the task's limit, 525)")
    parser.add_argument("--seed-index", type=flags.whole_number, default=0, help="which of the run's seeds, 0-based (default 0)")
    parser.add_argument("--all-seeds", action="store_true", help="evaluate every seed of the run in turn")
    parser.add_argument("--eval-seed", type=flags.whole_number, default=0,
                        help="seed of the episode starts and of the actions (default 0)")
    parser.add_argument("--greedy", action="store_true", help="take the most likely action instead of sampling")
    parser.add_argument("--video", type=Path, default=None, help="write the first policy episodes as a GIF")
    parser.add_argument("--video-episodes", type=flags.whole_number, default=3, help="episodes in the GIF (default 3)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    return parser


def check_args(parser: argparse.ArgumentParser, args) -> tuple:
    """Every refusal, before anything compiles; returns (config, env, the env's step limit)."""
    if not args.run.is_dir():
        parser.error(f"{args.run}: no such run folder")
    try:
        config = load_config(args.run)
    except (FileNotFoundError, ValueError, TypeError) as err:
        parser.error(str(err))
    checkpointed = (args.run / "checkpoint.msgpack").exists()
    if not checkpointed and not has_export(args.run):
        parser.error(f"{args.run} has no checkpoint.msgpack and no {EXPORT}/: they are not kept in git (only config.json "
                     f"and metrics.csv are). Copy one from the machine that trained the run, or train it again "
                     f"with its own settings: python -m simjax.train --resume {args.run} (from step 0; this "
                     f"rewrites its metrics.csv)")
    if args.episodes < 1:
        parser.error(f"--episodes must be at least 1, got {args.episodes}")
    if args.random_episodes is not None and args.random_episodes < 0:
        parser.error(f"--random-episodes must be 0 or more, got {args.random_episodes}")
    if not 0 <= args.seed_index < config.num_seeds:
        parser.error(f"--seed-index must lie in [0, {config.num_seeds}): the run has {config.num_seeds} seed(s)")
    if args.video is not None and (args.video.suffix.lower() != ".gif" or args.video_episodes < 1):
        parser.error("--video needs a FILE.gif and --video-episodes of at least 1")
    if args.backend == "vizdoom":
        try:
            from simjax.envs.doom.vizdoom_ref import TASK_SCENARIOS
        except ImportError as err:
            parser.error(f"--backend vizdoom needs the vizdoom package ({err}); pip install -e '.[test]'")
        if config.env not in TASK_SCENARIOS:
            parser.error(f"--backend vizdoom plays MyWayHome in ViZDoom's look; {args.run} trained on {config.env}, "
                         f"not one of {', '.join(TASK_SCENARIOS)}")
    from simjax.envs import make

    env = make(config.env)
    limit = getattr(getattr(env, "task", None), "max_steps", None)
    if limit is None:
        parser.error(f"{config.env} is not a maze task (no step limit or success to count)")
    if args.max_steps is not None and not 1 <= args.max_steps <= limit:
        parser.error(f"--max-steps must lie in [1, {limit}] ({config.env}'s limit), got {args.max_steps}")
    if args.video is not None and (getattr(env, "generator", None) is not None or not hasattr(env, "layout")):
        parser.error(f"--video draws the path on a fixed map; {config.env} has none")
    try:
        load_checkpoint(args.run) if checkpointed else load_export(args.run)
    except ValueError as err:
        parser.error(str(err))
    return config, env, limit


def policy_step(network, greedy: bool):
    """``(params, carry, obs (N, ...), key) -> (actions (N,) int32, carry)``: one step of the
    policy on a batch of frames, as it acts in training (``a2c.assemble_trainer``'s rollout). No
    reset flag: a caller starts each episode from ``network.initial_carry``, which is what a reset
    does."""
    import jax
    import jax.numpy as jnp

    def act(params, carry, obs, key):
        reset = jnp.zeros((1, obs.shape[0]), bool)
        carry, logits, _ = network.apply(params, carry, obs[None], reset)
        action = jnp.argmax(logits[0], -1) if greedy else jax.random.categorical(key, logits[0])
        return action.astype(jnp.int32), carry

    return act


# -- simjax ------------------------------------------------------------------------------------


def simjax_rollout(env, network, act, num_lanes: int, steps: int, record: int):
    """A jittable ``(params, key, uniform) -> (done, success, length (T, N), views, xy)``: ``N``
    lanes of ``env`` for ``steps`` steps (``envs.episodes.rollout``; the env auto-resets),
    acting with ``act`` or, where ``uniform``, uniformly at random; one compiled function serves
    both policies. ``views`` (T, record, H, W, C) are the first ``record`` lanes' frames and
    ``xy`` (T, N, 2) every lane's position, before each step."""
    import jax
    import jax.numpy as jnp

    from simjax.envs import rollout

    def keep(state, actions, nxt):
        m = nxt.metrics
        return (m["episode_done"] > 0, m["episode_success"] > 0, m["episode_length"], state.obs[:record],
                state.pipeline_state.pose.pos)

    def play(params, key, uniform):
        k_reset, k_act = jax.random.split(key)
        state = jax.vmap(env.reset)(jax.random.split(k_reset, num_lanes))

        def policy(carry, state, k):
            k_pol, k_rand = jax.random.split(k)
            action, carry = act(params, carry, state.obs, k_pol)
            return jnp.where(uniform, jax.random.randint(k_rand, (num_lanes,), 0, env.action_size), action), carry

        return rollout(env, policy, state, network.initial_carry(num_lanes), jax.random.split(k_act, steps), keep)[2]

    return play


def first_episodes(done, success, length, steps: int):
    """Each lane's first episode: (success (N,), length (N,)); one not ended within ``steps``
    counts as a failure of ``steps`` steps."""
    ended, first = done.any(axis=0), done.argmax(axis=0)
    lanes = np.arange(done.shape[1])
    return (np.where(ended, success[first, lanes], False),
            np.where(ended, length[first, lanes], steps).astype(np.int64))


def simjax_episodes(rollout, params, key, uniform: bool, n: int, steps: int, record: int):
    """(success (n,), length (n,), [(views, xy) of the first ``record`` episodes], ends (n, 2):
    where each episode was before its last step)."""
    done, success, length, views, xy = (np.asarray(a) for a in rollout(params, key, uniform))
    success, length = first_episodes(done, success, length, steps)
    success, length = success[:n], length[:n]
    ends = xy[length - 1, np.arange(n)]
    return success, length, [(views[:length[i], i], xy[:length[i], i]) for i in range(min(record, n))], ends


# -- ViZDoom -----------------------------------------------------------------------------------


def vizdoom_episodes(game, start, choose, seeds, steps: int, record: int, say=None):
    """Play ``len(seeds)`` ViZDoom episodes (episode i seeded ``seeds[i]``, from ``start``).
    ``choose(i)`` gives episode i's actor, ``42x42 frame -> action``. Returns as ``simjax_episodes``."""
    from simjax.envs.doom import vizdoom_ref

    success, length, recorded, ends = [], [], [], []
    for i, seed in enumerate(seeds):
        game.new_episode(start=start, seed=int(seed))
        actor, views, xy = choose(i), [], []
        for t in range(steps):  # noqa: B007 (t, read after the loop, is the episode's last step)
            view = vizdoom_ref.resize42(game.frame())
            here = game.pose()[:2]
            if i < record:
                views.append(view)
                xy.append(here)
            if game.step(actor(view))[1]:
                break
        success.append(game.succeeded)
        length.append(t + 1)
        ends.append(here)
        if i < record:
            recorded.append((np.stack(views), np.asarray(xy)))
        if say and (i + 1) % max(1, len(seeds) // 10) == 0:
            say(f"{i + 1}/{len(seeds)} episodes, success {np.mean(success):.3f}")
    return np.asarray(success, bool), np.asarray(length, np.int64), recorded, np.asarray(ends, np.float64).reshape(-1, 2)


def policy_actor(act, network, params, key, steps: int):
    """``choose(i)`` for ``vizdoom_episodes``: the policy with a fresh LSTM carry each episode,
    episode i's action keys drawn from ``fold_in(key, i)``."""
    import jax

    def choose(i):
        keys = np.asarray(jax.random.split(jax.random.fold_in(key, i), steps))
        state = {"carry": network.initial_carry(1), "t": 0}

        def actor(view):
            action, state["carry"] = act(params, state["carry"], view[None], keys[state["t"]])
            state["t"] += 1
            return int(action[0])

        return actor

    return choose


def random_actor(eval_seed: int, num_actions: int):
    def choose(i):
        rng = np.random.default_rng([eval_seed, i])
        return lambda view: int(rng.integers(num_actions))

    return choose


# -- numbers and pictures -------------------------------------------------------------------


def wilson(successes: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """The Wilson score interval of a binomial proportion (95% for the default z): unlike
    p +- z se, it stays inside [0, 1] and is not empty at 0 or n successes."""
    p, z2 = successes / n, z * z
    centre = (p + z2 / (2 * n)) / (1 + z2 / n)
    half = z / (1 + z2 / n) * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n))
    return (0.0 if successes == 0 else centre - half), (1.0 if successes == n else centre + half)


def nearest_spots(ends, spots: dict) -> dict:
    """{spot name: how many of ``ends`` (n, 2) lie nearest to it}, most first, ties by ``spots``'
    order ({name: (x, y)}, e.g. MyWayHome's spawn spots, one a room or corridor)."""
    ends = np.asarray(ends, np.float64).reshape(-1, 2)
    names, xy = list(spots), np.asarray(list(spots.values()), np.float64)
    counts = np.bincount(np.argmin(np.linalg.norm(ends[:, None] - xy[None], axis=-1), axis=1), minlength=len(names))
    order = sorted((i for i in range(len(names)) if counts[i]), key=lambda i: (-counts[i], i))
    return {str(names[i]): int(counts[i]) for i in order}


def where_they_end(ends, goal, spots: dict) -> dict:
    """Where episodes end (``ends`` (n, 2), the position before each one's last step): the mean
    distance from ``goal`` and ``nearest_spots``."""
    ends = np.asarray(ends, np.float64).reshape(-1, 2)
    return {"goal_distance_mean": float(np.mean(np.linalg.norm(ends - np.asarray(goal, np.float64), axis=1))),
            "nearest_spot": nearest_spots(ends, spots)}


def summarize(success, length, ends=None) -> dict:
    """Success with its Wilson interval and mean length; ``ends`` (``where_they_end``'s dict)
    added where given."""
    n, k = len(success), int(np.sum(success))
    lo, hi = wilson(k, n)
    out = {"episodes": n, "successes": k, "success_ratio": k / n, "success_95": [lo, hi],
           "mean_episode_length": float(np.mean(length))}
    return out if ends is None else out | {"ends": ends}


def table(results: dict) -> str:
    lines = [f"{'':8} {'success':>8}  {'95% interval':>15}  {'mean length':>11}  {'episodes':>8}"]
    for name, r in results.items():
        if r is not None:
            lo, hi = r["success_95"]
            lines.append(f"{name:8} {r['success_ratio']:8.3f}  [{lo:.3f}, {hi:.3f}]  "
                         f"{r['mean_episode_length']:11.1f}  {r['episodes']:8d}")
    for name, r in results.items():
        if r is not None and r.get("ends"):
            spots = ", ".join(f"{s}: {c}" for s, c in list(r["ends"]["nearest_spot"].items())[:5])
            lines.append(f"{name} ends {r['ends']['goal_distance_mean']:.0f} units from the goal on average; "
                         f"nearest spawn spot (most first) {spots}")
    return "\n".join(lines)


def write_gif(path: Path, layout, episodes, title: str, colours=None) -> None:
    """An animated GIF of ``episodes`` [(views (T, 42, 42, 3), xy (T, 2))]: each frame the view
    (scaled up, nearest) beside the path so far on the map. The map is drawn by matplotlib once
    and the path onto copies of it with PIL, so a frame costs milliseconds, not a figure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image, ImageDraw

    from simjax.envs.topdown import draw_topdown

    fig, ax = plt.subplots(figsize=(5.2, 3.5), dpi=72)
    draw_topdown(layout, ax=ax, title=title, spawns=False, colours=colours)
    fig.tight_layout()
    fig.canvas.draw()
    base = Image.fromarray(np.asarray(fig.canvas.buffer_rgba())[..., :3].copy())
    to_pixels = ax.transData.transform
    plt.close(fig)
    side = 42 * VIEW_SCALE
    frames = []
    for e, (views, xy) in enumerate(episodes):
        pts = [(float(x), base.height - float(y)) for x, y in to_pixels(np.asarray(xy, np.float64))]
        for t in range(0, len(views), math.ceil(len(views) / VIDEO_FRAMES)):
            frame = Image.new("RGB", (side + base.width, max(side + 20, base.height)), "white")
            frame.paste(Image.fromarray(views[t]).resize((side, side), Image.NEAREST), (0, 20))
            ImageDraw.Draw(frame).text((4, 4), f"episode {e + 1}, step {t + 1}", fill="black")
            board = base.copy()
            pen = ImageDraw.Draw(board)
            if t:
                pen.line(pts[: t + 1], fill=(220, 30, 30), width=2)
            x, y = pts[t]
            pen.ellipse((x - 4, y - 4, x + 4, y + 4), fill=(220, 30, 30))
            frame.paste(board, (side, 0))
            frames.append(frame)
    tmp = path.with_suffix(".tmp.gif")  # written whole, then renamed, like atomic_write
    frames[0].save(tmp, save_all=True, append_images=frames[1:], duration=70, loop=0)
    tmp.replace(path)


def _version(package: str) -> str | None:
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return None


# -- command line -------------------------------------------------------------------------------


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    config, env, limit = check_args(parser, args)
    with runtime.matmul_precision(config.precision):  # the policy acts at the precision it trained at
        return play(args, argv, config, env, limit)


def play(args, argv: list[str], config, env, limit: int) -> int:
    """Evaluate as ``args`` (checked by ``check_args``) say; ``argv`` is recorded in the JSON."""
    steps = args.max_steps or limit
    n, n_random = args.episodes, args.episodes if args.random_episodes is None else args.random_episodes
    record = min(args.video_episodes, n) if args.video else 0
    say = (lambda m: None) if args.quiet else (lambda m: print(m, file=sys.stderr, flush=True))

    import jax

    from simjax.envs import is_mywayhome
    from simjax.envs.doom import mywayhome_map

    runtime.enable_compilation_cache()
    restored = restore(args.run, env)
    network, params = restored.network, restored.policy()
    act = policy_step(network, args.greedy)
    key = jax.random.PRNGKey(args.eval_seed)
    indices = range(config.num_seeds) if args.all_seeds else [args.seed_index]
    ended = lambda ends: None
    if is_mywayhome(config.env):
        ended = lambda ends: where_they_end(ends, mywayhome_map.GOAL_XY, mywayhome_map.SPAWN_SPOTS)
    if args.backend == "simjax":
        rollout = jax.jit(simjax_rollout(env, network, act, max(n, n_random), steps, record))
        run_policy = lambda p: simjax_episodes(rollout, p, key, False, n, steps, record)
        run_random = lambda p: simjax_episodes(rollout, p, key, True, n_random, steps, 0)
        game = None
    else:
        from simjax.envs.doom import vizdoom_ref

        game, start = vizdoom_ref.open_task(config.env, seed=args.eval_seed, depth=False)
        seeds = np.random.default_rng(args.eval_seed).integers(0, 2**31 - 1, size=max(n, n_random))
        jitted = jax.jit(act)
        run_policy = lambda p: vizdoom_episodes(game, start, policy_actor(jitted, network, p, key, steps),
                                                seeds[:n], steps, record, say)
        run_random = lambda p: vizdoom_episodes(game, start, random_actor(args.eval_seed, env.action_size),
                                                seeds[:n_random], steps, 0, say)
    try:
        first = jax.tree.map(lambda x: x[indices[0]], params)
        random = None
        if n_random:
            say(f"random policy: {n_random} episodes on {args.backend}")
            success, length, _, ends = run_random(first)
            random = summarize(success, length, ended(ends))
        for k in indices:
            seed_params = jax.tree.map(lambda x, k=k: x[k], params)
            say(f"seed {restored.seeds[k]}: {n} episodes on {args.backend}")
            success, length, recorded, ends = run_policy(seed_params)
            results = {"policy": summarize(success, length, ended(ends)), "random": random}
            tag = f"-seed{k}" if config.num_seeds > 1 else ""
            video = None
            if args.video:
                video = args.video if len(indices) == 1 else args.video.with_name(args.video.stem + tag + ".gif")
                write_gif(video, env.layout, recorded, f"{args.run.name}, seed {restored.seeds[k]}, {args.backend}",
                          colours=getattr(getattr(env, "look", None), "wall_rgb", None))
            record_json = {
                "run": str(args.run), "env": config.env, "backend": args.backend, "seed_index": k,
                "seed": restored.seeds[k], "env_steps": restored.env_steps, "eval_seed": args.eval_seed,
                "greedy": args.greedy, "max_steps": steps, **results,
                "command": shlex.join(["python", "-m", "simjax.evaluate", *argv]),
                "date": dt.datetime.now().isoformat(timespec="seconds"),
                "versions": {p: _version(p) for p in ("vizdoom", "jax", "flax")},
                "video": None if video is None else str(video),
            }
            out = args.run / f"evaluate-{args.backend}{tag}.json"
            atomic_write(out, json.dumps(record_json, indent=2).encode())
            print(f"{args.run.name} ({config.env}, seed {restored.seeds[k]}) at {restored.env_steps:,} agent "
                  f"steps, on {args.backend}, {'greedy' if args.greedy else 'sampled'} actions, episodes of at "
                  f"most {steps} steps:")
            print(table(results))
            print(f"wrote {out}" + (f" and {video}" if video else ""))
    finally:
        if game is not None:
            game.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
