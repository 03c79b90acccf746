"""What Figures 5 and 6 (the DeepMind Lab tasks) share: one task, one run folder per method, a
measure the paper's claims are about (the success ratio on ``melon``, the episode reward on
``explore-goals``), a verdict on each claim, and the curves beside the random policy's level.

A method's input is a run (or sweep) folder whose config has the figure's ``env`` and the
method's ``algo``; where several have, the one named ``ENV-ALGO`` is used, else the one with
the most seeds and steps, and the others are listed as unused. A method with no input is
listed with the command that makes it. Per method and seed: the steps to the measure's
threshold (``protocol.steps_to_threshold`` on the measure's column: the first row at which the
mean over the most recent >= 100 episodes, weighted by episodes, is >= the threshold), the
final level (``protocol.level``: the mean over the episodes of the fewest last rows covering
>= 100k agent steps) and, where the figure names a step, the level at it (the same window, of
the rows that end at or before that step). Across seeds: ``protocol.across_seeds`` (median
steps with +inf for not reached, mean level, percentile-bootstrap intervals); SIM's speed
against each method: ``protocol.steps_ratio`` of median steps. The paper finds these curves
unstable ("ubiquitous glitches"), so the curves are read as running means: at each row each
seed's mean over its most recent >= 100 episodes, then the mean over seeds with a min-max band
(``protocol.mean_curve``). Only numpy and matplotlib: nothing is compiled.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import textwrap
from collections.abc import Callable
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from protocol import (  # noqa: E402
    PAPER_ALGO,
    SUCCESS,
    WINDOW_EPISODES,
    WINDOW_STEPS,
    Level,
    Point,
    SeedSummary,
    StepsRatio,
    across_seeds,
    label_points,
    level,
    mean_curve,
    steps_ratio,
    steps_to_threshold,
)
from report import (  # noqa: E402
    RESULTS,
    announce,
    commit,
    find_folders,
    fmt_steps,
    inputs_markdown,
    markdown_table,
    print_commands,
    read_all,
    rel,
    this_command,
    today,
    write_csv,
)

RETURN = "mean_extrinsic_return"
COLORS = {"sim": "C3", "rnd": "C2", "icm": "C1", "a2c": "C0", "ec": "C4"}  # as in no other figure: one colour a method
RUNNING_MEAN = (f"Curves: a running mean, as the paper's curves are unstable (\"ubiquitous glitches\"): at each log row, "
                f"each seed's mean over its most recent >= {WINDOW_EPISODES} episodes (whole rows, weighted by episodes; "
                f"none before a seed has {WINDOW_EPISODES}), then the mean over seeds, band = min-max over seeds.")
HOLDS, FAILS, UNKNOWN, NO_RUN = "holds", "does not hold", "cannot tell", "no run"


@dataclasses.dataclass(frozen=True)
class Measure:
    """A metrics.csv column read per episode: ``threshold`` is the level whose first crossing is
    timed; ``random`` the uniform random policy's level and its 95% interval."""

    column: str
    name: str  # in words, as the axis and the tables say it
    threshold: float | None
    random: tuple[float, float, float] | None
    digits: int = 3

    def fmt(self, x: float | None) -> str:
        return "–" if x is None or math.isnan(x) else f"{x:.{self.digits}f}"

    @property
    def threshold_text(self) -> str:
        """The threshold as the text says it: 0.8, 20."""
        return f"{self.threshold:g}"


@dataclasses.dataclass(frozen=True)
class Method:
    algo: str
    budget: int  # agent steps per seed the paper's protocol (ours: 3 seeds) trains it
    flags: str = ""  # further train flags (EC's pretraining passes)

    @property
    def name(self) -> str:
        return PAPER_ALGO.get(self.algo, self.algo)


