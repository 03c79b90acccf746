"""The transfer figure: a policy trained only in simjax, run in simjax and in real ViZDoom.

    python experiments/transfer_figure.py RUN [--out FILE.png]

Reads the ``evaluate-simjax*.json`` and ``evaluate-vizdoom*.json`` that ``python -m
simjax.evaluate RUN --backend ...`` wrote into the run folder, and draws each seed's success
ratio (with its 95% Wilson interval) beside the random policy's, on both backends. Writes
``RUN/transfer.png`` unless ``--out`` says otherwise, and prints the numbers as a markdown table.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def load(run: Path) -> list[dict]:
    results = [json.loads(p.read_text()) for p in sorted(run.glob("evaluate-*.json"))]
    if not results:
        raise SystemExit(f"{run} has no evaluate-*.json; run python -m simjax.evaluate {run} --backend ... first")
    return results


def table(results: list[dict]) -> str:
    rows = ["| backend | seed | policy success [95%] | random success [95%] | policy mean length | episodes |",
            "|---|---:|---|---|---:|---:|"]
    for r in results:
        p, q = r["policy"], r["random"]
        rows.append(f"| {r['backend']} | {r['seed']} | {p['success_ratio']:.3f} "
                    f"[{p['success_95'][0]:.3f}, {p['success_95'][1]:.3f}] | {q['success_ratio']:.3f} "
                    f"[{q['success_95'][0]:.3f}, {q['success_95'][1]:.3f}] | {p['mean_episode_length']:.0f} | "
                    f"{p['episodes']} / {q['episodes']} |")
    return "\n".join(rows)


def draw(results: list[dict], out: Path, title: str) -> None:
    fig, ax = plt.subplots(figsize=(1.6 + 1.3 * len(results), 3.6))
    for i, r in enumerate(results):
        for j, (who, colour) in enumerate((("policy", "tab:blue"), ("random", "tab:grey"))):
            s = r[who]
            x = i + (j - 0.5) * 0.35
            ax.bar(x, s["success_ratio"], 0.33, color=colour, label=who if i == 0 else None)
            lo, hi = s["success_95"]
            ax.errorbar(x, s["success_ratio"], yerr=[[s["success_ratio"] - lo], [hi - s["success_ratio"]]],
                        color="black", capsize=3, linewidth=1)
    ax.set_xticks(np.arange(len(results)))
    ax.set_xticklabels([f"{r['backend']}\nseed {r['seed']}" for r in results], fontsize=8)
    ax.set_ylabel("success ratio (95% interval)")
    ax.set_ylim(0, 1)
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", type=Path)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    results = load(args.run)
    results.sort(key=lambda r: (r["backend"] != "simjax", r["seed"]))
    r0 = results[0]
    title = f"{r0['env']} policy trained in simjax ({r0['env_steps']:,} steps), run in simjax and in ViZDoom"
    out = args.out or args.run / "transfer.png"
    draw(results, out, title)
    print(table(results))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
