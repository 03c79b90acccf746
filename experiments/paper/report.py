"""What the paper's table and figure commands share: finding their inputs, the commands that
made those inputs, the provenance (commit, date, budget), the per-point summary of
``protocol``'s statistics, markdown, CSV and the curve figure.

A figure is a list of panels, a panel a list of variants: the config values a run must have
to be a curve of that panel (``Variant.want`` over the panel's ``controls``). Inputs that
match no variant are listed as unused, variants no input matches as missing, with a command
that would make them.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import datetime as dt
import glob
import math
import subprocess
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from protocol import (  # noqa: E402
    BOOKKEEPING,
    THRESHOLD,
    WINDOW_EPISODES,
    WINDOW_STEPS,
    Point,
    across_seeds,
    final_success,
    format_value,
    label_points,
    read_points,
    relevant,
    steps_to_threshold,
    success_curve,
)

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "experiments" / "results"

DEFINITIONS = {
    "final": f"Final success: successes / episodes over the episodes that ended in the fewest last log rows covering >= "
             f"{WINDOW_STEPS:,} agent steps, per seed.",
    "steps": f"Steps to {THRESHOLD}: the first agent step at which the success ratio over the most recent >= "
             f"{WINDOW_EPISODES} episodes (whole rows) is >= {THRESHOLD}; `>N` = not reached in the N steps trained.",
    "seeds": "Across seeds: mean and median; [95%] = percentile bootstrap over seeds (10,000 resamples, numpy seed 0) of "
             "the mean for success, of the median for steps (a seed that did not reach counts as +inf).",
    "curves": f"Curves: mean over seeds of each seed's success over its most recent >= {WINDOW_EPISODES} episodes, "
              "band = min-max over seeds.",
}


# -- inputs -----------------------------------------------------------------------------------------


def rel(path: Path) -> str:
    """``path`` relative to the repository root where it lies inside it."""
    path = Path(path).resolve()
    try:
        return str(path.relative_to(ROOT))
    except ValueError:
        return str(path)


def find_folders(args: list[str], defaults: list[str]) -> list[Path]:
    """The folders named on the command line, or those the default globs (relative to the
    repository root) find; only folders holding config.json and metrics.csv."""
    if args:
        folders = [Path(a) for a in args]
    else:
        folders = sorted({Path(p) for pattern in defaults for p in glob.glob(str(ROOT / pattern))})
    kept = []
    for f in folders:
        if (f / "config.json").exists() and (f / "metrics.csv").exists():
            kept.append(f)
        else:
            print(f"skipped {rel(f)}: no config.json and metrics.csv", file=sys.stderr)
    return kept


def read_all(folders: list[Path]) -> list[Point]:
    return [p for f in folders for p in read_points(f)]


# -- provenance -------------------------------------------------------------------------------------


def git(*args: str) -> str | None:
    try:
        out = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() if out.returncode == 0 else None


def commit() -> str:
    """``git rev-parse --short HEAD``, and whether the code these numbers come from differs from it."""
    head = git("rev-parse", "--short", "HEAD") or "unknown"
    dirty = git("status", "--porcelain", "--", "simjax", "experiments/paper")
    return f"{head} (with uncommitted changes to simjax/ or experiments/paper/)" if dirty else head


def committed_in(path: Path) -> str:
    """The last commit (and its date) that changed ``path``, or that it is not committed."""
    line = git("log", "-1", "--format=%h %ad", "--date=short", "--", rel(path))
    if not line:
        return "not committed"
    changed = git("status", "--porcelain", "--", rel(path))
    return f"committed in {line.split()[0]} ({line.split()[1]})" + (", changed since" if changed else "")


def today() -> str:
    return dt.date.today().isoformat()


def this_command() -> str:
    """The command line that is running, as it could be typed at the repository root."""
    return " ".join(["python", rel(Path(sys.argv[0]))] + sys.argv[1:])


def flag_text(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def _defaults(config: dict) -> dict | None:
    """TrainConfig's defaults for ``config``'s task, method and learner (some depend on them: beta
    on the method, EC's bonus offset on the task, the learning rate, clip and return rules on the
    learner); imported only here: it imports JAX, compiles nothing."""
    try:
        from simjax.agents.config import TrainConfig

        return dataclasses.asdict(TrainConfig(env=config.get("env", "maze-very-sparse"), algo=config.get("algo", "a2c"),
                                              learner=config.get("learner", "a2c")))
    except Exception:  # the learner mid-edit, or a task unknown here: every field is then spelled out
        return None


def config_flags(config: dict, skip: tuple[str, ...] = ()) -> list[str]:
    """``--env E --algo A --total-steps T --num-seeds N`` and every other field of ``config``
    that differs from today's default for its task and method (all of them if the defaults cannot
    be read); EC's settings only for EC."""
    defaults = _defaults(config)
    from simjax.config_history import TRAINED_BEFORE_THE_FLAG

    # what a config.json without a setting trained with
    config = config | {k: v for k, v in TRAINED_BEFORE_THE_FLAG.items() if k not in config}
    first = ("env", "algo", "total_steps", "num_seeds")
    out = []
    for name in list(first) + [k for k in config if k not in first]:
        if name in skip or name not in config or (name.startswith("ec_") and config.get("algo") != "ec"):
            continue  # EC's settings mean nothing to the other methods
        if name not in first and defaults is not None and name in defaults and _equal(config[name], defaults[name]):
            continue
        out += ["--" + name.replace("_", "-"), flag_text(config[name])]
    return out


