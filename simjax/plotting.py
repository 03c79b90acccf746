"""Learning curves from a run folder's metrics.csv (the paper's two measures).

Panels: success ratio; mean episode length, or the mean episode return where returns are
more than success (melon, explore-goals, gymnax); the mean bonus per step if there is one."""

from __future__ import annotations

import csv
import json
from collections import defaultdict
from pathlib import Path


def read_metrics(run_dir: Path) -> dict[int, dict[str, list[float]]]:
    """metrics.csv as {seed: {column: values}}."""
    path = Path(run_dir) / "metrics.csv"
    if not path.exists():
        raise FileNotFoundError(f"no metrics.csv in {run_dir}")
    by_seed: dict[int, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            seed = int(float(row["seed"]))
            for k, v in row.items():
                by_seed[seed][k].append(float(v))
    return by_seed


def plot_run(run_dir: Path, filename: str = "curve.png") -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    by_seed = read_metrics(run_dir)
    with_bonus = any(max(cols.get("bonus_mean", [0.0])) > 0 for cols in by_seed.values())
    returns = any(
        abs(r - s) > 1e-6 for cols in by_seed.values()
        for r, s in zip(cols["mean_extrinsic_return"], cols["success_ratio"]) if r == r
    )
    second = ("mean_extrinsic_return", "mean episode return") if returns else ("mean_episode_length", "mean episode length")
    fig, axes = plt.subplots(1, 3 if with_bonus else 2, figsize=(15 if with_bonus else 10, 3.6))
    for seed, cols in sorted(by_seed.items()):
        steps = cols["env_steps"]
        axes[0].plot(steps, cols["success_ratio"], label=f"seed {seed}")
        axes[1].plot(steps, cols[second[0]], label=f"seed {seed}")
        if with_bonus:
            axes[2].plot(steps, cols["bonus_mean"], label=f"seed {seed}")
    axes[0].set(xlabel="agent steps", ylabel="success ratio", ylim=(-0.02, 1.02))
    axes[1].set(xlabel="agent steps", ylabel=second[1])
    if with_bonus:
        axes[2].set(xlabel="agent steps", ylabel="mean bonus per step (beta r+)", yscale="log")
    fork = Path(run_dir) / "fork.json"  # a fork (simjax.fork): mark where it left its source
    if fork.exists():
        record = json.loads(fork.read_text())
        changed = ", ".join(f"{k} {a}->{b}" for k, (a, b) in record["changed"].items() if k != "total_steps")
        for ax in axes:
            ax.axvline(record["env_steps"], color="grey", linestyle="--", linewidth=1)
        axes[0].text(record["env_steps"], 0.5, f" fork: {changed} ", fontsize=7, color="grey", rotation=90,
                     ha="right", va="center")
    axes[0].legend(fontsize=8)
    fig.suptitle(Path(run_dir).name, fontsize=10)
    fig.tight_layout()
    out = Path(run_dir) / filename
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return out