@dataclasses.dataclass(frozen=True)
class Result:
    """One method's numbers on the figure's measure (``at``: the level at the figure's step)."""

    method: Method
    point: Point
    label: str
    steps: dict  # seed -> first step at >= threshold, or None
    steps_summary: SeedSummary  # +inf for not reached; interval of the median
    final: dict  # seed -> protocol.Level over the last >= 100k steps
    final_summary: SeedSummary  # interval of the mean
    at: dict  # seed -> protocol.Level over the last >= 100k steps up to the figure's step ({} if none)
    at_summary: SeedSummary | None

    @property
    def trained(self) -> int:
        return self.point.trained

    @property
    def reached(self) -> int:
        return sum(v is not None for v in self.steps.values())

    def steps_values(self) -> dict[int, float]:
        return {s: math.inf if v is None else float(v) for s, v in self.steps.items()}

    def steps_per_seed(self) -> str:
        return " / ".join(fmt_steps(v, self.point.seeds[s].last_step) for s, v in self.steps.items())

    def steps_median(self) -> str:
        """Median [95%], a median not reached as >(steps trained)."""
        lo, hi = self.steps_summary.interval
        t = self.trained
        return f"{fmt_steps(self.steps_summary.median, t)} [{fmt_steps(lo, t)}, {fmt_steps(hi, t)}]"

    def in_progress(self) -> str:
        return "" if self.trained >= self.method.budget else f" (in progress: {fmt_steps(self.trained)} of {fmt_steps(self.method.budget)})"


@dataclasses.dataclass(frozen=True)
class Figure:
    name: str  # figure6: its output files' and results folder's name
    title: str
    env: str
    methods: tuple[Method, ...]  # SIM first
    measure: Measure  # the measure the claims are about
    panels: tuple[Measure, ...]  # the curve panels, left to right (the paper's)
    claim_step: int  # the step the claim about SIM names (a vertical line)
    at: int | None  # a step at which each seed's level is read as well (Figure 5's 1M)
    paper: str  # the paper's claim, in its words
    random_note: str  # where the random policy's levels come from
    verdicts: Callable[[Figure, dict], list[tuple[str, str, str]]]  # (claim, ours, verdict) from {algo: Result}
    notes: tuple[str, ...] = ()  # sentences for the markdown, after the definitions


# -- numbers ----------------------------------------------------------------------------------------


def levels_summary(levels: dict[int, Level]) -> SeedSummary:
    return across_seeds({s: lv.value for s, lv in levels.items()}, "mean")


def summarize(figure: Figure, method: Method, point: Point, label: str) -> Result:
    m = figure.measure
    steps = {s: steps_to_threshold(series, m.threshold, column=m.column) for s, series in point.seeds.items()}
    final = {s: level(series, m.column) for s, series in point.seeds.items()}
    at = {s: level(series, m.column, until=figure.at) for s, series in point.seeds.items()} if figure.at else {}
    steps_summary = across_seeds({s: math.inf if v is None else float(v) for s, v in steps.items()}, "median")
    return Result(method, point, label, steps, steps_summary, final, levels_summary(final), at,
                  levels_summary(at) if at else None)


def choose(figure: Figure, method: Method, points: list[Point]) -> list[Point]:
    """The inputs of ``method`` on the figure's task, the one the numbers read first."""
    hits = [p for p in points if p.config.get("env") == figure.env and p.config.get("algo") == method.algo]
    return sorted(hits, key=lambda p: (p.source.name != f"{figure.env}-{method.algo}", -len(p.seeds) * p.trained))


def speed(sim: Result, other: Result) -> StepsRatio:
    """SIM's median steps to the threshold over ``other``'s."""
    return steps_ratio(sim.steps_values(), other.steps_values(), (sim.trained, other.trained))


def ratio_text(r: StepsRatio) -> str:
    if math.isnan(r.value):
        return "neither reached"
    number = lambda x: "inf" if math.isinf(x) else f"{x:.2f}"
    lo, hi = r.interval
    return f"{r.bound}{number(r.value)} [{number(lo)}, {number(hi)}]"


