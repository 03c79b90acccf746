"""The paper's Figure 6: Stairway to Melon (DeepMind Lab; our ``melon``), SIM against
LSTM-A3C, ICM, RND and EC, with a verdict on each of the paper's claims.

    python experiments/paper/figure6.py [RUN_FOLDER ...] [--out experiments/results/paper-figure6]

The paper (section 4, 5 runs a method): SIM surpasses "the standard of >80% with less than 0.2M
environment interactions, which is at least 3x as fast as the compared baselines"; LSTM-A3C
"could only converge to an inferior navigation success ratio of <50%". Ours: 3 seeds x 1M agent
steps a method (EC 1.6M, its 0.6M pretraining steps counted). Per seed: the steps to 0.8
success (the first log row at which the success over the most recent >= 100 episodes is >=
0.8, as Table 2's steps to 0.9), the median over seeds with its bootstrap interval, SIM's median
over each method's (a method that never reached counts as its steps trained, so the ratio is a
bound), and the final success (last >= 100k steps). LSTM-A3C is ``--algo a2c``. The paper draws
the cumulative episode reward (left) and the success ratio (right); so do we, as running means
(``dmlab.py``), beside the random policy's level (dashed); the verdicts read the success ratio.

Default inputs: ``experiments/results/figure6/*/`` (``melon-sim``, ``melon-rnd``, ``melon-icm``,
``melon-a2c``, ``melon-ec``). Writes figure6.{png,csv,md} and figure6-curves.csv.
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
    figure_main,
    level_text,
    speed_verdict,
    within,
)
from protocol import SUCCESS  # noqa: E402

# The uniform random policy on today's melon (DeepMind Lab's motion), 2,048 episodes, measured on
# 2026-12-07 by `python experiments/random_level.py --tasks melon,melon-doom-motion --envs 1024
# --episodes 2` (docs/results.md, Figure 6's row): level, 95% interval.
RANDOM_SUCCESS = (0.111, 0.098, 0.126)  # Wilson interval
RANDOM_RETURN = (6.60, 6.31, 6.89)  # mean +- 1.96 standard errors
THRESHOLD = 0.8  # the paper's "standard of >80%"
BY = 200_000  # "with less than 0.2M environment interactions"
FACTOR = 3.0  # "at least 3x as fast as the compared baselines"
BELOW = 0.5  # LSTM-A3C "<50%"

SUCCESS_MEASURE = Measure(SUCCESS, "success ratio", THRESHOLD, RANDOM_SUCCESS, 3)
RETURN_MEASURE = Measure(RETURN, "episode reward", None, RANDOM_RETURN, 2)
PAPER = ("Our proposed method could fast grasp the navigation behavior under the reward distraction scenario, i.e., "
         "surpassing the standard of >80% with less than 0.2M environment interactions, which is at least 3x as fast as "
         "the compared baselines. The vanilla 'LSTM-A3C' could only converge to an inferior navigation success ratio of "
         "<50%.")


def verdicts(figure: Figure, results: dict) -> list[tuple[str, str, str]]:
    sim, a2c = results.get("sim"), results.get("a2c")
    out = []
    claim = f"SIM passes {THRESHOLD:.0%} success within {BY / 1e6:g}M steps (median over seeds)"
    if sim is None:
        out.append((claim, "no SIM run", NO_RUN))
    else:
        by = sum(v is not None and v <= BY for v in sim.steps.values())
        out.append((claim, f"SIM's steps to {THRESHOLD} per seed {sim.steps_per_seed()}, median {sim.steps_median()}; "
                           f"{by} of {len(sim.steps)} seeds by {BY / 1e6:g}M{sim.in_progress()}", within(sim, BY)))
    ours, verdict = speed_verdict(figure, results, FACTOR)
    out.append((f"at least {FACTOR:g}x as fast as the compared baselines (SIM : method <= 1/{FACTOR:g} in median steps "
                f"to {THRESHOLD})", ours, verdict))
    claim = f"LSTM-A3C converges below {BELOW:.0%} success (final mean)"
    if a2c is None:
        out.append((claim, "no LSTM-A3C run", NO_RUN))
    else:
        mean = a2c.final_summary.mean
        verdict = UNKNOWN if math.isnan(mean) or a2c.in_progress() else HOLDS if mean < BELOW else FAILS
        out.append((claim, f"LSTM-A3C's final success {level_text(figure.measure, a2c.final_summary, a2c.final)}"
                           f"{a2c.in_progress()}", verdict))
    return out


FIGURE = Figure(
    name="figure6", title="Figure 6: Stairway to Melon (melon), SIM against LSTM-A3C, ICM, RND and EC", env="melon",
    methods=(Method("sim", 1_000_000), Method("rnd", 1_000_000), Method("icm", 1_000_000), Method("a2c", 1_000_000),
             Method("ec", 1_600_000, "--ec-pretrain-epochs 3")),
    measure=SUCCESS_MEASURE, panels=(RETURN_MEASURE, SUCCESS_MEASURE), claim_step=BY, at=None, paper=PAPER,
    random_note=(f"The uniform random policy (dashed): success {RANDOM_SUCCESS[0]:.3f} [{RANDOM_SUCCESS[1]:.3f}, "
                 f"{RANDOM_SUCCESS[2]:.3f}], episode reward {RANDOM_RETURN[0]:.2f} [{RANDOM_RETURN[1]:.2f}, "
                 f"{RANDOM_RETURN[2]:.2f}] (2,048 episodes, 2026-12-07, `python experiments/random_level.py --tasks "
                 "melon,melon-doom-motion --envs 1024 --episodes 2`)."),
    verdicts=verdicts,
    notes=("LSTM-A3C is our `--algo a2c`; the paper runs each method 5 times, we run 3 seeds. EC's steps count its "
           "pretraining steps, as Table 2's do. Steps are agent steps, "
           "each holding its action for 4 engine frames (the paper's \"4-repeated steps\").",))


def main(argv: list[str] | None = None) -> int:
    return figure_main(argv, FIGURE, __doc__.split("\n")[0])


if __name__ == "__main__":
    sys.exit(main())
