"""Does ``--precision bfloat16`` change what a run learns? Two run folders that differ only in
their precision (same task, method, seeds and settings), side by side: the precision's learning check.

    python experiments/precision_check.py RUN_A RUN_B [--from STEPS]

Per run and seed: the final success ratio and the steps to 0.9 (the paper's protocol,
``experiments/paper/protocol.py``), and the mean over the rows from agent step ``--from`` on of
the bonus a step (``bonus_mean``), the policy entropy and the value. For each measure, the two
runs' means over seeds, their difference, and the seeds' own spread: the larger of the two runs'
ranges (max - min over seeds). A measure is *within* when the difference is no larger than that
spread, so a precision that moved it by more than the seeds move it is called out.

If both folders hold a ``novelty_map.csv`` (``experiments/novelty_map.py RUN``: the model's error
at each of MyWayHome's 17 spawn spots, per seed), the spots' ranking by error is compared too:
Spearman's rank correlation for every pair of seeds within each run, and across the runs (seed i
of one against seed j of the other, i != j, and the same seed). *Within* when the median across
pair (i != j) is no lower than the lowest pair within a run: the other precision's models rank
the spots as differently as another seed's would, not more.
"""

from __future__ import annotations

import argparse
import csv
import itertools
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent / "paper"))

from protocol import differing_fields, final_success, read_points, steps_to_threshold  # noqa: E402

MEASURES = ("bonus_mean", "entropy", "value_mean")


def ranks(values: np.ndarray) -> np.ndarray:
    """Rank of each entry, 1 = largest."""
    order = np.argsort(-np.asarray(values), kind="stable")
    out = np.empty(len(order), int)
    out[order] = np.arange(1, len(order) + 1)
    return out


def spearman(a, b) -> float:
    """Spearman's rank correlation (the errors are continuous: no ties)."""
    d = ranks(a) - ranks(b)
    n = len(d)
    return float(1.0 - 6.0 * np.sum(d * d) / (n * (n * n - 1)))


def compare(a: dict[int, float], b: dict[int, float]) -> tuple[float, float, float, bool]:
    """Means over seeds of ``a`` and ``b`` (seed -> value), and the seeds' own spread (the larger
    range); within when |mean a - mean b| <= spread."""
    va, vb = np.asarray(list(a.values())), np.asarray(list(b.values()))
    spread = max(np.ptp(va), np.ptp(vb))
    return float(va.mean()), float(vb.mean()), float(spread), bool(abs(va.mean() - vb.mean()) <= spread)


def read_map(folder: Path) -> dict[int, np.ndarray] | None:
    """seed -> the error at each spawn spot (in spot order), or None without a novelty_map.csv."""
    path = folder / "novelty_map.csv"
    if not path.is_file():
        return None
    by_seed: dict[int, list[tuple[int, float]]] = {}
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            by_seed.setdefault(int(row["seed"]), []).append((int(row["spot"]), float(row["error"])))
    return {seed: np.asarray([e for _, e in sorted(rows)]) for seed, rows in sorted(by_seed.items())}


def spot_ranking(maps: dict[str, dict[int, np.ndarray]]) -> bool:
    (na, a), (nb, b) = maps.items()
    within = {name: [spearman(m[i], m[j]) for i, j in itertools.combinations(sorted(m), 2)] for name, m in maps.items()}
    across = [spearman(a[i], b[j]) for i in a for j in b if i != j]
    same = [spearman(a[i], b[i]) for i in a if i in b]
    print("the spots' ranking by the novelty model's error (novelty_map.csv), Spearman per pair of seeds:")
    for name, values in within.items():
        print(f"  within {name}: " + ", ".join(f"{v:+.2f}" for v in values))
    print("  across, other seed: " + ", ".join(f"{v:+.2f}" for v in across)
          + f" (median {np.median(across):+.2f})")
    print("  across, same seed: " + ", ".join(f"{v:+.2f}" for v in same))
    mean_a, mean_b = np.mean(list(a.values()), axis=0), np.mean(list(b.values()), axis=0)
    print(f"  the seeds' mean error per spot, {na} against {nb}: Spearman {spearman(mean_a, mean_b):+.2f}")
    lowest = min(min(v) for v in within.values())
    ok = bool(np.median(across) >= lowest)
    print(f"  {'within' if ok else 'OUTSIDE'} the seeds' own spread (median across {np.median(across):+.2f}, "
          f"lowest within {lowest:+.2f})")
    return ok


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", type=Path, nargs=2, metavar="RUN")
    parser.add_argument("--from", dest="start", type=int, default=0,
                        help="average the measures over the rows from this agent step on (default: all rows)")
    args = parser.parse_args(argv)
    for run in args.runs:
        if not (run / "config.json").is_file() or not (run / "metrics.csv").is_file():
            parser.error(f"{run}: not a run folder (no config.json and metrics.csv)")
    points = [read_points(run)[0] for run in args.runs]
    differ = differing_fields([p.config for p in points])
    if differ != ["precision"]:
        parser.error(f"the runs must differ in --precision alone; they differ in {differ or 'nothing'}")
    names = [p.config["precision"] for p in points]
    seeds = [set(p.seeds) for p in points]
    if seeds[0] != seeds[1]:
        parser.error(f"the runs' seeds differ: {sorted(seeds[0])} and {sorted(seeds[1])}")
    steps = [min(s.last_step for s in p.seeds.values()) for p in points]
    print(f"{points[0].config['algo']} on {points[0].config['env']}, seeds {sorted(seeds[0])}: "
          f"{names[0]} to {steps[0]:,} and {names[1]} to {steps[1]:,} agent steps per seed")
    if steps[0] != steps[1]:
        print("  (the runs have not trained the same steps: the comparison is of what each has)")
    print(f"{'seed':>4}  {'precision':>9}  {'final success':>13}  {'steps to 0.9':>12}  "
          + "  ".join(f"{m:>10}" for m in MEASURES) + f"   (means over rows from {args.start:,})")
    values: dict[str, list[dict[int, float]]] = {m: [{}, {}] for m in MEASURES + ("final",)}
    for seed in sorted(seeds[0]):
        for k, (name, point) in enumerate(zip(names, points)):
            series = point.seeds[seed]
            rows = series.env_steps >= args.start
            final = final_success(series)
            reached = steps_to_threshold(series)
            values["final"][k][seed] = final.ratio
            for m in MEASURES:
                values[m][k][seed] = float(np.nanmean(series.columns[m][rows]))
            print(f"{seed:4d}  {name:>9}  {final.ratio:13.3f}  "
                  + (f"{reached:12,d}" if reached is not None else f"{'> ' + format(series.last_step, ','):>12}")
                  + "  " + "  ".join(f"{values[m][k][seed]:10.4g}" for m in MEASURES))
    verdicts = []
    for m in ("final",) + MEASURES:
        mean_a, mean_b, spread, ok = compare(*values[m])
        verdicts.append(ok)
        print(f"{'final success' if m == 'final' else m:>13}: {names[0]} {mean_a:.4g}, {names[1]} {mean_b:.4g}, "
              f"difference {mean_b - mean_a:+.3g}, the seeds' spread {spread:.3g}: {'within' if ok else 'OUTSIDE'}")
    maps = {name: read_map(run) for name, run in zip(names, args.runs)}
    if all(m is not None for m in maps.values()):
        verdicts.append(spot_ranking(maps))
    else:
        print("(no novelty_map.csv in both folders: run experiments/novelty_map.py on each to compare the spots)")
    print("verdict: " + ("every measure within the seeds' own spread" if all(verdicts) else
                         "at least one measure OUTSIDE the seeds' own spread"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