def as_fast_text(r: StepsRatio) -> str:
    """How many times as fast SIM is (the ratio's inverse): "4.0x", "> 5.0x", "< 0.5x"."""
    if math.isnan(r.value) or r.value == 0:
        return "–"
    bound = {"<": "> ", ">": "< "}.get(r.bound, "")
    return f"{bound}{1 / r.value:.1f}x"


def at_least_as_fast(r: StepsRatio, factor: float) -> str:
    """Whether SIM is at least ``factor`` times as fast: a method that did not reach may reach
    later (cannot tell unless SIM beat even its steps trained by the factor)."""
    if math.isnan(r.value):
        return UNKNOWN  # neither reached
    if r.bound == ">":
        return FAILS  # SIM did not reach, the other did
    if r.value <= 1 / factor:
        return HOLDS
    return UNKNOWN if r.bound == "<" else FAILS


def within(result: Result | None, limit: int) -> str:
    """Whether the median over seeds reached the threshold by ``limit`` steps."""
    if result is None:
        return NO_RUN
    median = result.steps_summary.median
    if median <= limit:
        return HOLDS
    if math.isinf(median) and result.trained < limit:
        return UNKNOWN
    return FAILS


def overall(outcomes: list[str]) -> str:
    if FAILS in outcomes:
        return FAILS
    if outcomes and all(o == HOLDS for o in outcomes):
        return HOLDS
    return UNKNOWN if any(o != NO_RUN for o in outcomes) else NO_RUN


def level_text(measure: Measure, summary: SeedSummary | None, levels: dict[int, Level]) -> str:
    """``a / b / c (episodes ...), mean m [lo, hi]``."""
    if summary is None or not levels:
        return "–"
    lo, hi = summary.interval
    per_seed = " / ".join(measure.fmt(lv.value) for lv in levels.values())
    return f"{per_seed}; mean {measure.fmt(summary.mean)} [{measure.fmt(lo)}, {measure.fmt(hi)}]"


def speed_verdict(figure: Figure, results: dict, factor: float) -> tuple[str, str]:
    """(ours, verdict) of "SIM is at least ``factor`` times as fast as every other method"."""
    sim = results.get("sim")
    if sim is None:
        return "no SIM run", NO_RUN
    parts, outcomes = [], []
    for method in figure.methods[1:]:
        other = results.get(method.algo)
        if other is None:
            parts.append(f"{method.name}: no run")
            outcomes.append(NO_RUN)
            continue
        r = speed(sim, other)
        outcome = at_least_as_fast(r, factor)
        if outcome == FAILS and r.bound == ">" and sim.in_progress():
            outcome = UNKNOWN  # SIM has not reached yet, but may
        parts.append(f"{method.name}: SIM : {method.name} = {ratio_text(r)}, SIM {as_fast_text(r)} as fast ({outcome})")
        outcomes.append(outcome)
    return "; ".join(parts), overall(outcomes)


# -- output -----------------------------------------------------------------------------------------


def missing_command(figure: Figure, method: Method) -> str:
    flags = f" {method.flags}" if method.flags else ""
    return (f"python -m simjax.train --env {figure.env} --algo {method.algo} --total-steps {method.budget} --num-seeds 3"
            f"{flags} --out experiments/results/{figure.name}/{figure.env}-{method.algo}")


def level_cells(measure: Measure, levels: dict[int, Level], summary: SeedSummary | None) -> list[str]:
    if summary is None or not levels:
        return ["–", "–"]
    lo, hi = summary.interval
    return [" / ".join(f"{measure.fmt(lv.value)} ({lv.episodes})" for lv in levels.values()),
            f"{measure.fmt(summary.mean)} [{measure.fmt(lo)}, {measure.fmt(hi)}]"]


