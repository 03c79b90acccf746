"""The paper's Figure 7: the ablations of SIM on maze-very-sparse (section 3.5).

    python experiments/paper/figure7.py [RUN_OR_SWEEP_FOLDER ...] [--out experiments/results/paper-figure7]

(a) action length L = 1 against L = 3; (b) the inverse loss on and off at L = 3 and L = 1;
(c) h_t combined as full [ho, ha, ho*ha], itr (ho*ha) and concat ([ho, ha]); (d) SIM-no-Seq
and SIM-no-RND against SIM and ICM. Every other SIM setting is the paper's (H = 10, L = 3,
inverse on, full, LSTMs, RND target). Curves are labelled by how their configs differ
(``act_len``, ``sim_inverse``, ``sim_combine``, ``sim_sequence``, ``sim_target``, ...).

Default inputs: ``experiments/results/figure7/*/`` and SIM's and ICM's Table 1 runs on
maze-very-sparse. Writes figure7.{png,csv,md} and figure7-curves.csv.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from report import Panel, Variant, figure_main  # noqa: E402

DEFAULT_INPUTS = ["experiments/results/figure7/*/", "experiments/results/table1/maze-very-sparse-sim/",
                  "experiments/results/table1/maze-very-sparse-icm/", "experiments/results/table1/maze-spot10-east-sim/",
                  "experiments/results/table1/maze-spot10-east-icm/"]
SIM = {"env": "maze-very-sparse", "algo": "sim", "obs_len": 10, "act_len": 3, "sim_inverse": True, "sim_combine": "full",
       "sim_sequence": "lstm", "sim_target": "rnd"}

PANELS = [
    Panel("a", "multi-step prediction: L = 1 vs L = 3", SIM,
          (Variant("H10-L1", {"act_len": 1}), Variant("H10-L3", {"act_len": 3})),
          "3-step forward prediction converges apparently better than the L1 variant."),
    Panel("b", "inverse dynamics loss on / off", SIM,
          (Variant("H10-L1", {"act_len": 1}), Variant("H10-L1 (inv-off)", {"act_len": 1, "sim_inverse": False}),
           Variant("H10-L3", {"act_len": 3}), Variant("H10-L3 (inv-off)", {"act_len": 3, "sim_inverse": False})),
          "at L1 the inverse loss matters little; H10-L3 (inv-off) is much worse than H10-L1 (inv-off)."),
    Panel("c", "h_t: full vs SIM-itr vs SIM-concat", SIM,
          (Variant("SIM", {}), Variant("SIM-itr", {"sim_combine": "itr"}), Variant("SIM-concat", {"sim_combine": "concat"})),
          "SIM-itr and SIM-concat fail occasionally, so their mean does not reach 100%; full h_t always does."),
    Panel("d", "sequence / RND modules: SIM-no-Seq, SIM-no-RND vs ICM", SIM,
          (Variant("SIM", {}), Variant("SIM-no-Seq", {"sim_sequence": "ff"}), Variant("SIM-no-RND", {"sim_target": "embed"}),
           Variant("ICM", {"algo": "icm"})),
          "SIM-no-Seq outperforms ICM; SIM-no-RND converges much faster than ICM; SIM is best."),
]


def main(argv: list[str] | None = None) -> int:
    return figure_main(argv, "figure7", "Figure 7: ablations of SIM on maze-very-sparse", PANELS, DEFAULT_INPUTS, __doc__.split("\n")[0])


if __name__ == "__main__":
    sys.exit(main())