def _equal(a, b) -> bool:
    if isinstance(a, float) or isinstance(b, float):
        return a is not None and b is not None and math.isclose(float(a), float(b), rel_tol=1e-12)
    return a == b


def input_commands(folder: Path) -> list[str]:
    """The command(s) that made a run or sweep folder, from its config.json (and fork.json)."""
    import json

    from simjax.config_history import current_record

    record = current_record(json.loads((folder / "config.json").read_text()))
    config = record["config"]
    sweep = record.get("sweep") or {}
    if sweep:
        swept = [f"--{k.replace('_', '-')} {','.join(flag_text(v) for v in values)}" for k, values in sweep.items()]
        flags = config_flags(config, skip=tuple(sweep))
        return [" ".join(["python -m simjax.sweep", *flags, *swept, "--out", rel(folder)])]
    fork = folder / "fork.json"
    if fork.exists():
        made = json.loads(fork.read_text())
        source = ROOT / made["from"]
        changes = [f"--{k.replace('_', '-')} {flag_text(new)}" for k, (_, new) in made["changed"].items()]
        lines = input_commands(source) if (source / "config.json").exists() else [f"(source {made['from']} not here)"]
        return lines + [" ".join(["python -m simjax.fork", made["from"], rel(folder), *changes]),
                        f"python -m simjax.train --resume {rel(folder)}  # forked at {made['env_steps']:,} steps"]
    return [" ".join(["python -m simjax.train", *config_flags(config), "--out", rel(folder)])]


def inputs_markdown(points: list[Point]) -> list[str]:
    """One list item per input folder: its command(s), seeds, budget, steps trained, git state."""
    lines, seen = [], []
    for p in points:
        if p.source in seen:
            continue
        seen.append(p.source)
        here = [q for q in points if q.source == p.source]
        trained = min(q.trained for q in here)
        state = "" if trained >= p.budget else ", in progress or stopped"
        seeds = sorted({s for q in here for s in q.seeds})
        lines.append(f"- `{rel(p.source)}`: {len(seeds)} seeds, budget {p.budget:,} agent steps per seed, "
                     f"trained {trained:,}{state}; metrics.csv {committed_in(p.source / 'metrics.csv')}:")
        lines += [f"  `{c}`" for c in input_commands(p.source)]
    return lines or ["- none yet"]


def header_markdown(title: str, points: list[Point], definitions: tuple[str, ...] = tuple(DEFINITIONS)) -> list[str]:
    """Title, the command, date, commit and budget, and the definitions of the numbers below."""
    budgets = sorted({p.budget for p in points})
    budget = ", ".join(f"{b:,}" for b in budgets) if budgets else "none yet"
    return [f"# {title}", "",
            f"Made by `{this_command()}` on {today()}, commit {commit()}; budget {budget} agent steps per seed.", "",
            " ".join(DEFINITIONS[d] for d in definitions) + " Definitions: `experiments/paper/protocol.py`.", ""]


def print_commands(points: list[Point]) -> None:
    print(f"commit {commit()}, {today()}")
    for line in inputs_markdown(points):
        print(line.strip().strip("`") if line.startswith("  ") else line)


# -- one point's numbers ----------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Summary:
    point: Point
    finals: dict  # seed -> protocol.Final
    final: object  # protocol.SeedSummary of the final success ratios (interval of the mean)
    steps: dict  # seed -> first step at >= THRESHOLD, or None
    steps_summary: object  # protocol.SeedSummary with +inf for not reached (interval of the median)

    @property
    def reached(self) -> int:
        return sum(v is not None for v in self.steps.values())