def csv_row(figure: Figure, r: Result, ratio: StepsRatio | None) -> dict:
    m = figure.measure
    slo, shi = r.steps_summary.interval
    flo, fhi = r.final_summary.interval
    row = {"figure": figure.name, "method": r.method.name, "algo": r.method.algo, "label": r.label,
           "source": rel(r.point.source), "setting": ";".join(f"{k}={v}" for k, v in r.point.setting.items()),
           "env": r.point.config.get("env"), "seeds": ";".join(map(str, r.point.seeds)), "budget": r.point.budget,
           "trained": r.trained, "measure": m.column, "threshold": m.threshold,
           "steps_to_threshold_per_seed": ";".join("" if v is None else str(v) for v in r.steps.values()),
           "reached": r.reached, "steps_to_threshold_median": f"{r.steps_summary.median:.6g}",
           "steps_median_ci_low": f"{slo:.6g}", "steps_median_ci_high": f"{shi:.6g}",
           "final_per_seed": ";".join(f"{lv.value:.6g}" for lv in r.final.values()),
           "final_episodes_per_seed": ";".join(str(lv.episodes) for lv in r.final.values()),
           "final_mean": f"{r.final_summary.mean:.6g}", "final_mean_ci_low": f"{flo:.6g}",
           "final_mean_ci_high": f"{fhi:.6g}"}
    if figure.at and r.at_summary is not None:
        alo, ahi = r.at_summary.interval
        row |= {"at_step": figure.at, "at_per_seed": ";".join(f"{lv.value:.6g}" for lv in r.at.values()),
                "at_episodes_per_seed": ";".join(str(lv.episodes) for lv in r.at.values()),
                "at_window_per_seed": ";".join(f"{lv.from_step}-{lv.to_step}" for lv in r.at.values()),
                "at_mean": f"{r.at_summary.mean:.6g}", "at_mean_ci_low": f"{alo:.6g}", "at_mean_ci_high": f"{ahi:.6g}"}
    if ratio is not None:
        row |= {"sim_ratio": f"{ratio.value:.6g}", "sim_ratio_bound": ratio.bound,
                "sim_ratio_ci_low": f"{ratio.interval[0]:.6g}", "sim_ratio_ci_high": f"{ratio.interval[1]:.6g}"}
    return row


