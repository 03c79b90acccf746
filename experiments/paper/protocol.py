"""The paper's evaluation protocol, defined once: how a run's metrics.csv becomes the numbers
of Table 1, Table 2 and the curves of Figures 5, 6, 7, 9 and 11.

A run folder's metrics.csv has one row per seed per log interval (about 25k agent steps); a
row's ``success_ratio`` is over the ``episodes`` that ended in that interval (NaN if none), so
a row holds ``successes = success_ratio * episodes`` (rounded: the ratio is written to 6
significant digits) and covers the agent steps from the previous row's ``env_steps`` (0 for
the first row) to its own. Every statistic below sums whole rows: episodes are not split.

- Final success ratio of a seed (Table 1, ``final_success``): successes / episodes over the
  fewest last rows that together cover at least ``WINDOW_STEPS`` = 100k agent steps (all rows
  if the run is shorter). With ~25k-step rows that is 5 rows (~123k steps), since 4 rows of
  24,640 steps cover 98,560.
- Steps to 0.9 of a seed (Table 2, ``steps_to_threshold``): the first row's ``env_steps`` at
  which the success ratio over the most recent >= ``WINDOW_EPISODES`` = 100 episodes (the
  fewest most recent whole rows whose episodes sum to >= 100) is >= ``THRESHOLD`` = 0.9;
  None ("not reached", reported as ``>`` the steps trained) if no row qualifies.
- Across seeds (``across_seeds``): the per-seed values, their mean and median, and a 95%
  percentile-bootstrap interval of the mean (final success) or of the median (steps to 0.9,
  where a seed that never reached 0.9 counts as +inf, so a mean is undefined): 10,000
  resamples of the seeds with replacement, ``numpy.random.default_rng(0)``, quantiles by the
  inverted empirical CDF (no interpolation, so +inf stays +inf). One seed: the interval is
  that seed's value.
- Curves (``success_curve``): at each row, each seed's success ratio over its most recent >=
  100 episodes (the quantity steps-to-0.9 thresholds; NaN before a seed has 100), the mean
  over seeds and a min-max band, against agent steps.
- Any per-episode column, not only the success ratio (Figures 5 and 6: the episode return,
  ``mean_extrinsic_return``, and success at 0.8): a row's mean over its episodes times its
  ``episodes`` is its sum (``episode_sums``), so the windows above hold for any column,
  weighted by episodes. ``windowed_mean`` and ``steps_to_threshold(..., column=)`` are the
  episode windows, ``level`` the step window (``final_success`` of any column, optionally of
  the rows up to a given step, e.g. the return at 1M), ``mean_curve`` the curves. On the
  success ratio each is exactly the function above.

``read_points(folder)`` reads a run folder (one point) or a sweep folder (``python -m
simjax.sweep``: metrics.csv has one leading column per swept config field before
``env_steps``, config.json has ``sweep`` {field: values} and ``grid`` [{field: value}, ...])
into points, each with its own config and its per-seed series. Only numpy is imported: no
JAX, nothing compiled.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from simjax.config_history import current_record

WINDOW_STEPS = 100_000  # final success: the last rows covering at least this many agent steps
WINDOW_EPISODES = 100  # steps to 0.9 and curves: the most recent rows holding at least this many episodes
THRESHOLD = 0.9
SUCCESS = "success_ratio"  # the column the statistics read unless told another
RESAMPLES = 10_000
BOOTSTRAP_SEED = 0
CONFIDENCE = 0.95


# -- one seed's rows ------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True, eq=False)
class Series:
    """One seed's metrics rows, in order of ``env_steps``; ``columns`` holds every column as floats."""

    env_steps: np.ndarray  # int64, increasing
    episodes: np.ndarray  # int64, episodes that ended in each row's interval
    successes: np.ndarray  # int64, round(success_ratio * episodes); 0 where no episode ended
    columns: dict[str, np.ndarray]

    @classmethod
    def from_columns(cls, columns: dict[str, list[float]]) -> Series:
        cols = {k: np.asarray(v, dtype=np.float64) for k, v in columns.items()}
        order = np.argsort(cols["env_steps"], kind="stable")
        cols = {k: v[order] for k, v in cols.items()}
        episodes = np.rint(cols["episodes"]).astype(np.int64)
        ratio = cols["success_ratio"]
        if np.any(~np.isfinite(ratio) & (episodes > 0)):
            raise ValueError("a row with episodes > 0 has no finite success_ratio")
        successes = np.rint(np.where(episodes > 0, np.nan_to_num(ratio) * episodes, 0.0)).astype(np.int64)
        return cls(np.rint(cols["env_steps"]).astype(np.int64), episodes, successes, cols)

    @property
    def last_step(self) -> int:
        return int(self.env_steps[-1]) if self.env_steps.size else 0