def summarize(point: Point) -> Summary:
    finals = {s: final_success(series) for s, series in point.seeds.items()}
    steps = {s: steps_to_threshold(series) for s, series in point.seeds.items()}
    return Summary(point, finals, across_seeds({s: f.ratio for s, f in finals.items()}, "mean"), steps,
                   across_seeds({s: math.inf if v is None else float(v) for s, v in steps.items()}, "median"))


def fmt_ratio(x: float) -> str:
    return "–" if x is None or math.isnan(x) else f"{x:.3f}"


def fmt_steps(x: float | None, trained: int | None = None) -> str:
    """Agent steps as 1.23M or 450k; not reached as >(steps trained)."""
    if x is None or math.isinf(x):
        return ">" + (fmt_steps(trained) if trained is not None else "budget")
    if math.isnan(x):
        return "–"
    return f"{x / 1e6:.2f}M" if x >= 1e6 else f"{x / 1e3:.0f}k"


def final_cells(s: Summary) -> list[str]:
    per_seed = " / ".join(f"{fmt_ratio(f.ratio)} ({f.episodes})" for f in s.finals.values())
    lo, hi = s.final.interval
    return [per_seed, f"{fmt_ratio(s.final.mean)} [{fmt_ratio(lo)}, {fmt_ratio(hi)}]", fmt_ratio(s.final.median)]


def steps_cells(s: Summary) -> list[str]:
    trained = {seed: series.last_step for seed, series in s.point.seeds.items()}
    per_seed = " / ".join(fmt_steps(v, trained[seed]) for seed, v in s.steps.items())
    lo, hi = s.steps_summary.interval
    least = s.point.trained
    return [per_seed, f"{fmt_steps(s.steps_summary.median, least)} [{fmt_steps(lo, least)}, {fmt_steps(hi, least)}]",
            f"{s.reached}/{len(s.steps)}"]


def summary_csv_row(s: Summary) -> dict:
    lo, hi = s.final.interval
    slo, shi = s.steps_summary.interval
    return {
        "source": rel(s.point.source), "setting": ";".join(f"{k}={v}" for k, v in s.point.setting.items()),
        "env": s.point.config.get("env"), "algo": s.point.config.get("algo"), "seeds": ";".join(map(str, s.point.seeds)),
        "budget": s.point.budget, "trained": s.point.trained,
        "final_success_per_seed": ";".join(f"{f.ratio:.6g}" for f in s.finals.values()),
        "final_episodes_per_seed": ";".join(str(f.episodes) for f in s.finals.values()),
        "final_window_steps_per_seed": ";".join(f"{f.to_step - f.from_step}" for f in s.finals.values()),
        "final_success_mean": f"{s.final.mean:.6g}", "final_success_median": f"{s.final.median:.6g}",
        "final_success_mean_ci_low": f"{lo:.6g}", "final_success_mean_ci_high": f"{hi:.6g}",
        "steps_to_threshold_per_seed": ";".join("" if v is None else str(v) for v in s.steps.values()),
        "reached": s.reached, "steps_to_threshold_median": f"{s.steps_summary.median:.6g}",
        "steps_median_ci_low": f"{slo:.6g}", "steps_median_ci_high": f"{shi:.6g}",
    }


# -- writing ----------------------------------------------------------------------------------------


def markdown_table(header: list[str], rows: list[list[str]], numeric: tuple[int, ...] = ()) -> list[str]:
    align = ["---:" if i in numeric else "---" for i in range(len(header))]
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(align) + "|"]
    return lines + ["| " + " | ".join(r) + " |" for r in rows]


def write_csv(path: Path, rows: list[dict], empty: tuple[str, ...] = ("source", "setting", "env_steps")) -> None:
    """``rows`` under the union of their keys (the fullest row's order first); with no rows,
    just the header ``empty``."""
    fields: list[str] = [] if rows else list(empty)
    for r in sorted(rows, key=len, reverse=True):  # the fullest row's order first
        fields += [k for k in r if k not in fields]
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=fields)
        writer.writeheader()
        writer.writerows(rows)


def announce(*paths: Path) -> None:
    for p in paths:
        print(f"wrote {rel(p)}")


