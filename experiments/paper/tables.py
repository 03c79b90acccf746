"""The paper's Table 1 (success ratio at the end of the budget) and Table 2 (agent steps to
reach it) for LSTM-A3C, ICM, RND, SIM and EC on maze-dense, maze-sparse and maze-very-sparse,
with the paper's own numbers beside ours.

    python experiments/paper/tables.py [RUN_OR_SWEEP_FOLDER ...] [--out-dir experiments/results]

Default inputs: ``experiments/results/table1/*/`` (e.g. ``table1/maze-spot10-east-sim``);
each run is placed in the table by its config's ``env`` and ``algo`` (a folder written before the
tasks took the ICM wads' starts by the start it trained with, ``simjax.config_history``), a cell
without one is listed as missing with the command that would make it. A run on
``maze-spot10-east`` (spot 10 facing exactly east: maze-very-sparse until 2026-12-04) stands in
the paper's sparse column, marked as that start without the paper's 0-3.6 degree jitter. Writes
``experiments/results/paper-table1/table1.{csv,md,png}`` and ``paper-table2/table2.{csv,md,png}``;
the statistics are ``protocol.py``'s. Our Table 2 threshold is 0.9 over the last >= 100
episodes; the paper's "convergence standard" is not defined in its text.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import matplotlib.pyplot as plt  # noqa: E402
from protocol import PAPER_ALGO, THRESHOLD, steps_ratio  # noqa: E402
from report import (  # noqa: E402
    RESULTS,
    announce,
    draw_curve,
    final_cells,
    find_folders,
    fmt_steps,
    header_markdown,
    inputs_markdown,
    markdown_table,
    print_commands,
    read_all,
    steps_cells,
    style_success_axis,
    summarize,
    summary_csv_row,
    write_csv,
)

ENVS = ("maze-dense", "maze-sparse", "maze-very-sparse")
METHODS = ("a2c", "icm", "rnd", "sim", "ec")  # EC last: the other methods keep their colours
DEFAULT_INPUTS = ["experiments/results/table1/*/"]

# The paper's Table 1 (ViZDoom, 6 runs each): success ratio at convergence, as printed.
PAPER_TABLE1 = {
    "maze-dense": {"a2c": "100%", "icm": "100%", "rnd": "100%", "sim": "100%", "ec": "100%"},
    "maze-sparse": {"a2c": "0.0%", "icm": "66.7%", "rnd": "100%", "sim": "100%", "ec": "100%"},
    "maze-very-sparse": {"a2c": "0.0%", "icm": "68.6%", "rnd": "100%", "sim": "100%", "ec": "75.5%"},
}
# The paper's Table 2 (appendix B.4), environment steps to its "convergence standard". Its text
# (our copy of the paper) holds 9 of the table's 15 cells: "dense sparse very sparse 7.13m >10m
# >10m 6.01m 4.51m >10m 6.45m >10m 1.82m" under the columns LSTM-A3C, ICM, RND, EC, SIM. LSTM-A3C's
# and EC's three cells are there; ICM, RND and SIM have one value each, which we read as one cell
# spanning the three settings (B.4: "we measure the average convergence time for each algorithm
# across the ViZDoom tasks"). EC's steps include its 0.6M pretraining steps, as ours do.
PAPER_TABLE2 = {
    "maze-dense": {"a2c": "7.13m", "icm": "6.01m*", "rnd": "4.51m*", "sim": "1.82m*", "ec": ">10m"},
    "maze-sparse": {"a2c": ">10m", "icm": "6.01m*", "rnd": "4.51m*", "sim": "1.82m*", "ec": "6.45m"},
    "maze-very-sparse": {"a2c": ">10m", "icm": "6.01m*", "rnd": "4.51m*", "sim": "1.82m*", "ec": ">10m"},
}
# Table 2's ratios the paper's text draws (SIM converges in about 0.40 of RND's steps and 0.30 of
# ICM's): ours per setting, of median steps to the threshold, numerator first.
RATIOS = (("sim", "rnd"), ("sim", "icm"))
PAPER_RATIOS = {("sim", "rnd"): 1.82 / 4.51, ("sim", "icm"): 1.82 / 6.01}
PAPER_TABLE2_NOTE = ("*: the paper's text gives ICM, RND and SIM one value each, not one per setting (appendix B.4 "
                     "measures \"the average convergence time for each algorithm across the ViZDoom tasks\"); its "
                     "\"convergence standard\" is not defined, ours is a success ratio >= 0.9 over the last >= 100 episodes.")


# a start that stands in one of the paper's columns without being that column's task exactly
STANDS_IN = {"maze-spot10-east": "maze-sparse"}
STANDS_IN_NOTE = ("`maze-spot10-east` (marked +): spot 10 facing exactly east, the paper's sparse start without its "
                  "0-3.6 degree jitter ([which task is which](../../../docs/results.md#task-names)).")


def cells(points) -> dict:
    """{(setting, algo): [points]} for the table's cells (a setting is one of the paper's columns:
    a run's env, or the column it stands in); other points under (env, algo) too."""
    out: dict = {}
    for p in points:
        env = p.config.get("env")
        out.setdefault((STANDS_IN.get(env, env), p.config.get("algo")), []).append(p)
    return out