def window_start_by_steps(env_steps: np.ndarray, window_steps: int = WINDOW_STEPS) -> int:
    """Index of the first of the fewest last rows whose steps (from the row before them, or 0)
    to the last row cover >= ``window_steps``; 0 if all rows cover less."""
    last = env_steps[-1]
    for start in range(len(env_steps) - 1, -1, -1):
        begin = env_steps[start - 1] if start > 0 else 0
        if last - begin >= window_steps:
            return start
    return 0


def window_start_by_episodes(episodes: np.ndarray, end: int, min_episodes: int = WINDOW_EPISODES) -> int | None:
    """Index of the first of the fewest rows ending at row ``end`` (inclusive) whose episodes
    sum to >= ``min_episodes``; None if all rows up to ``end`` hold fewer."""
    total = 0
    for start in range(end, -1, -1):
        total += int(episodes[start])
        if total >= min_episodes:
            return start
    return None


@dataclasses.dataclass(frozen=True)
class Final:
    """A seed's final success ratio and the rows it is over (``ratio`` NaN if no episode ended)."""

    ratio: float
    successes: int
    episodes: int
    from_step: int  # the window covers agent steps (from_step, to_step]
    to_step: int


def episode_sums(series: Series, column: str = SUCCESS) -> np.ndarray:
    """Each row's sum of ``column`` over the episodes that ended in it: ``successes`` (whole
    episodes) for the success ratio, otherwise the row's mean over its episodes times
    ``episodes`` (0 where none ended)."""
    if column == SUCCESS:
        return series.successes
    values = series.columns[column]
    if np.any(~np.isfinite(values) & (series.episodes > 0)):
        raise ValueError(f"a row with episodes > 0 has no finite {column}")
    return np.where(series.episodes > 0, np.nan_to_num(values) * series.episodes, 0.0)


@dataclasses.dataclass(frozen=True)
class Level:
    """A seed's mean of a column over the episodes of a window of rows (``value`` NaN if no
    episode ended there); ``total`` is the column summed over those episodes."""

    value: float
    total: float
    episodes: int
    from_step: int  # the window covers agent steps (from_step, to_step]
    to_step: int


def level(series: Series, column: str = SUCCESS, window_steps: int = WINDOW_STEPS, until: int | None = None) -> Level:
    """``column``'s mean over the episodes that ended in the fewest last rows covering at least
    ``window_steps`` agent steps, of the rows that end at or before ``until`` (all rows if
    None; a window of no rows, NaN, if none does): ``final_success`` of any column, at any step
    (Figure 5's return at 1M)."""
    if until is not None:
        series = Series(*(a[series.env_steps <= until] for a in (series.env_steps, series.episodes, series.successes)),
                        {k: v[series.env_steps <= until] for k, v in series.columns.items()})
    if not series.env_steps.size:
        return Level(math.nan, 0.0, 0, 0, 0)
    start = window_start_by_steps(series.env_steps, window_steps)
    total, episodes = episode_sums(series, column)[start:].sum(), int(series.episodes[start:].sum())
    value = total / episodes if episodes else math.nan
    begin = int(series.env_steps[start - 1]) if start > 0 else 0
    return Level(value, float(total), episodes, begin, series.last_step)