def style_success_axis(ax, title: str) -> None:
    ax.set(xlabel="agent steps", ylabel=f"success ratio (last >= {WINDOW_EPISODES} episodes)", ylim=(-0.02, 1.02))
    ax.axhline(THRESHOLD, color="grey", linewidth=0.8, linestyle=":")
    ax.set_xlim(left=0)
    ax.set_title(title, fontsize=9)


def draw_curve(ax, point: Point, label: str, color=None) -> None:
    curve = success_curve(point.seeds)
    line, = ax.plot(curve.env_steps, curve.mean, label=f"{label} ({len(point.seeds)} seeds)", color=color, linewidth=1.3)
    ax.fill_between(curve.env_steps, curve.low, curve.high, color=line.get_color(), alpha=0.2, linewidth=0)


def curve_csv_rows(point: Point, **keys) -> list[dict]:
    curve = success_curve(point.seeds)
    return [keys | {"source": rel(point.source), "setting": ";".join(f"{k}={v}" for k, v in point.setting.items()),
                    "env_steps": int(x), "mean": f"{m:.6g}", "low": f"{lo:.6g}", "high": f"{hi:.6g}", "seeds": int(n)}
            for x, m, lo, hi, n in zip(curve.env_steps, curve.mean, curve.low, curve.high, curve.seeds)]


# -- figures: panels of variants --------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Variant:
    """A curve of a panel: ``name`` is the paper's, ``want`` the config values it needs."""

    name: str
    want: dict


@dataclasses.dataclass(frozen=True)
class Panel:
    key: str
    title: str
    controls: dict  # config values every variant has unless its ``want`` says otherwise
    variants: tuple[Variant, ...]
    paper: str  # what the paper reports for this panel, in words
    make: str = ""  # a command that makes this panel's missing inputs (default: one train command per variant)


def matches(config: dict, want: dict) -> bool:
    """Whether ``config`` has every value in ``want`` that matters to its method (a field that
    a config predates counts as its default, which ``want`` is assumed to name)."""
    algo = want.get("algo", config.get("algo"))
    for k, v in want.items():
        if k != "algo" and not relevant(k, algo):
            continue
        if k not in config:
            continue
        if isinstance(v, float) and config[k] is not None:
            if not math.isclose(float(config[k]), v, rel_tol=1e-9):
                return False
        elif config[k] != v:
            return False
    return True


def suggest_command(spec: dict, slug: str, figure: str) -> str:
    """A train command for a variant no input has: its settings that matter to its method and
    differ from today's defaults; STEPS and SEEDS are left to the reader."""
    algo = spec.get("algo", "a2c")
    settings = {k: v for k, v in spec.items() if k not in BOOKKEEPING and (k in ("env", "algo") or relevant(k, algo))}
    flags = config_flags(settings, skip=("total_steps", "num_seeds"))
    return " ".join(["python -m simjax.train", *flags, "--total-steps STEPS --num-seeds SEEDS",
                     f"--out experiments/results/{figure}/{slug}"])


def slug(variant: Variant) -> str:
    return "".join(c if c.isalnum() else "-" for c in variant.name.lower()).strip("-").replace("--", "-")


