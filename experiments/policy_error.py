"""Is a trained policy's own novelty learnable? A run's checkpoint scores the policy's episodes
and uniform random episodes with its own novelty model; then, optionally, the policy is frozen
and only the novelty model goes on training on the policy's rollouts.

    python experiments/policy_error.py RUN_DIR [--seed-index 0] [--spot 22] [--chunks 0]
        [--chunk-updates 40]

Part 1: 16 episodes of the policy and 16 of the uniform random policy from the run's task,
scored by the checkpoint's model with its own running frame statistics (only transitions
whose whole window lies in the episode). Prints each one's mean error (the bonus before beta),
action shares, and the error within 128 units of ``--spot`` and elsewhere: a policy whose
error near a spot is well above random walks' there has found something there its model
cannot predict.

Part 1b (SIM only): the policy's own episodes again, but each sampled target frame is also
remade by replaying L uniform random actions, instead of the policy's, from the state at the
window's newest frame; the window's H frames stay the same. Prints both errors near the spot
and elsewhere, and the policy's most frequent last-L action tuples with their error (0 turn
left, 1 turn right, 2 forward, 3 no-op). If the random actions score as high, the policy's
windows are hard where it goes; if well below, it is what the policy does there.

Part 2 (``--chunks K``): the policy frozen, the novelty model alone trains on its rollouts
(16 envs x 20 steps per update, a fresh Adam at the run's lr and clip) for K chunks of
``--chunk-updates`` updates, and, for comparison, the same rollouts with the model frozen.
Prints the mean forward loss per chunk. If the first falls well below the second, the model
can learn what the policy does and the high error is a chase; if not, it is a plateau.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import optax

sys.path.insert(0, str(Path(__file__).resolve().parent))

from novelty_map import MYWAYHOME_TASKS

from simjax.agents import sampling_policy
from simjax.envs import given_actions, raycaster, rollout, starts_episode, uniform_policy
from simjax.envs.doom import mywayhome_map
from simjax.novelty.base import build_timeline, init_memory, normalize_frames
from simjax.runs import restore

NEAR = 128.0  # units
NUM_ENVS = 16


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", type=Path)
    parser.add_argument("--seed-index", type=int, default=0, help="which of the run's seeds")
    parser.add_argument("--spot", type=int, default=22, help="MyWayHome spawn spot to split the error at")
    parser.add_argument("--chunks", type=int, default=0, help="part 2: chunks of novelty-only training")
    parser.add_argument("--chunk-updates", type=int, default=40)
    args = parser.parse_args(argv)
    if args.spot not in mywayhome_map.SPAWN_SPOTS:
        parser.error(f"unknown spawn spot {args.spot}; known: {sorted(mywayhome_map.SPAWN_SPOTS)}")
    if args.chunks < 0 or args.chunk_updates < 1:
        parser.error("need --chunks >= 0 and --chunk-updates >= 1")
    try:
        restored = restore(args.run)
    except FileNotFoundError as err:
        parser.error(str(err))
    config = restored.config
    if config.algo == "a2c" or config.env not in MYWAYHOME_TASKS:
        parser.error(f"needs a run on {', '.join(MYWAYHOME_TASKS)} with a novelty model (sim, rnd, icm)")
    if not 0 <= args.seed_index < config.num_seeds:
        parser.error(f"--seed-index must be in [0, {config.num_seeds})")
    trainer, env = restored.trainer, restored.env
    model, network = trainer.novelty.model, trainer.network
    runner = restored.runner(args.seed_index)
    n = NUM_ENVS

    def episodes(key, random: bool):
        k_reset, k_act = jax.random.split(key)
        state = jax.vmap(env.reset)(jax.random.split(k_reset, n))
        act = uniform_policy(env.action_size, n) if random else sampling_policy(network, runner.params["policy"])

        def record(state, action, nxt):
            # how far the frame this step leads to sees: its farthest wall (through a door, a corridor)
            view = jax.vmap(lambda p, h: jnp.max(raycaster.cast_rays(env.layout.walls, p, h)[0]))(
                nxt.pipeline_state.pose.pos, nxt.pipeline_state.pose.heading)
            return state.obs, action, state.pipeline_state.pose.pos, view, nxt.done

        last, _, (obs, action, pos, view, done) = rollout(
            env, act, state, network.initial_carry(n), jax.random.split(k_act, env.task.max_steps), record)
        reset = jnp.zeros(action.shape, bool).at[0].set(True)
        tl, _ = build_timeline(init_memory(model.history, n, obs.shape[2:], obs.dtype), obs, reset, action,
                               last.obs, jnp.zeros((n,), bool))
        x = normalize_frames(tl.frames, runner.novelty.obs_stats if config.obs_norm else None)
        error, scored, _, _ = model.apply(runner.params["novelty"], tl, x)
        return error, scored, action, pos, view, done

    spot = np.asarray(mywayhome_map.SPAWN_SPOTS[args.spot])
    print(f"{args.run.name}, seed index {args.seed_index}, at {restored.env_steps:,} agent steps per seed; "
          f"{n} episodes each")
    for random in (False, True):
        error, scored, action, pos, view, done = jax.device_get(jax.jit(episodes, static_argnums=1)(jax.random.PRNGKey(7), random))
        t = np.arange(error.shape[0])[:, None]
        mask = scored & (np.cumsum(done, axis=0) == 0) & (t >= model.history)  # the whole window lies in the episode
        near = np.linalg.norm(pos - spot, axis=-1) < NEAR
        shares = np.bincount(action[mask], minlength=env.action_size) / mask.sum()
        parts = [f"{name} {error[sel].mean():.2f} ({sel.sum() / mask.sum():.0%} of steps)"
                 for name, sel in ((f"near spot {args.spot}", mask & near), ("elsewhere", mask & ~near)) if sel.any()]
        print(f"  {'random' if random else 'policy'}: error {error[mask].mean():.2f}; " + ", ".join(parts)
              + "; action shares " + " ".join(f"{s:.2f}" for s in shares))
        bands = [(0, 128), (128, 256), (256, 512), (512, np.inf)]
        print("    by the next frame's farthest wall: " + ", ".join(
            f"{lo}-{hi:.0f}: {error[sel].mean():.2f} ({sel.sum() / mask.sum():.0%})" for lo, hi in bands
            for sel in [mask & (view >= lo) & (view < hi)] if sel.any()))
        # how far the agent moved over the open-loop steps: from the window's newest frame
        # (before step t - L + 1) to the predicted one (after step t)
        L = getattr(model, "act_len", 1)  # SIM predicts L steps ahead, RND and ICM one
        moved = np.full(error.shape, np.nan)
        moved[L - 1 : -1] = np.linalg.norm(pos[L:] - pos[: -L], axis=-1)
        bands = [(0, 8), (8, 32), (32, 64), (64, np.inf)]
        print(f"    by distance moved over the last {L} steps: " + ", ".join(
            f"{lo}-{hi:.0f}: {error[sel].mean():.2f} ({sel.sum() / mask.sum():.0%})" for lo, hi in bands
            for sel in [mask & (moved >= lo) & (moved < hi)] if sel.any()))

    if hasattr(model, "act_len"):
        replay_last_actions(env, model, network, runner, config, spot, args.spot)
    if args.chunks == 0:
        return 0
    tx = optax.chain(optax.clip_by_global_norm(config.max_grad_norm), optax.adam(config.learning_rate))
    policy, novelty, T = runner.params["policy"], trainer.novelty, config.rollout_len

    def update(c, _):
        params, opt_state, env_state, carry, state, key, learn = c
        key, sub = jax.random.split(key)
        last, carry, (obs, reset, action) = rollout(env, sampling_policy(network, policy), env_state, carry,
                                                    jax.random.split(sub, T),
                                                    lambda s, a, nxt: (s.obs, starts_episode(s), a))
        grads, (_, metrics, state) = jax.grad(novelty.loss_and_bonus, has_aux=True)(
            params, state, obs, reset, action, last.obs, starts_episode(last))
        updates, opt_state = tx.update(grads, opt_state, params)
        params = jax.tree.map(lambda p, u: p + learn * u, params, updates)
        return (params, opt_state, last, carry, state, key, learn), metrics["forward_loss"]

    @jax.jit
    def chunk(c):
        c, forward = jax.lax.scan(update, c, None, args.chunk_updates)
        return c, forward.mean()

    print(f"policy frozen; forward loss per chunk of {args.chunk_updates} updates "
          f"({args.chunk_updates * config.steps_per_update:,} agent steps)")
    for learn in (1.0, 0.0):
        p = runner.params["novelty"]
        c = (p, tx.init(p), runner.env_state, runner.carry, runner.novelty, jax.random.PRNGKey(5), jnp.float32(learn))
        start, curve = time.time(), []
        for _ in range(args.chunks):
            c, forward = chunk(c)
            curve.append(float(forward))
        print(f"  model {'training' if learn else 'frozen  '} " + " ".join(f"{v:6.2f}" for v in curve)
              + f"   ({time.time() - start:.0f} s)", flush=True)
    return 0


def replay_last_actions(env, model, network, runner, config, spot, spot_id, n=NUM_ENVS, every=3):
    """Part 1b: the policy's windows scored with its own last L actions and with random ones."""
    H, L = model.obs_len, model.act_len
    stats = runner.novelty.obs_stats if config.obs_norm else None

    def error_of_last(frames, actions):
        """frames (H+L, B, ...) o_{e-H-L+1} .. o_e and actions (H+L-1, B): the error of o_e."""
        b = frames.shape[1]
        reset = jnp.zeros(actions.shape, bool).at[0].set(True)
        tl, _ = build_timeline(init_memory(model.history, b, frames.shape[2:], frames.dtype), frames[:-1], reset,
                               actions, frames[-1], jnp.zeros((b,), bool))
        error, _, _, _ = model.apply(runner.params["novelty"], tl, normalize_frames(tl.frames, stats))
        return error[-1]

    @jax.jit
    def run(key):
        k_reset, k_act, k_replay = jax.random.split(key, 3)
        state = jax.vmap(env.reset)(jax.random.split(k_reset, n))
        _, _, (states, actions) = rollout(env, sampling_policy(network, runner.params["policy"]), state,
                                          network.initial_carry(n), jax.random.split(k_act, env.task.max_steps),
                                          lambda s, a, nxt: (s, a))

        def at(e):  # target frame e (index into the episode), its window starting at e - H - L + 1
            frames = jax.lax.dynamic_slice_in_dim(states.obs, e - H - L + 1, H + L, 0)
            acts = jax.lax.dynamic_slice_in_dim(actions, e - H - L + 1, H + L - 1, 0)
            random = jax.random.randint(jax.random.fold_in(k_replay, e), (L, n), 0, env.action_size)

            _, _, (replayed, ended) = rollout(env, given_actions, jax.tree.map(lambda x: x[e - L], states), (), random,
                                              lambda s, a, nxt: (nxt.obs, nxt.done))
            own = error_of_last(frames, acts)
            other = error_of_last(jnp.concatenate([frames[:H], replayed]), jnp.concatenate([acts[: H - 1], random]))
            # the whole window and both continuations lie in one episode
            ok = (states.pipeline_state.steps[e - H - L + 1] + H + L - 1 == states.pipeline_state.steps[e])
            ok = ok & ~jnp.any(ended > 0, axis=0)
            return own, other, ok, states.pipeline_state.pose.pos[e - L], acts[H - 1 :].T

        return jax.lax.map(at, jnp.arange(H + L - 1, env.task.max_steps, every))

    own, other, ok, pos, last = jax.device_get(run(jax.random.PRNGKey(7)))
    near = np.linalg.norm(pos - spot, axis=-1) < NEAR
    print(f"  policy windows, error of the target frame after its own last {L} actions vs {L} uniform random ones "
          "replayed from the same state:")
    for name, sel in ((f"near spot {spot_id}", ok & near), ("elsewhere", ok & ~near)):
        if sel.any():
            print(f"    {name}: own {own[sel].mean():.2f}, random {other[sel].mean():.2f} ({sel.sum()} windows)")
    sel = ok & near if (ok & near).sum() >= 100 else ok
    code = (last[sel] * env.action_size ** np.arange(L - 1, -1, -1)).sum(axis=-1)
    counts = np.bincount(code, minlength=env.action_size ** L)
    print(f"    most frequent last-{L} action tuples ({'near the spot' if sel is not ok else 'all'}): " + ", ".join(
        f"{tuple(int(d) for d in np.unravel_index(c, (env.action_size,) * L))} {counts[c] / sel.sum():.1%} "
        f"error {own[sel][code == c].mean():.2f}" for c in np.argsort(-counts)[:8]))


if __name__ == "__main__":
    sys.exit(main())
