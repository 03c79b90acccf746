"""Learning curves from a run folder's metrics.csv (the paper's two measures).

Panels: success ratio; mean episode length, or the mean episode return where returns are
more than success (melon, explore-goals, gymnax); the mean bonus per step if there is one."""

from __future__ import annotations

import csv
import json
import warnings
from collections import defaultdict
from pathlib import Path


def swept_columns(run_dir: Path) -> tuple[str, ...]:
    """The swept settings of a sweep's folder (metrics.csv's columns before ``env_steps``)."""
    with open(Path(run_dir) / "metrics.csv", newline="") as f:
        header = next(csv.reader(f))
    return tuple(header[: header.index("env_steps")])


def read_members(run_dir: Path) -> dict[tuple, dict[str, list[float]]]:
    """metrics.csv as {(point, seed): {column: values}}; a point is a tuple of (setting, value)
    pairs, () for a plain run."""
    path = Path(run_dir) / "metrics.csv"
    if not path.exists():
        raise FileNotFoundError(f"no metrics.csv in {run_dir}")
    swept = swept_columns(run_dir)
    members: dict[tuple, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            key = (tuple((k, float(row[k])) for k in swept), int(float(row["seed"])))
            for k, v in row.items():
                members[key][k].append(float(v))
    return members


def read_metrics(run_dir: Path) -> dict[int, dict[str, list[float]]]:
    """metrics.csv of a plain run as {seed: {column: values}} (a sweep: ``read_members``)."""
    members = read_members(run_dir)
    if any(point for point, _ in members):
        raise ValueError(f"{run_dir} is a sweep; read it with read_members")
    return {seed: cols for (_, seed), cols in members.items()}


def _label(point: tuple) -> str:
    return ", ".join(f"{k}={v:g}" for k, v in point)


def plot_run(run_dir: Path, filename: str = "curve.png") -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    members = read_members(run_dir)
    with_bonus = any(max(cols.get("bonus_mean", [0.0])) > 0 for cols in members.values())
    returns = any(
        abs(r - s) > 1e-6 for cols in members.values()
        for r, s in zip(cols["mean_extrinsic_return"], cols["success_ratio"]) if r == r
    )
    second = ("mean_extrinsic_return", "mean episode return") if returns else ("mean_episode_length", "mean episode length")
    columns = ["success_ratio", second[0]] + (["bonus_mean"] if with_bonus else [])
    fig, axes = plt.subplots(1, 3 if with_bonus else 2, figsize=(15 if with_bonus else 10, 3.6))
    points = sorted({point for point, _ in members})
    if points == [()]:  # a plain run: one curve per seed
        for (_, seed), cols in sorted(members.items()):
            for ax, column in zip(axes, columns):
                ax.plot(cols["env_steps"], cols[column], label=f"seed {seed}")
    else:  # a sweep: one curve per point, the mean over its seeds, the band from min to max
        for point in points:
            seeds = [cols for (p, _), cols in sorted(members.items()) if p == point]
            rows = min(len(c["env_steps"]) for c in seeds)
            steps = seeds[0]["env_steps"][:rows]
            for ax, column in zip(axes, columns):
                values = np.array([c[column][:rows] for c in seeds])
                with warnings.catch_warnings():  # rows where no seed ended an episode are NaN
                    warnings.simplefilter("ignore", RuntimeWarning)
                    line = ax.plot(steps, np.nanmean(values, axis=0), label=f"{_label(point)} ({len(seeds)} seeds)")
                    ax.fill_between(steps, np.nanmin(values, axis=0), np.nanmax(values, axis=0),
                                    color=line[0].get_color(), alpha=0.2, linewidth=0)
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
