"""Where a maze env step's time goes: the motion (Doom's, or DeepMind Lab's for the DMLab
worlds), the renderer, and the renderer's XLA:CPU fusions from the JAX profiler's trace.

    python experiments/profile_env.py [--task maze-very-sparse] [--envs 1024] [--pause PID]

Times three programs over ``--steps`` agent steps of ``--envs`` envs with random actions, each
one ``lax.scan``: the whole ``env.step`` (4 tics of motion, the pickup test, auto-reset, one
frame), the 4 tics of motion alone, and one frame alone (``env.render`` at the envs' poses,
turned by a random angle each step). Then it traces the render program and lists its largest
thunks with the JAX operation they came from, marking the fusions that read the look's
tables by gather (the texel lookups). ``--pause PID`` stops a training run (SIGSTOP) while it
compiles, times and traces, and lets it go on (SIGCONT) after, even on an error.
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import sys
from pathlib import Path

import jax
import jax.numpy as jnp

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench import time_call  # noqa: E402
from profile_update import trace_thunks  # noqa: E402

from simjax.envs import TASK_NAMES, make  # noqa: E402


def programs(env, num_envs: int, steps: int):
    """(whole step, motion alone, render alone), each jitted over ``steps`` agent steps."""
    layout, params, model = env.layout, env.motion_params, env.motion_model

    def actions(key):
        return jax.random.randint(key, (num_envs,), 0, env.action_size)

    @jax.jit
    def whole(state, key):
        def body(s, k):
            return jax.vmap(env.step)(s, actions(k)), None
        return jax.lax.scan(body, state, jax.random.split(key, steps))[0].obs.sum()

    def four_tics(pose, action):
        for _ in range(params.tics_per_step):
            pose = model.tic(pose, action, layout.boxes, params, layout.line_dir, layout.block_origin)
        return pose

    @jax.jit
    def moving(state, key):
        def body(pose, k):
            return jax.vmap(four_tics)(pose, actions(k)), None
        return jax.lax.scan(body, state.pipeline_state.pose, jax.random.split(key, steps))[0].pos.sum()

    @jax.jit
    def drawing(state, key):
        pose = state.pipeline_state.pose

        def body(total, k):
            turned = turn(pose, jax.random.randint(k, (num_envs,), 0, 4096))
            return total + jax.vmap(env.render)(turned).astype(jnp.float32).sum(), None
        return jax.lax.scan(body, jnp.float32(0.0), jax.random.split(key, steps))[0]

    return {"env.step (motion + render)": whole, "motion (4 tics)": moving, "render (one frame)": drawing}


def turn(pose, units):
    """``pose`` turned by ``units`` of a 65536-unit turn: Doom's ``angle``, or the game's part
    of DMLab's yaw (``delta_yaw``)."""
    if hasattr(pose, "angle"):
        return pose._replace(angle=(pose.angle + units) % 65536)
    return pose._replace(delta_yaw=(pose.delta_yaw + units) % 65536)


def gather_fusions(hlo: str) -> set[str]:
    """Names of the fusions whose computation contains a gather."""
    bodies = {m.group(1): m.group(2) for m in re.finditer(r"^(%?[\w.\-]+) [^\n]*\{\n(.*?)\n\}", hlo, re.M | re.S)}
    found = set()
    for m in re.finditer(r"^\s*%(\S+) = [^\n]* fusion\([^\n]*calls=(%[\w.\-]+)", hlo, re.M):
        body = bodies.get(m.group(2)) or bodies.get(m.group(2).lstrip("%"), "")
        if " gather(" in body:
            found.add(m.group(1))
    return found


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default="maze-very-sparse")
    parser.add_argument("--envs", type=int, default=1024)
    parser.add_argument("--steps", type=int, default=16, help="agent steps per timed call")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--pause", type=int, default=0, help="PID of a training run to stop while timing")
    args = parser.parse_args(argv)
    if args.task not in TASK_NAMES:
        parser.error(f"unknown task {args.task!r}; one of {', '.join(TASK_NAMES)}")
    if args.envs < 1 or args.steps < 1 or args.repeats < 1:
        parser.error("--envs, --steps and --repeats must be at least 1")
    if args.pause:
        os.kill(args.pause, 0)  # a missing PID fails here, before any compile
    env = make(args.task)
    if not hasattr(env, "layout"):
        parser.error(f"{args.task} generates its maps; this profiles the fixed-map tasks (maze-*)")
    state = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), args.envs))
    key = jax.random.PRNGKey(1)
    progs = programs(env, args.envs, args.steps)
    if args.pause:
        os.kill(args.pause, signal.SIGSTOP)
    try:
        seconds = {name: time_call(fn, state, key, repeats=args.repeats)[1] for name, fn in progs.items()}
        # the trace needs the compiled object, which time_call does not hand back: one more compile
        render = progs["render (one frame)"].lower(state, key).compile()
        jax.block_until_ready(render(state, key))  # warm-up
        wall, per_thunk, _, op_names = trace_thunks(render, state, key)
    finally:
        if args.pause:
            os.kill(args.pause, signal.SIGCONT)

    frames = args.envs * args.steps
    print(f"{args.task}, {args.envs} envs, {args.steps} agent steps a call, median of {args.repeats}\n")
    print("| program | agent steps/s | us per agent step |\n|---|---:|---:|")
    for name, s in seconds.items():
        print(f"| {name} | {frames / s:,.0f} | {1e6 * s / frames:.2f} |")
    look = getattr(env, "look", None)
    if look is not None:
        print(f"\nthe look's tables: walls {look.wall_prefix.nbytes / 2**20:.1f} MiB, sprite "
              f"{look.sprite_prefix.nbytes / 2**20:.2f} MiB (float32 prefix sums, read by gather)")
    gathers = gather_fusions(render.as_text())
    total = sum(per_thunk.values())
    print(f"\nrender, traced once: {1e3 * wall:.0f} ms wall, {total:.0f} ms of op time (both threads)")
    print("| thunk | share of op time | reads by gather | JAX operation |\n|---|---:|---|---|")
    for name, ms in per_thunk.most_common(8):
        print(f"| {name} | {100 * ms / total:.0f}% | {'yes' if name in gathers else ''} | {op_names.get(name, '')[-70:]} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
