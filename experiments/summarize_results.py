"""Print the numbers the README quotes from committed run folders (experiments/results/*).

    python experiments/summarize_results.py experiments/results/very-sparse-*

Per run and seed: agent steps trained, success ratio and mean episode length over the first
and the last ~100k steps (4 log rows), the same for the extrinsic episode return (what
`melon` and `explore-goals` are judged by), policy entropy and mean bonus per step over the
last rows, and the best single row's success ratio.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from simjax.plotting import read_metrics


def summarize_run(run_dir: Path, rows: int = 4) -> list[str]:
    lines = []
    for seed, cols in sorted(read_metrics(run_dir).items()):
        def mean(name, part, cols=cols):
            values = np.asarray(cols[name][:rows] if part == "first" else cols[name][-rows:])
            values = values[np.isfinite(values)]
            return float(values.mean()) if values.size else float("nan")

        lines.append(
            f"| {run_dir.name} | {seed} | {int(cols['env_steps'][-1]):,} | {mean('success_ratio', 'first'):.3f} | "
            f"{mean('success_ratio', 'last'):.3f} | {np.nanmax(cols['success_ratio']):.3f} | "
            f"{mean('mean_extrinsic_return', 'first'):.2f} | {mean('mean_extrinsic_return', 'last'):.2f} | "
            f"{mean('mean_episode_length', 'last'):.0f} | {mean('entropy', 'last'):.3f} | {mean('bonus_mean', 'last'):.4f} |"
        )
    return lines


def main(argv: list[str]) -> int:
    print("| run | seed | agent steps | success, first 4 rows | success, last 4 rows | best row | "
          "return, first 4 | return, last 4 | episode length, last 4 | entropy, last 4 | bonus per step, last 4 |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for arg in argv:
        for line in summarize_run(Path(arg)):
            print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