def final_success(series: Series, window_steps: int = WINDOW_STEPS) -> Final:
    """Successes / episodes over the episodes that ended in the fewest last rows covering at
    least ``window_steps`` agent steps (Table 1)."""
    at = level(series, SUCCESS, window_steps)
    return Final(at.value, int(at.total), at.episodes, at.from_step, at.to_step)


def windowed_mean(series: Series, column: str = SUCCESS, min_episodes: int = WINDOW_EPISODES) -> np.ndarray:
    """At each row, ``column``'s mean over the most recent >= ``min_episodes`` episodes (the
    fewest whole rows ending there, each weighted by its episodes); NaN while fewer episodes
    have ended."""
    sums = episode_sums(series, column)
    out = np.full(series.env_steps.shape, np.nan)
    for end in range(len(out)):
        start = window_start_by_episodes(series.episodes, end, min_episodes)
        if start is not None:
            out[end] = sums[start:end + 1].sum() / series.episodes[start:end + 1].sum()
    return out


def windowed_success(series: Series, min_episodes: int = WINDOW_EPISODES) -> np.ndarray:
    """At each row, the success ratio over the most recent >= ``min_episodes`` episodes (the
    fewest whole rows ending there); NaN while fewer episodes have ended."""
    return windowed_mean(series, SUCCESS, min_episodes)


def steps_to_threshold(series: Series, threshold: float = THRESHOLD, min_episodes: int = WINDOW_EPISODES,
                       column: str = SUCCESS) -> int | None:
    """The first ``env_steps`` at which ``windowed_mean`` of ``column`` (the success ratio:
    Table 2; the return: Figure 5) >= ``threshold``; None if never."""
    reached = np.flatnonzero(windowed_mean(series, column, min_episodes) >= threshold)
    return int(series.env_steps[reached[0]]) if reached.size else None


# -- across seeds ---------------------------------------------------------------------------------