def setting_label(env: str, point) -> str:
    """A row's setting: the column, with the start the run had where it only stands in for it."""
    own = point.config.get("env")
    return env if own == env else f"{env} (as {own}+)"


def missing_command(env: str, algo: str, points) -> str:
    """A command for an empty cell, with the budget and seeds most of the table's runs have (and, for
    EC, the pretraining passes most of the table's EC runs have, where they are not the default)."""
    common = lambda key, ps=points: Counter(p.config[key] for p in ps).most_common(1)[0][0] if ps else key.upper()
    budget, extra = common("total_steps"), ""
    if algo == "ec":
        from simjax.agents.config import TrainConfig

        if isinstance(budget, int):  # EC's pretraining steps count on top of the policy's
            budget += TrainConfig().ec_pretrain_steps
        ec_runs = [p for p in points if p.config.get("algo") == "ec" and "ec_pretrain_epochs" in p.config]
        if ec_runs and (epochs := common("ec_pretrain_epochs", ec_runs)) != TrainConfig().ec_pretrain_epochs:
            extra = f" --ec-pretrain-epochs {epochs}"
    return (f"python -m simjax.train --env {env} --algo {algo} --total-steps {budget} "
            f"--num-seeds {common('num_seeds')}{extra} --out experiments/results/table1/{env}-{algo}")