def draw(figure: Figure, results: dict, verdicts: list[tuple[str, str, str]], path: Path) -> list[dict]:
    """The curve panels (one per measure, the paper's) and a text panel with the paper's claim
    and the verdicts; returns the curves' CSV rows."""
    n = len(figure.panels)
    fig, axes = plt.subplots(1, n + 1, figsize=(5.4 * n + 4.6, 4.4), gridspec_kw={"width_ratios": [5.4] * n + [4.6]})
    rows = []
    budget = max((m.budget for m in figure.methods if m.algo in results), default=max(m.budget for m in figure.methods))
    for ax, measure in zip(axes, figure.panels):
        for method in figure.methods:
            r = results.get(method.algo)
            if r is None:
                continue
            curve = mean_curve(r.point.seeds, measure.column)
            ax.plot(curve.env_steps, curve.mean, color=COLORS.get(method.algo), linewidth=1.3,
                    label=f"{method.name} ({len(r.point.seeds)} seeds)")
            ax.fill_between(curve.env_steps, curve.low, curve.high, color=COLORS.get(method.algo), alpha=0.18, linewidth=0)
            rows += [{"figure": figure.name, "measure": measure.column, "method": method.name, "label": r.label,
                      "source": rel(r.point.source), "env_steps": int(x), "mean": f"{mean:.6g}", "low": f"{lo:.6g}",
                      "high": f"{hi:.6g}", "seeds": int(k)}
                     for x, mean, lo, hi, k in zip(curve.env_steps, curve.mean, curve.low, curve.high, curve.seeds)]
        if measure.random is not None:
            ax.axhline(measure.random[0], color="black", linewidth=0.9, linestyle="--",
                       label=f"random policy ({measure.fmt(measure.random[0])})")
        if measure is figure.measure and measure.threshold is not None:
            ax.axhline(measure.threshold, color="grey", linewidth=0.8, linestyle=":")
            ax.axvline(figure.claim_step, color="grey", linewidth=0.8, linestyle=":")
        ax.set(xlabel="agent steps", ylabel=f"{measure.name} (last >= {WINDOW_EPISODES} episodes)", xlim=(0, budget))
        if measure.column == SUCCESS:
            ax.set_ylim(-0.02, 1.02)
        else:
            ax.set_ylim(bottom=0)
        ax.set_title(f"{figure.env}: {measure.name}\nrunning mean per seed, mean over seeds, band min-max", fontsize=8)
        if results:
            ax.legend(fontsize=7, loc="upper left")
        else:
            ax.text(0.5, 0.5, "no runs yet", ha="center", va="center", transform=ax.transAxes, color="grey")
    text = axes[-1]
    text.axis("off")
    lines = ["The paper:"] + textwrap.wrap(f"\"{figure.paper}\"", 60) + ["", "Ours:"]
    for claim, _, verdict in verdicts:
        lines += textwrap.wrap(f"- {claim}: {verdict.upper()}", 60)
    lines += [""] + textwrap.wrap(RUNNING_MEAN, 60)
    text.text(0, 1, "\n".join(lines), va="top", ha="left", fontsize=7, family="sans-serif", transform=text.transAxes)
    fig.suptitle(figure.title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return rows


def definitions(figure: Figure) -> str:
    m = figure.measure
    at = (f"; at {fmt_steps(figure.at)}: the same, of the rows that end at or before {figure.at:,} agent steps"
          if figure.at else "")
    return (f"Steps to {m.threshold_text}: the first log row at which the {m.name} over the most recent >= "
            f"{WINDOW_EPISODES} episodes (whole rows, weighted by episodes) is >= {m.threshold_text}; `>N` = not "
            f"reached in the N steps trained. Final: the {m.name} over the episodes of the fewest last rows covering >= "
            f"{WINDOW_STEPS:,} agent steps{at}. Across seeds: the mean of the levels and the median of the steps (a seed "
            "that did not reach counts as +inf); [95%] = percentile bootstrap over seeds (10,000 resamples, numpy seed "
            f"0). {RUNNING_MEAN} Definitions: `experiments/paper/protocol.py`.")


def report(figure: Figure, points: list[Point], out: Path) -> list[Path]:
    """figure's PNG, per-method CSV, curves CSV and markdown; the commands of missing inputs printed."""
    out.mkdir(parents=True, exist_ok=True)
    points = [p for p in points if p.seeds]
    chosen, unused, missing = {}, [], []
    for method in figure.methods:
        hits = choose(figure, method, points)
        if hits:
            chosen[method.algo] = hits[0]
            unused += hits[1:]
        else:
            missing.append(method)
    unused += [p for p in points if all(p is not q for q in chosen.values()) and p not in unused]
    labels = dict(zip(chosen, label_points(list(chosen.values()))))
    results = {m.algo: summarize(figure, m, chosen[m.algo], labels[m.algo]) for m in figure.methods if m.algo in chosen}
    verdicts = figure.verdicts(figure, results)
    m = figure.measure
    at = f" at {fmt_steps(figure.at)}" if figure.at else ""
    budgets = ", ".join(f"{b:,}" for b in sorted({q.budget for q in chosen.values()})) or "none yet"
    md = [f"# {figure.title}", "", f"Made by `{this_command()}` on {today()}, commit {commit()}; budget {budgets} agent "
          "steps per seed.", ""]
    md += [definitions(figure), "", *figure.notes, *([""] if figure.notes else [])]
    md += ["## The paper's claims and our verdicts", "", f"The paper: \"{figure.paper}\"", ""]
    md += markdown_table(["claim", "ours", "verdict"], [[c, o, f"**{v}**"] for c, o, v in verdicts])
    md += ["", "## Per method", ""]
    rows, csv_rows = [], []
    sim = results.get("sim")
    for method in figure.methods:
        r = results.get(method.algo)
        if r is None:
            rows.append([method.name, "no run", "", "", "", "", "", *(["", ""] if figure.at else []), "", ""])
            continue
        ratio = speed(sim, r) if sim is not None and r is not sim else None
        rows.append([r.label, f"`{r.point.name}`", str(len(r.point.seeds)), f"{r.trained:,} / {r.point.budget:,}",
                     r.steps_per_seed(), r.steps_median(), f"{r.reached}/{len(r.steps)}",
                     *(level_cells(m, r.at, r.at_summary) if figure.at else []), *level_cells(m, r.final, r.final_summary)])
        csv_rows.append(csv_row(figure, r, ratio))
    md += markdown_table(["method", "input", "seeds", "trained / budget", f"steps to {m.threshold_text} per seed",
                          "median [95%]", "reached", *([f"{m.name}{at} per seed (episodes)", "mean [95%]"] if figure.at else []),
                          f"final {m.name} per seed (episodes)", "mean [95%]"], rows, numeric=(2,))
    if sim is not None and len(results) > 1:
        md += ["", f"SIM's median steps to {m.threshold_text} over each method's (`protocol.steps_ratio`; a median not "
                   "reached counts as the steps that method trained, so the ratio is a bound):", ""]
        md += markdown_table(["method", f"median steps to {m.threshold_text} [95%]", "SIM : method [95%]", "SIM as fast as"],
                             [[r.method.name, r.steps_median(), ratio_text(speed(sim, r)), as_fast_text(speed(sim, r))]
                              for a, r in results.items() if a != "sim"])
    md += ["", figure.random_note, ""]
    for method in missing:
        command = missing_command(figure, method)
        md.append(f"- missing: {method.name} (no input with env={figure.env}, algo={method.algo}); to make it: `{command}`")
        print(f"missing {method.name}: {command}")
    if missing:
        md.append("")
    if unused:
        md += ["Inputs not used (another task or method, or a second run of a method): "
               + ", ".join(f"`{p.name}`" for p in unused), ""]
    paths = [out / f"{figure.name}.png", out / f"{figure.name}.csv", out / f"{figure.name}-curves.csv", out / f"{figure.name}.md"]
    curve_rows = draw(figure, results, verdicts, paths[0])
    md += [f"![{figure.name}]({figure.name}.png)", "", "Inputs, and the commands that made them:", "",
           *inputs_markdown(list(chosen.values())), ""]
    write_csv(paths[1], csv_rows, ("figure", "method", "algo", "label", "source", "seeds", "budget", "trained"))
    write_csv(paths[2], curve_rows, ("figure", "measure", "method", "label", "source", "env_steps", "mean", "low", "high",
                                     "seeds"))
    paths[3].write_text("\n".join(md))
    print_commands(list(chosen.values()))
    announce(*paths)
    return paths


def figure_main(argv: list[str] | None, figure: Figure, description: str) -> int:
    """``python experiments/paper/FIGURE.py [FOLDER ...] [--out DIR]``, reading
    ``experiments/results/FIGURE/*/`` when no folder is named."""
    defaults = [f"experiments/results/{figure.name}/*/"]
    parser = argparse.ArgumentParser(prog=f"python experiments/paper/{figure.name}.py", description=description)
    parser.add_argument("folders", nargs="*", help=f"run or sweep folders (default: {' '.join(defaults)})")
    parser.add_argument("--out", type=Path, default=RESULTS / f"paper-{figure.name}", help="output folder")
    args = parser.parse_args(argv)
    report(figure, read_all(find_folders(args.folders, defaults)), args.out)
    return 0


if __name__ == "__main__":
    sys.exit("run figure5.py or figure6.py")
