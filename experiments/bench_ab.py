"""Before and after: the training loop's speed at a git revision against the working tree, in one run.

    python experiments/bench_ab.py [--base HEAD] [--cells sim:1,sim:3,a2c:3,rnd:3,icm:3]
                                   [--rounds 2] [--reps 5] [--task maze-very-sparse] [--pause PID]

Speeds on this VM drift by 10-30% between runs, so a change is judged against its base measured
beside it: the base revision is checked out in a temporary git worktree, and fresh processes of
the base and of the working tree alternate ``--rounds`` times. Each process compiles every cell
(``bench.bench_loop``'s program: the chunk as ``make train`` runs it, 16 envs per seed, 8
updates), then measures the matmul peak and times each cell ``--reps`` times. The table gives
every process's median agent steps/s (all seeds together) and the ratio of the medians.

``--pause PID`` stops that process (SIGSTOP) while a side is timing and resumes it (SIGCONT)
after, so a training run in the background neither slows the timings nor loses its place.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def measure(cells: list[tuple[str, int]], task: str, reps: int, pause: int | None) -> dict:
    """In this process (whose ``simjax`` is the tree being measured): compile, then time."""
    import bench
    import jax

    import simjax
    from simjax.agents import TrainConfig

    if not Path(simjax.__file__).resolve().is_relative_to(Path(bench.__file__).resolve().parents[1]):
        raise RuntimeError(f"measuring {simjax.__file__}, not the tree of {bench.__file__}")

    programs = {}
    for algo, seeds in cells:
        extra = {"ec_pretrain_steps": 0} if algo == "ec" else {}
        config = TrainConfig(env=task, algo=algo, num_envs=16, num_seeds=seeds, total_steps=16 * 20 * 8,
                             log_every=16 * 20 * 8, **extra)
        chunk, runner = bench._sweep_chunk(config, {})
        compiled = jax.jit(chunk).lower(runner).compile()
        jax.block_until_ready(compiled(runner))
        programs[f"{algo}:{seeds}"] = (compiled, runner, 16 * 20 * 8 * seeds)
    if pause:
        os.kill(pause, signal.SIGSTOP)
        time.sleep(1)
    try:
        peak = bench.matmul_peak()
        speeds = {name: [] for name in programs}
        for _ in range(reps):
            for name, (compiled, runner, steps) in programs.items():
                started = time.perf_counter()
                jax.block_until_ready(compiled(runner))
                speeds[name].append(steps / (time.perf_counter() - started))
    finally:
        if pause:
            os.kill(pause, signal.SIGCONT)
    return {"peak": peak, "speeds": speeds}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--base", default="HEAD", help="git revision to compare the working tree against")
    parser.add_argument("--cells", default="sim:1,sim:3,a2c:3,rnd:3,icm:3", help="algo:seeds, comma-separated")
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--reps", type=int, default=5)
    parser.add_argument("--task", default="maze-very-sparse")
    parser.add_argument("--pause", type=int, default=None, help="pid to stop while timing (a training run)")
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    cells = []
    for cell in args.cells.split(","):
        algo, _, seeds = cell.partition(":")
        if not seeds.isdigit() or int(seeds) < 1:
            parser.error(f"a cell is algo:seeds, got {cell!r}")
        cells.append((algo, int(seeds)))
    if args.rounds < 1 or args.reps < 1:
        parser.error("--rounds and --reps must be at least 1")
    if args.pause is not None:
        os.kill(args.pause, 0)  # a clear error now if there is no such process
    if args.child:  # a measuring process: print one JSON line
        sys.path[:0] = [args.child, str(Path(args.child) / "experiments")]
        print(json.dumps(measure(cells, args.task, args.reps, args.pause)))
        return 0
    base = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", args.base], check=True,
                          capture_output=True, text=True).stdout.strip()
    results = {"base": [], "tree": []}
    with tempfile.TemporaryDirectory() as folder:
        worktree = Path(folder) / "base"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "-q", str(worktree), base], check=True)
        try:
            for _ in range(args.rounds):
                for side, tree in (("base", worktree), ("tree", ROOT)):
                    command = [sys.executable, __file__, "--child", str(tree), "--cells", args.cells,
                               "--reps", str(args.reps), "--task", args.task]
                    if args.pause is not None:
                        command += ["--pause", str(args.pause)]
                    out = subprocess.run(command, check=True, capture_output=True, text=True, cwd=tree).stdout
                    results[side].append(json.loads(out.strip().splitlines()[-1]))
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(worktree)], check=False)
    peaks = [r["peak"] / 1e9 for side in results.values() for r in side]
    print(f"base {base} against the working tree, {args.rounds} round(s) of {args.reps} timings, {args.task}; "
          f"matmul peak {min(peaks):.0f}-{max(peaks):.0f} GFLOP/s")
    print("| algo:seeds | base (median of each process) | working tree | tree / base |\n|---|---|---|---:|")
    for algo, seeds in cells:
        name = f"{algo}:{seeds}"
        b = [statistics.median(r["speeds"][name]) for r in results["base"]]
        t = [statistics.median(r["speeds"][name]) for r in results["tree"]]
        print(f"| {name} | {', '.join(f'{x:,.0f}' for x in b)} | {', '.join(f'{x:,.0f}' for x in t)} | "
              f"{statistics.median(t) / statistics.median(b):.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