def figure_report(name: str, title: str, panels: list[Panel], points: list[Point], out: Path, figure: str) -> list[Path]:
    """Curves (PNG), per-curve numbers (CSV, markdown) and the inputs' commands for ``panels``."""
    out.mkdir(parents=True, exist_ok=True)
    points = [p for p in points if p.seeds]
    used: set[int] = set()
    summary_rows, curve_rows = [], []
    md = header_markdown(title, points)
    ncols = 2 if len(panels) > 2 else len(panels)
    nrows = -(-len(panels) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(6.4 * ncols, 4.0 * nrows), squeeze=False)
    for ax in axes.flat[len(panels):]:
        ax.set_visible(False)
    for ax, panel in zip(axes.flat, panels):
        chosen, missing = [], []
        for variant in panel.variants:
            spec = panel.controls | variant.want
            hits = [p for p in points if matches(p.config, spec)]
            chosen += [(variant, p) for p in hits]
            if not hits:
                missing.append((variant, spec))
        used.update(id(p) for _, p in chosen)
        labels = label_points([p for _, p in chosen], tuple(k for v in panel.variants for k in v.want))
        md += [f"## ({panel.key}) {panel.title}", "", f"Paper: {panel.paper}", ""]
        rows = []
        for (variant, p), label in zip(chosen, labels):
            s = summarize(p)
            rows.append([label, variant.name, f"`{p.name}`", str(len(p.seeds)), f"{p.trained:,} / {p.budget:,}",
                         *final_cells(s), *steps_cells(s)])
            summary_rows.append({"panel": panel.key, "variant": variant.name, "label": label} | summary_csv_row(s))
            curve_rows += curve_csv_rows(p, panel=panel.key, variant=variant.name, label=label)
            draw_curve(ax, p, label)
        if rows:
            md += markdown_table(["curve", "paper's name", "input", "seeds", "trained / budget", "final success per seed (episodes)",
                                  "final success mean [95%]", "median", f"steps to {THRESHOLD} per seed", "median [95%]",
                                  "reached"], rows, numeric=(3,))
            md.append("")
        if missing and panel.make:  # one command (a sweep) makes them all
            names = ", ".join(v.name for v, _ in missing)
            md += [f"- missing: {names}; to make them: `{panel.make}`", ""]
            print(f"({panel.key}) missing {names}: {panel.make}")
        elif missing:
            for variant, spec in missing:
                command = suggest_command(spec, slug(variant), figure)
                wanted = ", ".join(f"{k}={format_value(v)}" for k, v in variant.want.items())
                md.append(f"- missing: {variant.name} (no input with {wanted}); to make it: `{command}`")
                print(f"({panel.key}) missing {variant.name}: {command}")
            md.append("")
        style_success_axis(ax, f"({panel.key}) {panel.title}")
        if chosen:
            ax.legend(fontsize=7)
        else:
            ax.text(0.5, 0.5, "no runs yet", ha="center", va="center", transform=ax.transAxes, color="grey")
    unused = [p for p in points if id(p) not in used]
    if unused:
        md += ["Inputs in no panel (their config matches no curve): " + ", ".join(f"`{p.name}`" for p in unused), ""]
    md += [f"![{name}]({name}.png)", "", "Inputs, and the commands that made them:", "", *inputs_markdown(points), ""]
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    paths = [out / f"{name}.png", out / f"{name}.csv", out / f"{name}-curves.csv", out / f"{name}.md"]
    fig.savefig(paths[0], dpi=100)
    plt.close(fig)
    write_csv(paths[1], summary_rows, ("panel", "variant", "label", "source", "setting", "seeds", "budget", "trained"))
    write_csv(paths[2], curve_rows, ("panel", "variant", "label", "source", "setting", "env_steps", "mean", "low", "high",
                                     "seeds"))
    paths[3].write_text("\n".join(md))
    print_commands(points)
    announce(*paths)
    return paths


def figure_main(argv: list[str] | None, figure: str, title: str, panels: list[Panel], default_inputs: list[str],
                description: str) -> int:
    """The command line every figure script has: ``python experiments/paper/FIGURE.py [FOLDER ...]
    [--out DIR]``, reading the default inputs when no folder is named."""
    parser = argparse.ArgumentParser(prog=f"python experiments/paper/{figure}.py", description=description)
    parser.add_argument("folders", nargs="*", help=f"run or sweep folders (default: {' '.join(default_inputs)})")
    parser.add_argument("--out", type=Path, default=RESULTS / f"paper-{figure}", help="output folder")
    parser.add_argument("--very-sparse-as", default=VERY_SPARSE, metavar="TASK",
                        help=f"the task whose runs the panels on the paper's very sparse setting draw (default "
                             f"{VERY_SPARSE}; maze-spot10-east for the runs made from spot 10 facing east, which "
                             f"were called maze-very-sparse before 2026-12-04)")
    args = parser.parse_args(argv)
    if args.very_sparse_as != VERY_SPARSE:
        panels = [retarget(p, args.very_sparse_as) for p in panels]
        title = title.replace(VERY_SPARSE, args.very_sparse_as)
    figure_report(figure, title, panels, read_all(find_folders(args.folders, default_inputs)), args.out, figure)
    return 0


VERY_SPARSE = "maze-very-sparse"


def retarget(panel: Panel, task: str) -> Panel:
    """``panel`` drawing ``task``'s runs where it draws the paper's very sparse setting's."""
    if panel.controls.get("env") != VERY_SPARSE:
        return panel
    return dataclasses.replace(panel, controls=panel.controls | {"env": task}, title=panel.title.replace(VERY_SPARSE, task),
                               make=panel.make.replace(f"--env {VERY_SPARSE}", f"--env {task}")
                               .replace(f"figure9-{VERY_SPARSE}", f"figure9-{task}"))

