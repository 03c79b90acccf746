"""The paper's Figure 9 (appendix B.5): SIM's bonus scale beta in {0.01, 0.001, 0.0001} on
maze-dense and maze-very-sparse.

    python experiments/paper/figure9.py [RUN_OR_SWEEP_FOLDER ...] [--out experiments/results/paper-figure9]

The paper plots task reward; on these tasks (+1 at the goal, episode ends there) the mean
episode return is the success ratio, which is what is drawn. Curves are labelled by
``bonus_scale`` (and any other setting in which the inputs differ).

Default inputs: ``experiments/results/figure9*/`` (run folders in ``figure9/``, or a sweep
folder over ``bonus_scale``) and SIM's Table 1 runs on both tasks (beta = 0.001). Writes
figure9.{png,csv,md} and figure9-curves.csv.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from report import Panel, Variant, figure_main  # noqa: E402

DEFAULT_INPUTS = ["experiments/results/figure9/*/", "experiments/results/figure9-*/",
                  "experiments/results/table1/maze-dense-sim/", "experiments/results/table1/maze-very-sparse-sim/",
                  "experiments/results/table1/maze-spot10-east-sim/"]
BETAS = (0.01, 0.001, 0.0001)
SIM = {"algo": "sim", "obs_len": 10, "act_len": 3, "sim_inverse": True, "sim_combine": "full", "sim_sequence": "lstm",
       "sim_target": "rnd"}


def panel(key: str, env: str, paper: str) -> Panel:
    make = (f"python -m simjax.sweep --env {env} --algo sim --bonus-scale {','.join(map(str, BETAS))} "
            f"--total-steps STEPS --num-seeds SEEDS --out experiments/results/figure9-{env}")
    return Panel(key, f"{env}: beta", SIM | {"env": env},
                 tuple(Variant(f"beta {b:g}", {"bonus_scale": b}) for b in BETAS), paper, make)


PANELS = [
    panel("left", "maze-dense", "0.001 and 0.0001 both learn; 0.01 biases behaviour and does worse."),
    panel("right", "maze-very-sparse", "0.0001 is too small to let learning progress, 0.01 biases behaviour; 0.001 works."),
]


def main(argv: list[str] | None = None) -> int:
    return figure_main(argv, "figure9", "Figure 9: SIM's bonus scale beta", PANELS, DEFAULT_INPUTS, __doc__.split("\n")[0])


if __name__ == "__main__":
    sys.exit(main())
