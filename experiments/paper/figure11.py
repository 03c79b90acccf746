"""The paper's Figure 11 (appendix B.6): SIM's action length L in {1, 2, 3, 4, 5} on
maze-very-sparse, from one sweep folder.

    python experiments/paper/figure11.py [SWEEP_OR_RUN_FOLDER ...] [--out experiments/results/paper-figure11]

Curves are labelled by ``act_len`` (read from the sweep's columns, or a run's config.json).
Default input: ``experiments/results/figure11-sweep/``, made by
``python -m simjax.sweep --env maze-very-sparse --algo sim --act-len 1,2,3,4,5 ...``.
Writes figure11.{png,csv,md} and figure11-curves.csv.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from report import Panel, Variant, figure_main  # noqa: E402

DEFAULT_INPUTS = ["experiments/results/figure11-sweep/"]
LENGTHS = (1, 2, 3, 4, 5)
SIM = {"env": "maze-very-sparse", "algo": "sim", "obs_len": 10, "sim_inverse": True, "sim_combine": "full",
       "sim_sequence": "lstm", "sim_target": "rnd"}
PANELS = [
    Panel("L", "maze-very-sparse: action length L", SIM, tuple(Variant(f"L={n}", {"act_len": n}) for n in LENGTHS),
          "L = 3 has an apparent advantage over L = 1 and L = 2; L = 4 and L = 5 none over L = 3.",
          "python -m simjax.sweep --env maze-very-sparse --algo sim --act-len 1,2,3,4,5 --total-steps STEPS "
          "--num-seeds SEEDS --out experiments/results/figure11-sweep"),
]


def main(argv: list[str] | None = None) -> int:
    return figure_main(argv, "figure11", "Figure 11: SIM's action length L on maze-very-sparse", PANELS,
                       DEFAULT_INPUTS, __doc__.split("\n")[0])


if __name__ == "__main__":
    sys.exit(main())