def bootstrap_interval(values, statistic: str = "mean", resamples: int = RESAMPLES, seed: int = BOOTSTRAP_SEED,
                       confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Percentile-bootstrap ``confidence`` interval of the mean or median of ``values`` over
    seeds: ``resamples`` resamples with replacement from ``numpy.random.default_rng(seed)``,
    quantiles by the inverted empirical CDF. One value, or all alike: (value, value)."""
    values = np.asarray(values, dtype=np.float64)
    if values.size == 0:
        return math.nan, math.nan
    if np.all(values == values[0]):  # one seed, or seeds alike: every resample is that value (exactly, not to rounding)
        return float(values[0]), float(values[0])
    reduce = {"mean": np.mean, "median": np.median}[statistic]
    idx = np.random.default_rng(seed).integers(0, values.size, size=(resamples, values.size))
    with np.errstate(invalid="ignore"):  # a median of +inf and +inf
        stats = reduce(values[idx], axis=1)
    tail = (1.0 - confidence) / 2
    low, high = np.quantile(stats, [tail, 1.0 - tail], method="inverted_cdf")
    return float(low), float(high)


@dataclasses.dataclass(frozen=True)
class SeedSummary:
    """Per-seed values (in seed order) and their summary; ``interval`` is of ``statistic``."""

    seeds: tuple[int, ...]
    values: tuple[float, ...]
    mean: float
    median: float
    interval: tuple[float, float]
    statistic: str


def across_seeds(values: dict[int, float], statistic: str = "mean") -> SeedSummary:
    """Mean, median and the bootstrap interval of ``statistic`` over the seeds whose value is
    not NaN (a seed with no episode in its window has none; +inf counts)."""
    seeds = tuple(sorted(values))
    kept = np.asarray([values[s] for s in seeds if not math.isnan(values[s])], dtype=np.float64)
    if kept.size == 0:
        return SeedSummary(seeds, tuple(values[s] for s in seeds), math.nan, math.nan, (math.nan, math.nan), statistic)
    with np.errstate(invalid="ignore"):
        mean, median = float(np.mean(kept)), float(np.median(kept))
    return SeedSummary(seeds, tuple(values[s] for s in seeds), mean, median, bootstrap_interval(kept, statistic), statistic)


@dataclasses.dataclass(frozen=True)
class StepsRatio:
    """``numerator``'s median steps to the threshold over ``denominator``'s (the paper's
    SIM : RND is 1.82 / 4.51). ``value`` is NaN when neither median is reached; ``bound`` is then
    "", and where only one is reached the ratio is beyond the steps the other trained:
    ``bound`` "<" (or ">") and ``value`` the ratio with the unreached median set to its steps
    trained. ``interval``: percentile bootstrap, each method's seeds resampled on their own; a
    resample where neither median is reached could be any ratio, so it counts as 0 at the low
    end and +inf at the high end."""

    value: float
    bound: str
    interval: tuple[float, float]


def steps_ratio(numerator: dict[int, float], denominator: dict[int, float], trained: tuple[int, int],
                resamples: int = RESAMPLES, seed: int = BOOTSTRAP_SEED, confidence: float = CONFIDENCE) -> StepsRatio:
    """Ratio of medians of steps to the threshold (+inf = not reached) of two methods' seeds;
    ``trained`` is each method's steps trained per seed (the fewest of its seeds)."""
    a = np.asarray([v for v in numerator.values() if not math.isnan(v)], dtype=np.float64)
    b = np.asarray([v for v in denominator.values() if not math.isnan(v)], dtype=np.float64)
    if a.size == 0 or b.size == 0:
        return StepsRatio(math.nan, "", (math.nan, math.nan))
    ma, mb = float(np.median(a)), float(np.median(b))
    if math.isinf(ma) and math.isinf(mb):
        value, bound = math.nan, ""
    elif math.isinf(mb):
        value, bound = ma / trained[1], "<"
    elif math.isinf(ma):
        value, bound = trained[0] / mb, ">"
    else:
        value, bound = ma / mb, ""
    rng = np.random.default_rng(seed)
    ra = np.median(a[rng.integers(0, a.size, size=(resamples, a.size))], axis=1)
    rb = np.median(b[rng.integers(0, b.size, size=(resamples, b.size))], axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = ra / rb  # inf / finite = inf, finite / inf = 0, inf / inf = NaN
    unknown = np.isnan(ratio)
    tail = (1.0 - confidence) / 2
    low = np.quantile(np.where(unknown, 0.0, ratio), tail, method="inverted_cdf")
    high = np.quantile(np.where(unknown, np.inf, ratio), 1.0 - tail, method="inverted_cdf")
    return StepsRatio(value, bound, (float(low), float(high)))


def fisher_exact(a: int, n: int, b: int, m: int) -> float:
    """Two-sided Fisher exact test p-value of a/n against b/m: the probability, with the margins
    fixed, of a table no more likely than the one seen."""
    k = a + b

    def log_p(x):  # hypergeometric: x of the k successes fall in the first sample
        comb = lambda p, q: math.lgamma(p + 1) - math.lgamma(q + 1) - math.lgamma(p - q + 1)
        return comb(n, x) + comb(m, k - x) - comb(n + m, k)

    seen = log_p(a)
    support = range(max(0, k - m), min(k, n) + 1)
    return min(1.0, sum(math.exp(log_p(x)) for x in support if log_p(x) <= seen + 1e-9))


# -- curves ---------------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class Curve:
    """Mean over seeds and a min-max band at each agent step every seed logged; ``seeds`` is
    how many seeds had a value (>= ``WINDOW_EPISODES`` episodes) there."""

    env_steps: np.ndarray
    mean: np.ndarray
    low: np.ndarray
    high: np.ndarray
    seeds: np.ndarray


def success_curve(seeds: dict[int, Series], min_episodes: int = WINDOW_EPISODES) -> Curve:
    """``windowed_success`` of each seed, at the agent steps all seeds logged."""
    return mean_curve(seeds, SUCCESS, min_episodes)


def mean_curve(seeds: dict[int, Series], column: str = SUCCESS, min_episodes: int = WINDOW_EPISODES) -> Curve:
    """``windowed_mean`` of ``column`` of each seed, at the agent steps all seeds logged: a
    running mean over each seed's most recent >= ``min_episodes`` episodes, then the mean and
    the min-max over seeds."""
    if not seeds:
        empty = np.zeros(0)
        return Curve(empty.astype(np.int64), empty, empty, empty, empty.astype(np.int64))
    common = None
    for s in seeds.values():
        common = set(s.env_steps.tolist()) if common is None else common & set(s.env_steps.tolist())
    steps = np.asarray(sorted(common), dtype=np.int64)
    table = np.full((len(seeds), steps.size), np.nan)
    for i, s in enumerate(seeds.values()):
        ratio = windowed_mean(s, column, min_episodes)
        at = {int(k): r for k, r in zip(s.env_steps, ratio)}
        table[i] = [at[int(k)] for k in steps]
    have = np.isfinite(table)
    counts = have.sum(axis=0)
    with np.errstate(invalid="ignore"):
        mean = np.where(counts > 0, np.nansum(table, axis=0) / np.maximum(counts, 1), np.nan)
        low = np.where(counts > 0, np.nanmin(np.where(have, table, np.inf), axis=0), np.nan)
        high = np.where(counts > 0, np.nanmax(np.where(have, table, -np.inf), axis=0), np.nan)
    return Curve(steps, mean, low, high, counts)


# -- run and sweep folders ------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True, eq=False)
class Point:
    """One configuration's seeds: a plain run folder, or one point of a sweep folder.
    ``setting`` is the swept fields' values ({} for a plain run), ``config`` the folder's
    config with them applied, ``record`` the whole config.json."""

    source: Path
    setting: dict
    config: dict
    seeds: dict[int, Series]
    record: dict

    @property
    def name(self) -> str:
        if not self.setting:
            return self.source.name
        return f"{self.source.name} [{', '.join(f'{k}={format_value(v)}' for k, v in self.setting.items())}]"

    @property
    def budget(self) -> int:
        """Agent steps per seed the run was asked for (``total_steps``)."""
        return int(self.config["total_steps"])

    @property
    def trained(self) -> int:
        """Agent steps per seed trained so far (the fewest any seed logged)."""
        return min((s.last_step for s in self.seeds.values()), default=0)


def parse_cell(text: str):
    """A swept column's cell as the value it writes: bool, int, float or str."""
    lowered = text.strip().lower()
    if lowered in ("true", "false"):
        return lowered == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def same_value(cell: str, value) -> bool:
    """Whether a swept column's ``cell`` (text) holds ``value`` (from config.json's grid)."""
    if isinstance(value, bool):
        return cell.strip().lower() in (("true", "1", "1.0") if value else ("false", "0", "0.0"))
    if isinstance(value, (int, float)):
        try:
            return math.isclose(float(cell), float(value), rel_tol=1e-9, abs_tol=0.0)
        except ValueError:
            return False
    return cell == str(value)


def read_points(folder: Path) -> list[Point]:
    """A run folder as one point, a sweep folder as one point per grid entry (in the grid's
    order; an entry with no rows yet has no seeds; rows that match no entry form points of
    their own, in order of appearance)."""
    folder = Path(folder)
    record = current_record(json.loads((folder / "config.json").read_text()))
    config = dict(record["config"])
    with open(folder / "metrics.csv", newline="") as f:
        rows = list(csv.reader(f))
    if not rows or "env_steps" not in rows[0]:
        raise ValueError(f"{folder}/metrics.csv has no env_steps column")
    header = rows[0]
    swept = header[:header.index("env_steps")]
    metric_names = header[len(swept):]
    grid = record.get("grid") or []
    if swept and not grid and record.get("sweep"):
        raise ValueError(f"{folder}/config.json has a sweep but no grid")
    keyed: dict[tuple, dict[int, dict[str, list[float]]]] = {}
    for row in rows[1:]:
        if len(row) != len(header) or "" in row:  # a row a running training is writing right now
            continue
        key = tuple(row[:len(swept)])
        values = row[len(swept):]
        seed = int(float(values[metric_names.index("seed")]))
        cols = keyed.setdefault(key, {}).setdefault(seed, {n: [] for n in metric_names})
        for n, v in zip(metric_names, values):
            cols[n].append(float(v))

    def point(setting: dict, by_seed: dict) -> Point:
        seeds = {seed: Series.from_columns(cols) for seed, cols in sorted(by_seed.items())}
        return Point(folder, setting, config | setting, seeds, record)

    if not swept:
        return [point({}, keyed.get((), {}))]
    points, used = [], set()
    for entry in grid:
        match = [k for k in keyed if all(same_value(cell, entry[name]) for name, cell in zip(swept, k))]
        used.update(match)
        by_seed: dict = {}
        for k in match:
            by_seed.update(keyed[k])
        points.append(point({name: entry[name] for name in swept}, by_seed))
    for k, by_seed in keyed.items():
        if k not in used:
            points.append(point({name: parse_cell(cell) for name, cell in zip(swept, k)}, by_seed))
    return points


# -- naming points by their config ----------------------------------------------------------------

# fields that only say how a run was run, not what was run
BOOKKEEPING = ("seed", "num_seeds", "total_steps", "log_every")
# the short names the labels use, in the order they are shown
SHORT = {"env": "env", "obs_len": "H", "act_len": "L", "sim_inverse": "inverse", "sim_combine": "h", "sim_sequence": "seq",
         "sim_target": "target", "bonus_scale": "beta"}
PAPER_ALGO = {"a2c": "LSTM-A3C", "icm": "ICM", "rnd": "RND", "sim": "SIM", "ec": "EC"}


def format_value(value) -> str:
    if isinstance(value, bool):
        return "on" if value else "off"
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


def relevant(field: str, algo: str) -> bool:
    """Whether ``field`` changes what ``algo`` does (SIM's settings mean nothing to RND)."""
    if field in BOOKKEEPING:
        return False
    if field.startswith("sim_") or field in ("obs_len", "act_len"):
        return algo == "sim"
    if field == "forward_weight":
        return algo in ("sim", "icm")
    if field.startswith("ec_"):
        return algo == "ec"
    if field.startswith("bonus_") or field in ("rl_weight", "obs_norm"):
        return algo != "a2c"
    return True


def paper_name(config: dict) -> str:
    """The paper's name for a config: LSTM-A3C, ICM, RND, SIM or a SIM ablation of section 3.5
    (SIM-no-Seq, SIM-no-RND, SIM-itr, SIM-concat)."""
    algo = config.get("algo", "?")
    name = PAPER_ALGO.get(algo, algo)
    if algo != "sim":
        return name
    if config.get("sim_sequence", "lstm") == "ff":
        name += "-no-Seq"
    if config.get("sim_target", "rnd") == "embed":
        name += "-no-RND"
    if config.get("sim_combine", "full") != "full":
        name += "-" + config["sim_combine"]
    return name


def differing_fields(configs: list[dict]) -> list[str]:
    """Config fields (not bookkeeping) whose values are not the same in all ``configs``."""
    fields = []
    for config in configs:
        fields += [k for k in config if k not in fields]
    return [k for k in fields if k not in BOOKKEEPING and len({json.dumps(c.get(k)) for c in configs}) > 1]


def label_points(points: list[Point], show: tuple[str, ...] = ()) -> list[str]:
    """A legend label per point: its paper name and, in brackets, the fields (relevant to its
    method) in which the points differ, and those in ``show``, e.g. ``SIM (L=1, inverse=off)``;
    points still alike get their folder's name."""
    configs = [p.config for p in points]
    diff = [k for k in differing_fields(configs) if k != "algo"]
    diff += [k for k in dict.fromkeys(show) if k not in diff and k != "algo"]
    diff.sort(key=lambda k: (list(SHORT).index(k) if k in SHORT else len(SHORT), k))
    labels = []
    for config in configs:
        parts = [f"{SHORT.get(k, k)}={format_value(config.get(k))}" for k in diff if relevant(k, config.get("algo", ""))]
        labels.append(paper_name(config) + (f" ({', '.join(parts)})" if parts else ""))
    alike = [labels.count(label) > 1 for label in labels]
    return [f"{label} [{p.name}]" if same else label for label, p, same in zip(labels, points, alike)]