def build(points, out_dir: Path) -> list[Path]:
    by_cell = cells([p for p in points if p.seeds])
    used = [p for key, ps in by_cell.items() if key[0] in ENVS and key[1] in METHODS for p in ps]
    others = [p for key, ps in by_cell.items() if not (key[0] in ENVS and key[1] in METHODS) for p in ps]
    rows1, rows2, csv1, csv2, missing = [], [], [], [], []
    summaries: dict = {}
    for env in ENVS:
        for algo in METHODS:
            paper1, paper2 = PAPER_TABLE1[env][algo], PAPER_TABLE2[env][algo]
            found = by_cell.get((env, algo), [])
            if not found:
                command = missing_command(env, algo, used)
                missing.append(f"- missing: {env} {algo}: `{command}`")
                print(f"missing {env} {algo}: {command}")
                rows1.append([env, PAPER_ALGO[algo], "no run", "", "", "", "", "", paper1])
                rows2.append([env, PAPER_ALGO[algo], "no run", "", "", "", "", "", paper2])
                csv1.append({"env": env, "algo": algo, "paper": paper1})
                csv2.append({"env": env, "algo": algo, "paper": paper2})
                continue
            for p in found:
                s = summarize(p)
                summaries.setdefault((env, algo), []).append(s)
                head = [setting_label(env, p), PAPER_ALGO[algo], f"`{p.name}`", str(len(p.seeds)),
                        f"{p.trained:,} / {p.budget:,}"]
                rows1.append(head + final_cells(s) + [paper1])
                rows2.append(head + steps_cells(s) + [paper2])
                row = summary_csv_row(s)
                csv1.append({"env": env, "algo": algo} | {k: v for k, v in row.items() if not k.startswith("steps")
                                                         and k != "reached"} | {"paper": paper1})
                csv2.append({"env": env, "algo": algo} | {k: v for k, v in row.items() if not k.startswith("final")}
                            | {"paper": paper2})
    head = ["setting", "method", "input", "seeds", "trained / budget"]
    notes = missing + ([f"- not in the table (other task or method): {', '.join(f'`{p.name}`' for p in others)}"] if others else [])
    if any(p.config.get("env") in STANDS_IN for p in used):
        notes.append(f"- {STANDS_IN_NOTE}")
    inputs = ["Inputs, and the commands that made them:", "", *inputs_markdown(used), ""]

    dir1, dir2 = out_dir / "paper-table1", out_dir / "paper-table2"
    dir1.mkdir(parents=True, exist_ok=True)
    dir2.mkdir(parents=True, exist_ok=True)
    md1 = header_markdown("Table 1: success ratio at the end of the budget", used, ("final", "seeds", "curves")) + markdown_table(
        head + ["final success per seed (episodes)", "mean [95%]", "median", "paper (Table 1)"], rows1, numeric=(3,))
    md1 += ["", "Paper: Table 1, ViZDoom, 6 runs per method; its budget is not stated with the table (its Table 2 "
            "counts up to >10m steps).", "", *notes, "", "![table1](table1.png)", "", *inputs]
    md2 = header_markdown(f"Table 2: agent steps to a success ratio of {THRESHOLD}", used, ("steps", "seeds")) + markdown_table(
        head + [f"steps to {THRESHOLD} per seed", "median [95%]", "reached", "paper (Table 2)"], rows2, numeric=(3,))
    ratio_rows, ratio_csv = ratios(summaries)
    md2 += ["", PAPER_TABLE2_NOTE, "", *RATIOS_INTRO, "", *markdown_table(
        ["setting", *(f"{PAPER_ALGO[a]} : {PAPER_ALGO[b]}" for a, b in RATIOS)], ratio_rows), "",
        *notes, "", "![table2](table2.png)", "", *inputs]

    paths = [dir1 / "table1.md", dir1 / "table1.csv", dir1 / "table1.png", dir2 / "table2.md", dir2 / "table2.csv",
             dir2 / "table2.png", dir2 / "table2-ratios.csv"]
    paths[0].write_text("\n".join(md1))
    write_csv(paths[1], csv1)
    draw_table1(by_cell, paths[2])
    paths[3].write_text("\n".join(md2))
    write_csv(paths[4], csv2)
    draw_table2(by_cell, paths[5])
    write_csv(paths[6], ratio_csv)
    print_commands(used)
    announce(*paths)
    return paths


RATIOS_INTRO = [f"Ratios of median agent steps to {THRESHOLD} (seeds that did not reach count as +inf), [95%] = "
                "percentile bootstrap, each method's seeds resampled on their own (a resample where neither median "
                "reaches could be any ratio: it counts as 0 at the low end and +inf at the high end); `<` / `>`: "
                "one method's median did not reach, so the ratio is beyond the one with its steps trained in its "
                "place; `neither reached`: no ratio. Paper: "
                + ", ".join(f"{PAPER_ALGO[a]} : {PAPER_ALGO[b]} = {PAPER_RATIOS[a, b]:.2f}" for a, b in RATIOS)
                + " (its Table 2's one value per method)."]


def fmt_ratio_value(x: float) -> str:
    return "inf" if math.isinf(x) else f"{x:.2f}"


