"""The screen: each arm against the control on the paper's very sparse start.

    python experiments/screen.py ARM [ARM ...] [--control FOLDER] [--budget 2000000]

An ARM is a run folder, or a sweep folder (one arm per point). The control is the committed
6 x 4M SIM run (``--control``, default ``experiments/results/table1/maze-very-sparse-sim``),
read only up to each arm's own last agent step, so both cover the same budget. Per arm:

- per seed, the final success ratio (the paper's protocol, ``experiments/paper/protocol.py``:
  the last rows covering 100k agent steps) and the steps to 0.9; across seeds the mean and its
  95% bootstrap interval;
- the successes over the whole run, against the uniform random policy's rate on the same task
  (``experiments/results/vizdoom-fidelity/random-policy-TASK.json``, simjax's episodes);
- the successes over the second half, the whole rows that start at or after half the arm's
  last step (1M of 2M), against the control's same rows: two-sided Fisher exact test;
- at the end (the final window's rows, the mean over rows and seeds): the bonus a step, the
  value and the policy entropy (ln 4 = 1.386 is the uniform policy's);
- the arm's ``--precision`` where it is not the control's;
- the verdict the issue asks for: *helps* where a seed reaches 0.9 or the second half's
  success ratio is above the control's with Fisher p < 0.01; otherwise *does not help at this
  budget* (the paper's SIM has converged by 2M).

Only numpy: reads metrics.csv and config.json, compiles nothing.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent / "paper"))

from protocol import Point, Series, across_seeds, final_success, fisher_exact, read_points, steps_to_threshold  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CONTROL = ROOT / "experiments" / "results" / "table1" / "maze-very-sparse-sim"
RANDOM = ROOT / "experiments" / "results" / "vizdoom-fidelity" / "random-policy-{task}.json"
P_HELPS = 0.01
AT_END = ("bonus_mean", "value_mean", "entropy")


def counts(series: Series, begin: int, end: int) -> tuple[int, int]:
    """(successes, episodes) over the whole rows that start at or after ``begin`` (the previous
    row's env_steps, 0 for the first) and end at or before ``end``."""
    starts = np.concatenate([[0], series.env_steps[:-1]])
    rows = (starts >= begin) & (series.env_steps <= end)
    return int(series.successes[rows].sum()), int(series.episodes[rows].sum())


def pooled(point: Point, begin: int, end: int) -> tuple[int, int]:
    per_seed = [counts(s, begin, end) for s in point.seeds.values()]
    return sum(a for a, _ in per_seed), sum(n for _, n in per_seed)


def random_rate(task: str) -> tuple[int, int] | None:
    path = Path(str(RANDOM).format(task=task))
    if not path.is_file():
        return None
    record = json.loads(path.read_text())["simjax"]
    return int(record["successes"]), int(record["episodes"])


def at_end(series: Series, name: str) -> float:
    final = final_success(series)
    rows = series.env_steps > final.from_step
    return float(np.nanmean(series.columns[name][rows]))


def report(point: Point, control: Point) -> bool:
    """Print one arm against the control; True where it helps."""
    last = min(s.last_step for s in point.seeds.values())
    half = last // 2
    label = point.source.name + (" (" + ", ".join(f"{k}={v}" for k, v in point.setting.items()) + ")"
                                 if point.setting else "")
    print(f"== {label}: {point.config['algo']} on {point.config['env']}, {len(point.seeds)} seeds x {last:,} agent steps")
    ours, theirs = (c.get("precision", "highest") for c in (point.config, control.config))
    if ours != theirs:
        print(f"  precision {ours}, the control's {theirs} (the precision's learning check found them within the seeds' "
              "spread on this start: docs/usage.md#precision)")
    finals, reached = {}, {}
    for seed, series in point.seeds.items():
        final = final_success(series)
        steps = steps_to_threshold(series)
        finals[seed] = final.ratio
        reached[seed] = math.inf if steps is None else float(steps)
        print(f"  seed {seed}: final success {final.ratio:.4f} ({final.successes}/{final.episodes} episodes in "
              f"({final.from_step:,}, {final.to_step:,}]), steps to 0.9 "
              + (f"{steps:,}" if steps is not None else f"> {series.last_step:,}")
              + "; at the end " + ", ".join(f"{n} {at_end(series, n):.4g}" for n in AT_END))
    summary = across_seeds(finals)
    print(f"  final success: mean {summary.mean:.4f}, 95% interval [{summary.interval[0]:.4f}, {summary.interval[1]:.4f}]")
    wins, episodes = pooled(point, 0, last)
    line = f"  whole run: {wins} successes in {episodes:,} episodes ({wins / max(episodes, 1):.3%})"
    rate = random_rate(point.config["env"])
    if rate is not None:
        line += f"; the random policy {rate[0] / rate[1]:.3%} ({rate[0]}/{rate[1]:,})"
    print(line)
    a, n = pooled(point, half, last)
    b, m = pooled(control, half, last)
    p = fisher_exact(a, n, b, m) if n and m else math.nan
    print(f"  second half ({half:,}, {last:,}]: {a}/{n:,} ({a / max(n, 1):.3%}) against the control's {b}/{m:,} "
          f"({b / max(m, 1):.3%}), Fisher p = {p:.3g}")
    above = n > 0 and m > 0 and a / n > b / m and p < P_HELPS
    helps = any(math.isfinite(v) for v in reached.values()) or above
    print("  verdict: " + ("HELPS (" + ("a seed reached 0.9" if any(map(math.isfinite, reached.values()))
                                        else f"second half above the control, p < {P_HELPS}") + ")"
                           if helps else "does not help at this budget: no seed at 0.9, the second half not above the "
                           f"control at p < {P_HELPS}"))
    return helps


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("arms", type=Path, nargs="+", metavar="ARM")
    parser.add_argument("--control", type=Path, default=CONTROL, help="the control run folder (default: %(default)s)")
    args = parser.parse_args(argv)
    for folder in [args.control, *args.arms]:
        if not (folder / "config.json").is_file() or not (folder / "metrics.csv").is_file():
            parser.error(f"{folder}: not a run folder (no config.json and metrics.csv)")
    (control,) = read_points(args.control)
    arms = [p for folder in args.arms for p in read_points(folder) if p.seeds]
    if not arms:
        parser.error("no arm has any rows yet")
    for point in arms:
        if point.config["env"] != control.config["env"]:
            parser.error(f"{point.source}: on {point.config['env']}, the control on {control.config['env']}")
    print(f"control: {control.source.name}, {len(control.seeds)} seeds, read up to each arm's last step")
    helped = [point for point in arms if report(point, control)]
    print(f"{len(helped)} of {len(arms)} arm(s) help")
    return 0


if __name__ == "__main__":
    sys.exit(main())
