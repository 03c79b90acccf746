"""How predictable is each MyWayHome room for SIM? A fresh SIM model per room, trained on the
same number of random-walk transitions inside that room only; a room whose forward loss stays
high after the same training is hard to predict, not merely unseen (a "noisy TV").

    python experiments/room_predictability.py [--spots 10 17 22 26] [--updates 400] [--chunks 8]
        [--look-as I J]

``--look-as I J`` draws wall texture I with texture J's look (``raycaster.TEXTURE_LOOKS``), to
tell a room's look from its shape: e.g. ``--spots 22 --look-as 4 6`` gives the cyan room
(TLITE6_1, texture 4) the grey room's SILVER2 bands.

Each spot's walks start there with a random heading and last 60 steps (so they stay near
it); 16 environments x 20-step rollouts per update, the default SIM (H = 10, L = 3, RND
target, observation normalisation by the room's own running statistics), Adam at the
training default (lr 1e-3, clip 0.5). Same seed for every room. Prints the forward loss (mean
over each chunk of updates) per room, and each room's last value relative to the lowest.
"""

from __future__ import annotations

import argparse
import sys
import time

import jax
import optax

from simjax.agents import TrainConfig
from simjax.agents.a2c import ADAM_EPS
from simjax.envs import MazeEnv, MazeTask, given_actions, mywayhome_layout, raycaster, rollout, starts_episode
from simjax.envs.doom import mywayhome_map
from simjax.novelty import make_novelty

ROOMS = {10: "start (BIGDOOR2 panels)", 11: "tan (CEIL4_2 checker)", 17: "green (COMP01 bands)",
         22: "cyan (TLITE6_1 panels)", 24: "grey (SILVER2 bands)", 26: "blue (SFALL2 stripes)",
         13: "red (FLOOR1_6 bricks)"}


def room_trainer(spot: int, config: TrainConfig, updates_per_chunk: int, walk_steps: int = 60):
    env = MazeEnv(mywayhome_layout([spot]), MazeTask(f"room-{spot}", random_heading=True, max_steps=walk_steps))
    novelty = make_novelty(config.novelty, env.action_size, env.observation_size)
    tx = optax.chain(optax.clip_by_global_norm(config.max_grad_norm),
                     optax.adam(config.learning_rate, eps=ADAM_EPS))
    n, t = config.num_envs, config.rollout_len

    def init(key):
        k_env, k_nov, k_run = jax.random.split(key, 3)
        env_state = jax.vmap(env.reset)(jax.random.split(k_env, n))
        params, state = novelty.init(k_nov, env_state.obs)
        return params, tx.init(params), env_state, state, k_run

    def update(carry, _):
        params, opt_state, env_state, state, key = carry
        key, k_act = jax.random.split(key)
        actions = jax.random.randint(k_act, (t, n), 0, env.action_size)
        last, _, (obs, reset) = rollout(env, given_actions, env_state, (), actions,
                                        lambda s, a, nxt: (s.obs, starts_episode(s)))
        grads, (bonus, metrics, state) = jax.grad(novelty.loss_and_bonus, has_aux=True)(
            params, state, obs, reset, actions, last.obs, starts_episode(last))
        updates, opt_state = tx.update(grads, opt_state, params)
        params = optax.apply_updates(params, updates)
        return (params, opt_state, last, state, key), metrics["forward_loss"]

    @jax.jit
    def chunk(carry):
        carry, forward = jax.lax.scan(update, carry, None, updates_per_chunk)
        return carry, forward.mean()

    return jax.jit(init), chunk


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--spots", type=int, nargs="+", default=[10, 17, 22, 26])
    parser.add_argument("--updates", type=int, default=400, help="updates per room")
    parser.add_argument("--chunks", type=int, default=8, help="rows of the printed curve")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--look-as", type=int, nargs=2, metavar=("I", "J"), default=None,
                        help="draw texture I with texture J's look")
    args = parser.parse_args(argv)
    unknown = [s for s in args.spots if s not in mywayhome_map.SPAWN_SPOTS]
    if unknown:
        parser.error(f"unknown spawn spots {unknown}; known: {sorted(mywayhome_map.SPAWN_SPOTS)}")
    if args.updates < args.chunks or args.chunks < 1:
        parser.error("need --updates >= --chunks >= 1")
    if args.look_as is not None:
        i, j = args.look_as
        if not (0 <= i < raycaster.NUM_TEXTURES and 0 <= j < raycaster.NUM_TEXTURES):
            parser.error(f"--look-as takes texture indices in [0, {raycaster.NUM_TEXTURES})")
        looks = list(raycaster.TEXTURE_LOOKS)
        looks[i] = looks[j]
        raycaster.TEXTURE_LOOKS = tuple(looks)  # read when a frame is traced
        print(f"texture {i} drawn with texture {j}'s look")
    config = TrainConfig(env="maze-very-sparse", algo="sim")
    per_chunk = args.updates // args.chunks
    steps = per_chunk * args.chunks * config.steps_per_update
    print(f"forward loss (mean over each chunk of {per_chunk} updates), {steps:,} random-walk transitions per room")
    curves = {}
    for spot in args.spots:
        init, chunk = room_trainer(spot, config, per_chunk)
        carry = init(jax.random.PRNGKey(args.seed))
        start = time.time()
        curve = []
        for _ in range(args.chunks):
            carry, forward = chunk(carry)
            curve.append(float(forward))
        curves[spot] = curve
        name = ROOMS.get(spot, "")
        print(f"spot {spot:2d} {name:26s} " + " ".join(f"{v:6.2f}" for v in curve)
              + f"   ({time.time() - start:.0f} s)", flush=True)
    last = {s: c[-1] for s, c in curves.items()}
    lowest = min(last.values())
    print("last chunk relative to the most predictable room: "
          + ", ".join(f"{s}: {v / lowest:.1f}x" for s, v in last.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