def ratios(summaries: dict) -> tuple[list[list[str]], list[dict]]:
    """Table 2's SIM : RND and SIM : ICM per setting, for settings with one run in each cell."""
    rows, csv_rows = [], []
    for env in ENVS:
        row = [env]
        for a, b in RATIOS:
            sa, sb = summaries.get((env, a), []), summaries.get((env, b), [])
            if len(sa) != 1 or len(sb) != 1:
                row.append("no run" if not sa or not sb else "several runs in a cell")
                continue
            per_seed = [dict(zip(s.steps_summary.seeds, s.steps_summary.values)) for s in (sa[0], sb[0])]
            r = steps_ratio(*per_seed, (sa[0].point.trained, sb[0].point.trained))
            lo, hi = r.interval
            shown = "neither reached" if math.isnan(r.value) else f"{r.bound}{fmt_ratio_value(r.value)}"
            row.append(f"{shown} [{fmt_ratio_value(lo)}, {fmt_ratio_value(hi)}]")
            csv_rows.append({"env": env, "ratio": f"{a}:{b}", "value": r.value, "bound": r.bound, "low": lo,
                             "high": hi, "paper": PAPER_RATIOS[a, b]})
        rows.append(row)
    return rows, csv_rows


def draw_table1(by_cell: dict, path: Path) -> None:
    """The curves behind Table 1 (the paper's Figure 4): one panel per setting, one curve per method."""
    fig, axes = plt.subplots(1, len(ENVS), figsize=(15.6, 3.8))
    for ax, env in zip(axes, ENVS):
        drawn = False
        for i, algo in enumerate(METHODS):
            for p in by_cell.get((env, algo), []):
                draw_curve(ax, p, PAPER_ALGO[algo] + ("" if p.config.get("env") == env else "+"), color=f"C{i}")
                drawn = True
        style_success_axis(ax, env)
        if drawn:
            ax.legend(fontsize=7)
        else:
            ax.text(0.5, 0.5, "no runs yet", ha="center", va="center", transform=ax.transAxes, color="grey")
    fig.suptitle("Table 1's runs: success ratio against agent steps (mean over seeds, min-max band)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _paper_steps(text: str) -> float | None:
    text = text.rstrip("*")
    return None if text.startswith(">") else float(text.rstrip("m")) * 1e6


def draw_table2(by_cell: dict, path: Path) -> None:
    """Per setting: each seed's steps to 0.9 (a triangle at the steps trained if not reached),
    the median over seeds (a bar) and the paper's value (a cross) per method."""
    fig, axes = plt.subplots(1, len(ENVS), figsize=(15.6, 3.2), sharey=True)
    for ax, env in zip(axes, ENVS):
        for y, algo in enumerate(METHODS):
            for p in by_cell.get((env, algo), []):
                s = summarize(p)
                for seed, v in s.steps.items():
                    if v is None:
                        ax.plot(p.seeds[seed].last_step, y, ">", color=f"C{y}", markerfacecolor="none")
                    else:
                        ax.plot(v, y, "o", color=f"C{y}", alpha=0.7)
                if math.isfinite(s.steps_summary.median):
                    ax.plot(s.steps_summary.median, y, "|", color="black", markersize=16)
            paper = _paper_steps(PAPER_TABLE2[env][algo])
            if paper is not None:
                ax.plot(paper, y, "x", color="grey")
                ax.annotate(f"paper {fmt_steps(paper)}", (paper, y), xytext=(0, 6), textcoords="offset points",
                            fontsize=7, color="grey", ha="center")
        ax.set_yticks(range(len(METHODS)))
        ax.set_yticklabels([PAPER_ALGO[a] for a in METHODS])
        ax.set_ylim(-0.6, len(METHODS) - 0.4)
        ax.set_xlim(left=0)
        ax.set(xlabel="agent steps")
        ax.set_title(env, fontsize=9)
    fig.suptitle(f"Table 2: steps to success >= {THRESHOLD} (dots: seeds, >: not reached by the steps trained, "
                 "|: median, x: paper)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python experiments/paper/tables.py", description=__doc__.split("\n")[0])
    parser.add_argument("folders", nargs="*", help=f"run or sweep folders (default: {' '.join(DEFAULT_INPUTS)})")
    parser.add_argument("--out-dir", type=Path, default=RESULTS, help="where paper-table1/ and paper-table2/ go")
    args = parser.parse_args(argv)
    build(read_all(find_folders(args.folders, DEFAULT_INPUTS)), args.out_dir)
    return 0


if __name__ == "__main__":
    sys.exit(main())
