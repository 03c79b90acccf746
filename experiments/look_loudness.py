"""How "loud" is each wall look for a random-network target? Measures, and calibrates, the
spread of the RND target (SIM's and RND's prediction target) over frames of each look.

    python experiments/look_loudness.py [--calibrate 4] [--walks 16] [--steps 40]

A prediction-error bonus is roughly (1 - the model's relative accuracy) times the spread of
its target where the agent is. A look whose frames spread the target widely (bright walls
over the dark floor: the wall's edge sweeps bright pixels over dark ones as the agent moves)
pays more at the same accuracy: a noisy TV made of paint.

*Spread* is half the summed variance of the target's 64 outputs over a set of frames, which is
the error of a model that predicts their mean target; averaged over 4 random targets. Frames
are normalised per pixel by the statistics of all the frames measured together, as a run's
running statistics would.

Prints:
- per look: its spread when it is drawn on every wall of the MyWayHome map (random walks from
  spawn spots 10, 13, 17, 22, 24 and 26);
- per spawn spot of the real map (its own looks): the spread of random walks from there, and
  the ratio of the loudest spot to the quietest.
With ``--calibrate K``: K rounds of moving each of the nine looks' colours toward (or away
from) mid grey 0.45 by a factor per look, ``factor *= sqrt(median spread / its spread)``; then
the map is measured again with the calibrated looks, and they are printed as Python tuples.
"""

from __future__ import annotations

import argparse
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

from simjax.envs import mywayhome_layout, random_walks, raycaster
from simjax.envs.doom import mywayhome_map
from simjax.envs.maze import MazeEnv, MazeTask
from simjax.novelty.base import RunningMeanStd, normalize_frames, spread
from simjax.novelty.networks import RNDTarget

LOOK_SPOTS = (10, 13, 17, 22, 24, 26)  # where the walks start when one look covers the map
MAP_SPOTS = (10, 11, 13, 16, 17, 18, 21, 22, 23, 24, 25, 26)
GREY = 0.45
NUM_LOOKS = 9  # MyWayHome's textures


def scaled_looks(factors) -> tuple:
    """TEXTURE_LOOKS with look k's two colours at GREY + factors[k] * (colour - GREY)."""
    looks = list(raycaster.TEXTURE_LOOKS)
    for k, f in enumerate(factors):
        base, alt, pu, pv = looks[k]
        move = lambda c, f=f: tuple(float(v) for v in np.clip(GREY + f * (np.asarray(c) - GREY), 0.0, 1.0))  # noqa: E731
        looks[k] = (move(base), move(alt), pu, pv)
    return tuple(looks)


class Meter:
    """Random-walk frames for a map whose wall looks are a traced argument (one compile)."""

    def __init__(self, walks: int, steps: int):
        self.base = mywayhome_layout([10])
        self.walks, self.steps = walks, steps
        self.targets = [RNDTarget().init(jax.random.PRNGKey(100 + i), jnp.zeros((1, 42, 42, 3))) for i in range(4)]

        def frames(texture, spawn, key):
            walls = self.base.walls._replace(texture=texture)
            layout = self.base._replace(walls=walls, spawns=spawn[None])
            env = MazeEnv(layout, MazeTask("loudness", random_heading=True))
            obs, *_ = random_walks(env, key, walks, steps)
            return obs.reshape((-1,) + obs.shape[2:])

        self._frames = jax.jit(frames)
        self._targets = jax.jit(lambda params, x: RNDTarget().apply(params, x))

    def frames(self, texture, spot: int, key):
        spawn = jnp.asarray(mywayhome_map.SPAWN_SPOTS[spot], jnp.float32)
        return self._frames(jnp.asarray(texture, jnp.int32), spawn, key)

    def spread(self, frames, stats) -> float:  # averaged over the random targets
        x = normalize_frames(frames, stats)
        return float(np.mean([spread(self._targets(p, x)) for p in self.targets]))


def measure(meter: Meter, looks) -> tuple[np.ndarray, dict]:
    """(spread per look over the whole map, {spawn spot: spread} on the real map)."""
    saved = raycaster.TEXTURE_LOOKS
    raycaster.TEXTURE_LOOKS = looks  # read when the renderer is traced
    jax.clear_caches()
    try:
        real = np.asarray(meter.base.walls.texture)
        per_look = [[meter.frames(np.full_like(real, k), s, jax.random.PRNGKey(50 + j)) for j, s in enumerate(LOOK_SPOTS)]
                    for k in range(NUM_LOOKS)]
        per_spot = [meter.frames(real, s, jax.random.PRNGKey(50 + j)) for j, s in enumerate(MAP_SPOTS)]
    finally:
        raycaster.TEXTURE_LOOKS = saved
        jax.clear_caches()
    stack = jnp.concatenate([f for fs in per_look for f in fs])
    stats = RunningMeanStd.create(stack.shape[1:]).update(stack)
    look_spread = np.asarray([np.mean([meter.spread(f, stats) for f in fs]) for fs in per_look])
    stack = jnp.concatenate(per_spot)
    stats = RunningMeanStd.create(stack.shape[1:]).update(stack)
    spot_spread = {s: meter.spread(f, stats) for s, f in zip(MAP_SPOTS, per_spot)}
    return look_spread, spot_spread


def report(look_spread, spot_spread) -> None:
    names = mywayhome_map.TEXTURE_NAMES
    print("  per look: " + ", ".join(f"{names[k]} {v:.1f}" for k, v in enumerate(look_spread))
          + f"   (max/min {look_spread.max() / look_spread.min():.1f}x)")
    values = np.asarray(list(spot_spread.values()))
    print("  per spawn spot: " + ", ".join(f"{s}: {v:.1f}" for s, v in spot_spread.items())
          + f"   (max/min {values.max() / values.min():.1f}x)", flush=True)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--calibrate", type=int, default=0, help="rounds of calibration (0: measure only)")
    parser.add_argument("--walks", type=int, default=16, help="random walks per spot")
    parser.add_argument("--steps", type=int, default=40, help="steps per walk")
    args = parser.parse_args(argv)
    if args.calibrate < 0 or args.walks < 1 or args.steps < 1:
        parser.error("need --calibrate >= 0, --walks >= 1 and --steps >= 1")
    meter = Meter(args.walks, args.steps)
    start = time.time()
    print(f"spread of the RND target (half its summed variance; 4 random targets), {args.walks} walks "
          f"of {args.steps} steps per spot")
    print("current looks (simjax.envs.raycaster.TEXTURE_LOOKS):")
    look_spread, spot_spread = measure(meter, raycaster.TEXTURE_LOOKS)
    report(look_spread, spot_spread)
    if args.calibrate:
        factors = np.ones(NUM_LOOKS)
        for r in range(args.calibrate):
            factors = factors * np.sqrt(np.median(look_spread) / look_spread)
            look_spread, spot_spread = measure(meter, scaled_looks(factors))
            print(f"round {r + 1}, factors " + " ".join(f"{f:.3f}" for f in factors) + ":")
            report(look_spread, spot_spread)
        print("calibrated looks:")
        for look in scaled_looks(factors)[:NUM_LOOKS]:
            base, alt, pu, pv = look
            print(f"    ({tuple(round(v, 2) for v in base)}, {tuple(round(v, 2) for v in alt)}, {pu}, {pv}),")
    print(f"({time.time() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
