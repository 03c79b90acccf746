"""The paper's Figure 5: Explore Goal Locations (DeepMind Lab; our ``explore-goals``), SIM
against ICM, RND and LSTM-A3C, with a verdict on each of the paper's claims.

    python experiments/paper/figure5.py [RUN_FOLDER ...] [--out experiments/results/paper-figure5]

The paper (section 4, 5 runs a method, 2M steps, EC exempted): "the method without intrinsic
novelty model could only converge to an inferior performance around 10. Our proposed method
could score > 20 with less than 1M training steps, whereas 'ICM' and 'RND' take almost 2M
steps". Its measure is the episode reward (``mean_extrinsic_return``; each goal +10, so 20 = two
goals an episode). Ours: 3 seeds x 2M agent steps a method. Per seed: the reward at 1M (over the
episodes of the fewest last rows covering >= 100k steps of the rows that end by 1M), the steps
to reward 20 (the first log row at which the reward over the most recent >= 100 episodes,
weighted by episodes, is >= 20), their summaries over seeds, SIM's median steps over each
method's, and the final reward (last >= 100k steps). LSTM-A3C is ``--algo a2c``. Drawn as
running means (``dmlab.py``) beside the random policy's level (dashed).

Default inputs: ``experiments/results/figure5/*/`` (``explore-goals-sim``, ``-rnd``, ``-icm``,
``-a2c``). Writes figure5.{png,csv,md} and figure5-curves.csv.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from dmlab import (  # noqa: E402
    FAILS,
    HOLDS,
    NO_RUN,
    RETURN,
    UNKNOWN,
    Figure,
    Measure,
    Method,
    Result,
    figure_main,
    level_text,
    overall,
    within,
)
from report import fmt_steps  # noqa: E402

GOAL = 10.0  # the reward of a goal
# The uniform random policy on today's explore-goals (DeepMind Lab's motion), 1,024 episodes,
# measured on 2026-12-07 by `python experiments/random_level.py --tasks
# explore-goals,explore-goals-doom-motion --envs 512 --episodes 2` (docs/results.md, Figure 5's
# row): 0.491 [0.442, 0.541] goals an episode (mean +- 1.96 standard errors), times GOAL.
RANDOM_RETURN = (0.491 * GOAL, 0.442 * GOAL, 0.541 * GOAL)
THRESHOLD = 20.0  # "could score > 20"
BY = 1_000_000  # "with less than 1M training steps"
BASELINES_BY = 2_000_000  # ICM and RND "take almost 2M steps"
AROUND = (10.0, 2.5)  # "an inferior performance around 10": read as within a quarter of a goal of 10 (ours)

REWARD = Measure(RETURN, "episode reward", THRESHOLD, RANDOM_RETURN, 2)
PAPER = ("As a result, the method without intrinsic novelty model could only converge to an inferior performance around "
         "10. Our proposed method could score > 20 with less than 1M training steps, whereas 'ICM' and 'RND' take almost "
         "2M steps.")


def takes_about(result: Result | None) -> str:
    """Reached the threshold after SIM's 1M and by the 2M budget (median over seeds)."""
    if result is None:
        return NO_RUN
    median = result.steps_summary.median
    if median <= BY:
        return FAILS  # as fast as the paper says SIM is
    if median <= BASELINES_BY:
        return HOLDS
    return UNKNOWN if math.isinf(median) and result.trained < BASELINES_BY else FAILS


def verdicts(figure: Figure, results: dict) -> list[tuple[str, str, str]]:
    sim, a2c = results.get("sim"), results.get("a2c")
    out = []
    claim = f"SIM scores above {THRESHOLD:g} reward within {BY / 1e6:g}M steps (median steps to {THRESHOLD:g})"
    if sim is None:
        out.append((claim, "no SIM run", NO_RUN))
    else:
        out.append((claim, f"SIM's steps to {THRESHOLD:g} per seed {sim.steps_per_seed()}, median {sim.steps_median()}; "
                           f"reward at {fmt_steps(BY)} {level_text(figure.measure, sim.at_summary, sim.at)}"
                           f"{sim.in_progress()}", within(sim, BY)))
    parts, outcomes = [], []
    for algo, name in (("icm", "ICM"), ("rnd", "RND")):
        r = results.get(algo)
        outcomes.append(takes_about(r))
        parts.append(f"{name}: no run" if r is None else
                     f"{name}: median {r.steps_median()} ({r.reached}/{len(r.steps)} seeds){r.in_progress()} ({outcomes[-1]})")
    out.append((f"ICM and RND take about {BASELINES_BY / 1e6:g}M steps (median steps to {THRESHOLD:g} after "
                f"{BY / 1e6:g}M and by {BASELINES_BY / 1e6:g}M)", "; ".join(parts), overall(outcomes)))
    center, half = AROUND
    claim = (f"the agent without a bonus (LSTM-A3C) stays around {center:g} (final mean within {center - half:g}-"
             f"{center + half:g}, a quarter of a goal)")
    if a2c is None:
        out.append((claim, "no LSTM-A3C run", NO_RUN))
    else:
        mean = a2c.final_summary.mean
        verdict = UNKNOWN if math.isnan(mean) or a2c.in_progress() else HOLDS if abs(mean - center) <= half else FAILS
        out.append((claim, f"LSTM-A3C's final reward {level_text(figure.measure, a2c.final_summary, a2c.final)}"
                           f"{a2c.in_progress()}", verdict))
    return out


FIGURE = Figure(
    name="figure5", title="Figure 5: Explore Goal Locations (explore-goals), SIM against ICM, RND and LSTM-A3C",
    env="explore-goals", methods=tuple(Method(a, 2_000_000) for a in ("sim", "rnd", "icm", "a2c")),
    measure=REWARD, panels=(REWARD,), claim_step=BY, at=BY, paper=PAPER,
    random_note=(f"The uniform random policy (dashed): {RANDOM_RETURN[0] / GOAL:.3f} [{RANDOM_RETURN[1] / GOAL:.3f}, "
                 f"{RANDOM_RETURN[2] / GOAL:.3f}] goals an episode, episode reward {RANDOM_RETURN[0]:.2f} "
                 f"[{RANDOM_RETURN[1]:.2f}, {RANDOM_RETURN[2]:.2f}] (1,024 episodes, 2026-12-07, `python "
                 "experiments/random_level.py --tasks explore-goals,explore-goals-doom-motion --envs 512 --episodes 2`)."),
    verdicts=verdicts,
    notes=("LSTM-A3C is our `--algo a2c`; the paper runs each method 5 times, we run 3 seeds; like the paper we run no "
           "EC here. Steps are agent steps, each holding its action for 4 engine frames (the paper's \"4-repeated "
           f"steps\"). Each goal is +{GOAL:g}, so reward {THRESHOLD:g} is {THRESHOLD / GOAL:g} goals an episode.",))


def main(argv: list[str] | None = None) -> int:
    return figure_main(argv, FIGURE, __doc__.split("\n")[0])


if __name__ == "__main__":
    sys.exit(main())
