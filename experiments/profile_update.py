"""Where a training update's time goes, from XLA:CPU's own trace (``jax.profiler``).

    python experiments/profile_update.py [--algo sim] [--task maze-very-sparse] [--seeds 1] [--precision highest]

Runs ``K`` updates (one compiled chunk, as ``make train`` runs it) under the JAX profiler, maps
every XLA:CPU thunk in the trace to the JAX operation it came from (the compiled HLO's
``op_name`` metadata), and prints the thunks per update and their time by kind: matmuls,
the patch convolutions' im2col (the strided slices and concatenation of the patches, and the
pads and transposes of their gradients), the casts of operands to bfloat16 (``--precision
bfloat16``), the ReLUs' gradients, the LSTMs' elementwise work, copies, and the rest; then the
same time by the network (module) it belongs to, forward and backward apart.
Op time sums the work of every thread, so it can exceed the wall time of an update.
"""

from __future__ import annotations

import argparse
import collections
import gzip
import json
import re
import tempfile
import time
from pathlib import Path

import jax

from simjax import runtime
from simjax.agents import TrainConfig, make_trainer, summarize
from simjax.runs.grid import batch_inputs, grid_of

SKIP = ("ThunkExecutor", "$", "SlinkyThreadPool", "end:", "Threadpool", "while")


def trace_thunks(compiled, *args):
    """Run a compiled (warmed-up) program once under the JAX profiler. Returns the wall
    seconds, two Counters by XLA:CPU thunk name (ms of op time, summed over threads; how many
    times it ran) and each thunk's JAX ``op_name`` from the compiled HLO's metadata."""
    op_names = {}
    for m in re.finditer(r"^\s*%(\S+) = [^\n]*", compiled.as_text(), re.M):
        found = re.search(r'op_name="([^"]+)"', m.group(0))
        op_names[m.group(1)] = found.group(1) if found else ""
    with tempfile.TemporaryDirectory() as folder:
        jax.profiler.start_trace(folder, create_perfetto_trace=True)
        started = time.perf_counter()
        jax.block_until_ready(compiled(*args))
        wall = time.perf_counter() - started
        jax.profiler.stop_trace()
        trace = json.load(gzip.open(next(Path(folder).rglob("perfetto_trace.json.gz"))))
    events = trace["traceEvents"] if isinstance(trace, dict) else trace
    times, counts = collections.Counter(), collections.Counter()
    for e in events:
        if e.get("ph") == "X" and not e["name"].startswith(SKIP):
            times[e["name"]] += e.get("dur", 0) / 1e3
            counts[e["name"]] += 1
    return wall, times, counts, op_names


def kind(thunk: str, op_name: str) -> str:
    last = op_name.rsplit("/", 1)[-1]
    if "PatchConv" in op_name and last in ("slice", "concatenate", "transpose", "pad", "reshape", "add_any"):
        return "im2col (patch slices, concatenation, their gradients)"
    if last == "dot_general" or thunk.startswith(("ynn_fusion", "dot")):
        return "matmuls"
    if last == "convert_element_type":
        return "casts (to bfloat16 and back)"
    if last == "select_n" and "transpose(" in op_name:
        return "ReLU gradients (selects)"
    if "LSTM" in op_name:
        return "LSTM elementwise"
    if thunk.startswith("copy"):
        return "copies"
    return "other"


def part(op_name: str) -> str:
    """The network an op belongs to, forward or backward: e.g. "SIMNet/FrameEmbedding_0 (backward)";
    "rollout (env, acting)" for the rollout's loop, "rest" for what no module names."""
    path = re.sub(r"^jit\([^)]*\)/(vmap\(\)/)?while/body/", "", op_name)
    if path.startswith("closed_call/while/body"):
        return "rollout (env, acting)"
    m = re.search(r"(transpose\()?jvp\((\w+)\)\)?/(\w+)", path)
    if not m:
        return "rest (losses, optimiser, bookkeeping)"
    return f"{m.group(2)}/{m.group(3)} ({'backward' if m.group(1) else 'forward'})"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--algo", default="sim")
    parser.add_argument("--task", default="maze-very-sparse")
    parser.add_argument("--seeds", type=int, default=1)
    parser.add_argument("--updates", type=int, default=4)
    parser.add_argument("--precision", choices=tuple(runtime.MATMUL_PRECISIONS), default=TrainConfig.precision)
    args = parser.parse_args(argv)
    with runtime.matmul_precision(args.precision):
        return profile(args)


def profile(args) -> int:
    K = args.updates
    extra = {"ec_pretrain_steps": 0} if args.algo == "ec" else {}
    config = TrainConfig(env=args.task, algo=args.algo, num_seeds=args.seeds, total_steps=16 * 20 * K,
                         log_every=16 * 20 * K, **extra)
    trainer = make_trainer(config)
    runner = jax.jit(jax.vmap(trainer.init))(*batch_inputs(config, grid_of({})))

    def chunk(r):
        r, metrics = trainer.run_chunk(r)
        return r, summarize(metrics)

    compiled = jax.jit(jax.vmap(chunk)).lower(runner).compile()
    runner = jax.block_until_ready(compiled(runner))[0]  # warm-up
    wall, per_thunk, counts, op_names = trace_thunks(compiled, runner)
    by_kind, by_part = collections.Counter(), collections.Counter()
    for name, ms in per_thunk.items():
        by_kind[kind(name, op_names.get(name, ""))] += ms
        by_part[part(op_names.get(name, ""))] += ms
    thunks = sum(counts.values())
    total = sum(by_kind.values())
    print(f"{args.algo}, precision {args.precision}, {args.seeds} seed(s), N = 16, T = 20: {1000 * wall / K:.0f} ms per update (wall, "
          f"under the profiler), {thunks // K:,} thunks and {total / K:.0f} ms of op time per update")
    print("| kind | ms per update | share of op time |\n|---|---:|---:|")
    for name, ms in by_kind.most_common():
        print(f"| {name} | {ms / K:.1f} | {100 * ms / total:.0f}% |")
    print("\n| network part | ms per update | share of op time |\n|---|---:|---:|")
    for name, ms in by_part.most_common(10):
        print(f"| {name} | {ms / K:.1f} | {100 * ms / total:.0f}% |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
