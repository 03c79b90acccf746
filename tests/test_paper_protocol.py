"""The paper's evaluation protocol (experiments/paper/protocol.py) on hand-made metrics.csv
files: final success, steps to 0.9, the bootstrap over seeds, curves, sweep folders, the
commands read back from config.json, the table and figure scripts and collect.py. No JAX
program is compiled."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from simjax.config_history import TASKS_AS_OF

PAPER = Path(__file__).resolve().parents[1] / "experiments" / "paper"
sys.path.insert(0, str(PAPER))

import collect  # noqa: E402
import figure11  # noqa: E402
import protocol  # noqa: E402
import report  # noqa: E402
import tables  # noqa: E402

COLUMNS = ("env_steps,seed,success_ratio,mean_episode_length,mean_extrinsic_return,episodes,policy_loss,value_loss,"
           "entropy,value_mean,grad_norm,bonus_mean,forward_loss,inverse_loss,steps_per_s,wall_s").split(",")
SIM = {"env": "maze-very-sparse", "algo": "sim", "total_steps": 100, "num_seeds": 1, "seed": 0, "log_every": 10,
       "bonus_scale": 0.001, "act_len": 3, "obs_len": 10, "sim_inverse": True, "sim_combine": "full",
       "sim_sequence": "lstm", "sim_target": "rnd"}


def series(ratios, episodes, step=10):
    """One seed's rows: row i ends at (i + 1) * step agent steps."""
    n = len(ratios)
    return protocol.Series.from_columns({"env_steps": [(i + 1) * step for i in range(n)], "seed": [0] * n,
                                         "success_ratio": list(ratios), "episodes": list(episodes)})


def write_folder(folder: Path, config: dict, rows: list[dict], swept: tuple[str, ...] = (), sweep=None, grid=None,
                 tasks_as_of=TASKS_AS_OF):
    """A run folder (or, with ``swept`` columns, a sweep folder) holding ``rows``; ``tasks_as_of``
    None writes its config.json as it was written before the tasks took the ICM wads' starts."""
    folder.mkdir(parents=True)
    record = {"config": config, "versions": {}} | ({"sweep": sweep, "grid": grid} if sweep else {})
    record |= {"tasks_as_of": tasks_as_of} if tasks_as_of else {}
    (folder / "config.json").write_text(json.dumps(record))
    lines = [",".join([*swept, *COLUMNS])]
    for r in rows:
        values = {c: 0 for c in COLUMNS} | r
        lines.append(",".join([str(r[s]) for s in swept] + [str(values[c]) for c in COLUMNS]))
    (folder / "metrics.csv").write_text("\n".join(lines) + "\n")
    return folder


def test_successes_are_ratio_times_episodes_and_a_row_without_episodes_holds_none():
    s = series([0.0606061, math.nan, 0.5], [33, 0, 4])
    assert s.successes.tolist() == [2, 0, 2] and s.episodes.tolist() == [33, 0, 4]
    with pytest.raises(ValueError):
        series([math.nan], [3])


def test_steps_to_threshold_waits_for_100_episodes_and_reaches_at_the_crossing_row():
    # row 0 alone is 100% but holds 50 episodes; windows of two rows: 0.5, 0.4, then exactly 0.9 at row 3
    s = series([1.0, 0.0, 0.8, 1.0, 1.0], [50, 50, 50, 50, 50])
    windowed = protocol.windowed_success(s)
    assert np.isnan(windowed[0]) and windowed[1:].tolist() == [0.5, 0.4, 0.9, 1.0]
    assert protocol.steps_to_threshold(s) == 40


def test_steps_to_threshold_not_reached_is_none_and_shown_as_more_than_the_steps_trained():
    s = series([0.5, 0.89, 0.89, 0.9], [100, 100, 100, 10], step=25_000)  # last window (rows 2-3): 98/110
    assert protocol.steps_to_threshold(s) is None
    assert report.fmt_steps(None, s.last_step) == ">100k" and report.fmt_steps(None, 1_500_000) == ">1.50M"


def test_the_100_episode_window_spans_as_many_whole_rows_as_it_needs():
    # 30 episodes a row: 3 rows hold 90, so the window at row 3 is all four rows (120 episodes)
    s = series([1.0, 1.0, 1.0, 0.0], [30, 30, 30, 30])
    assert protocol.window_start_by_episodes(s.episodes, 3) == 0
    assert protocol.windowed_success(s)[3] == pytest.approx(90 / 120)
    # a row in which no episode ended adds nothing; the window reaches back past it
    s = series([1.0, math.nan, 0.0, 0.5], [60, 0, 20, 40])
    assert protocol.window_start_by_episodes(s.episodes, 3) == 0  # 40 + 20 + 0 < 100: back to row 0
    assert protocol.windowed_success(s)[3] == pytest.approx((60 + 0 + 0 + 20) / 120)


def test_final_success_is_over_the_fewest_last_rows_covering_100k_steps():
    # rows of 24,640 steps: 4 rows cover 98,560 < 100k, so the window is the last 5 rows
    ratios = [0.0] * 5 + [0.5] + [1.0] * 4
    s = series(ratios, [20] * 10, step=24_640)
    final = protocol.final_success(s)
    assert (final.successes, final.episodes) == (10 + 80, 100)
    assert final.ratio == pytest.approx(0.9)
    assert (final.from_step, final.to_step) == (5 * 24_640, 10 * 24_640)
    assert protocol.window_start_by_steps(np.arange(1, 9) * 25_000) == 4  # 4 rows of 25k cover exactly 100k
    short = protocol.final_success(series([1.0, 0.0], [10, 30], step=25_000))  # under 100k: every row
    assert (short.successes, short.episodes, short.from_step) == (10, 40, 0)
    assert math.isnan(protocol.final_success(series([math.nan], [0], step=200_000)).ratio)


def test_bootstrap_interval_contains_the_mean_is_fixed_and_degenerate_for_identical_seeds():
    values = [0.2, 0.9, 1.0, 0.6, 0.4, 0.95]
    low, high = protocol.bootstrap_interval(values)
    assert low < np.mean(values) < high and 0.2 <= low and high <= 1.0
    assert protocol.bootstrap_interval(values) == (low, high)  # numpy seed 0 every time
    assert protocol.bootstrap_interval([0.7, 0.7, 0.7]) == (0.7, 0.7)
    assert protocol.bootstrap_interval([0.3]) == (0.3, 0.3)
    # steps: the median's interval, with seeds that never reached 0.9 as +inf
    low, high = protocol.bootstrap_interval([1e5, 2e5, math.inf, math.inf, math.inf], "median")
    assert low <= 2e5 and high == math.inf


def test_steps_ratio_is_of_medians_and_bounded_or_undefined_where_a_method_did_not_reach():
    inf = math.inf
    both = protocol.steps_ratio({0: 1e6, 1: 2e6, 2: 3e6}, {0: 4e6, 1: 5e6, 2: 6e6}, (4_000_000, 8_000_000))
    assert both.bound == "" and both.value == pytest.approx(2e6 / 5e6)
    assert 1e6 / 6e6 <= both.interval[0] < both.value < both.interval[1] <= 3e6 / 4e6
    one_each = protocol.steps_ratio({0: 1e6}, {0: 4e6}, (2_000_000, 8_000_000))
    assert one_each.value == 0.25 and one_each.interval == (0.25, 0.25)
    # the denominator's median never reached: the ratio is below the one with its steps trained
    below = protocol.steps_ratio({0: 1e6, 1: 2e6, 2: 3e6}, {0: inf, 1: inf, 2: 5e6}, (4_000_000, 8_000_000))
    assert below.bound == "<" and below.value == 2e6 / 8e6 and below.interval[0] == 0.0
    above = protocol.steps_ratio({0: inf, 1: inf, 2: 1e6}, {0: 2e6, 1: 2e6, 2: 2e6}, (4_000_000, 8_000_000))
    assert above.bound == ">" and above.value == 4e6 / 2e6 and above.interval[1] == inf
    neither = protocol.steps_ratio({0: inf, 1: inf}, {0: inf, 1: math.nan}, (4_000_000, 4_000_000))
    assert math.isnan(neither.value) and neither.interval == (0.0, inf)  # could be any ratio


def test_across_seeds_reports_each_seed_and_ignores_seeds_without_episodes():
    summary = protocol.across_seeds({2: 1.0, 0: 0.5, 1: math.nan})
    assert summary.seeds == (0, 1, 2) and summary.values[0] == 0.5 and math.isnan(summary.values[1])
    assert summary.mean == 0.75 and summary.median == 0.75 and summary.statistic == "mean"
    assert summary.interval[0] >= 0.5 and summary.interval[1] <= 1.0


def test_curve_is_the_mean_over_seeds_with_a_min_max_band():
    seeds = {0: series([0.0, 0.2, 0.4], [100, 100, 100]), 1: series([1.0, 1.0, 1.0], [100, 100, 100])}
    curve = protocol.success_curve(seeds)
    assert curve.env_steps.tolist() == [10, 20, 30]
    assert curve.mean.tolist() == pytest.approx([0.5, 0.6, 0.7])
    assert curve.low.tolist() == pytest.approx([0.0, 0.2, 0.4]) and curve.high.tolist() == [1.0, 1.0, 1.0]


def sweep_rows():
    rows = []
    for act_len, ratio in ((1, 0.25), (3, 1.0)):
        for seed in (0, 1):
            rows += [{"act_len": act_len, "env_steps": k * 25_000, "seed": seed, "success_ratio": ratio, "episodes": 100}
                     for k in (1, 2, 3)]
    return rows


def test_a_sweep_folder_is_one_point_per_grid_entry_and_a_run_folder_one_point(tmp_path):
    grid = [{"act_len": n} for n in (1, 2, 3)]
    folder = write_folder(tmp_path / "sweep", SIM, sweep_rows(), ("act_len",), {"act_len": [1, 2, 3]}, grid)
    points = protocol.read_points(folder)
    assert [p.setting for p in points] == grid
    assert [p.config["act_len"] for p in points] == [1, 2, 3] and points[0].config["algo"] == "sim"
    assert [sorted(p.seeds) for p in points] == [[0, 1], [], [0, 1]]  # L = 2 has no rows yet
    assert points[0].seeds[1].successes.tolist() == [25, 25, 25] and points[2].trained == 75_000
    assert protocol.label_points([points[0], points[2]]) == ["SIM (L=1)", "SIM (L=3)"]
    run = write_folder(tmp_path / "run", SIM, [{"env_steps": 10, "seed": 0, "success_ratio": 0.5, "episodes": 4}])
    with open(run / "metrics.csv", "a") as f:
        f.write("20,0,0.7,300")  # the row a running training is writing as it is read
    (point,) = protocol.read_points(run)
    assert point.setting == {} and point.name == "run" and point.seeds[0].successes.tolist() == [2]


def test_swept_cells_match_their_grid_values_whatever_their_spelling():
    assert protocol.same_value("True", True) and protocol.same_value("false", False) and not protocol.same_value("1", False)
    assert protocol.same_value("0.0001", 1e-4) and protocol.same_value("1e-04", 0.0001) and not protocol.same_value("0.001", 1e-4)
    assert protocol.same_value("itr", "itr") and protocol.parse_cell("3") == 3 and protocol.parse_cell("0.01") == 0.01


def test_labels_show_only_the_settings_that_differ_and_matter_to_the_method():
    icm = SIM | {"algo": "icm", "bonus_scale": 0.01}
    points = [protocol.Point(Path(n), {}, c, {}, {}) for n, c in
              (("a", SIM), ("b", SIM | {"sim_sequence": "ff"}), ("c", icm), ("d", SIM | {"act_len": 1, "sim_inverse": False}))]
    assert protocol.label_points(points) == [
        "SIM (L=3, inverse=on, seq=lstm, beta=0.001)", "SIM-no-Seq (L=3, inverse=on, seq=ff, beta=0.001)",
        "ICM (beta=0.01)", "SIM (L=1, inverse=off, seq=lstm, beta=0.001)"]
    twins = [protocol.Point(Path("x"), {}, SIM, {}, {}), protocol.Point(Path("y"), {}, SIM, {}, {})]
    assert protocol.label_points(twins) == ["SIM [x]", "SIM [y]"]


def test_commands_are_read_back_from_config_json(tmp_path):
    run = write_folder(tmp_path / "run", SIM | {"bonus_scale": 0.01, "total_steps": 500000, "num_seeds": 3}, [])
    (command,) = report.input_commands(run)
    assert command.startswith("python -m simjax.train --env maze-very-sparse --algo sim --total-steps 500000 --num-seeds 3")
    assert "--bonus-scale 0.01" in command and "--act-len" not in command and command.endswith("--out " + report.rel(run))
    sweep = write_folder(tmp_path / "sweep", SIM, [], ("act_len",), {"act_len": [1, 2, 3, 4, 5]}, [{"act_len": 1}])
    (command,) = report.input_commands(sweep)
    assert command.startswith("python -m simjax.sweep --env maze-very-sparse --algo sim")
    assert "--act-len 1,2,3,4,5 --out" in command and command.count("--act-len") == 1


def test_figure11_and_the_tables_write_csv_markdown_and_png(tmp_path):
    grid = [{"act_len": n} for n in (1, 2, 3)]
    folder = write_folder(tmp_path / "sweep", SIM, sweep_rows(), ("act_len",), {"act_len": [1, 2, 3]}, grid)
    out = tmp_path / "results" / "paper-figure11"
    assert figure11.main([str(folder), "--out", str(out)]) == 0
    md = (out / "figure11.md").read_text()
    assert "SIM (L=1)" in md and "SIM (L=3)" in md and "missing: L=2" in md and "python -m simjax.sweep" in md
    assert "0.250 (300) / 0.250 (300)" in md  # 3 rows of 100 episodes per seed, 75k steps: all of them
    assert (out / "figure11.png").stat().st_size > 0 and "env_steps" in (out / "figure11-curves.csv").read_text()
    assert tables.main([str(folder), "--out-dir", str(tmp_path / "results")]) == 0
    table1 = (tmp_path / "results" / "paper-table1" / "table1.md").read_text()
    assert "| maze-very-sparse | ICM | no run |" in table1 and "68.6%" in table1  # the paper's number beside ours
    assert "1.000 (300) / 1.000 (300)" in table1  # the L = 3 point: 100% in its last 100k steps
    table2 = (tmp_path / "results" / "paper-table2" / "table2.md").read_text()
    assert "| >75k / >75k | >75k [>75k, >75k] | 0/2 |" in table2  # L = 1 never reaches 0.9
    assert "| 25k / 25k | 25k [25k, 25k] | 2/2 |" in table2  # L = 3 does at its first row of 100 episodes
    assert "| maze-very-sparse | no run | no run |" in table2  # SIM : RND and SIM : ICM need both cells
    assert "SIM : RND = 0.40" in table2  # the paper's 1.82m / 4.51m beside ours


def test_a_folder_written_before_the_icm_starts_is_tabled_by_the_start_it_trained_with(tmp_path):
    rows = [{"env_steps": 25_000 * (i + 1), "seed": 0, "success_ratio": 0.5, "episodes": 100} for i in range(4)]
    old = write_folder(tmp_path / "old", SIM, rows, tasks_as_of=None)  # maze-very-sparse meant spot 10, east
    new = write_folder(tmp_path / "new", SIM | {"algo": "rnd", "bonus_scale": 0.01}, rows)  # spot 15, west
    (point,) = protocol.read_points(old)
    assert point.config["env"] == "maze-spot10-east" and point.record["tasks_as_of"] == TASKS_AS_OF
    assert report.input_commands(old)[0].startswith("python -m simjax.train --env maze-spot10-east --algo sim")
    assert protocol.read_points(new)[0].config["env"] == "maze-very-sparse"
    assert tables.main([str(old), str(new), "--out-dir", str(tmp_path / "results")]) == 0
    table1 = (tmp_path / "results" / "paper-table1" / "table1.md").read_text()
    assert "| maze-sparse (as maze-spot10-east+) | SIM | `old` |" in table1  # the paper's sparse column, marked
    assert "| maze-very-sparse | SIM | no run |" in table1 and "| maze-very-sparse | RND | `new` |" in table1
    assert "without its 0-3.6 degree jitter" in table1


def test_a_melon_folder_written_before_dmlabs_motion_reads_as_the_doom_motion_world(tmp_path):
    rows = [{"env_steps": 25_000 * (i + 1), "seed": 0, "success_ratio": 0.5, "episodes": 100} for i in range(4)]
    for name, tasks_as_of, want in (("none", None, "melon-doom-motion"), ("dec4", "2026-12-04", "melon-doom-motion"),
                                    ("today", TASKS_AS_OF, "melon")):
        folder = write_folder(tmp_path / name, SIM | {"env": "melon"}, rows, tasks_as_of=tasks_as_of)
        (point,) = protocol.read_points(folder)
        assert point.config["env"] == want and point.record["tasks_as_of"] == TASKS_AS_OF
        assert report.input_commands(folder)[0].startswith(f"python -m simjax.train --env {want} --algo sim")


def test_an_empty_ec_cell_asks_for_the_pretraining_passes_the_tables_ec_runs_used():
    run = lambda c: protocol.Point(Path("r"), {}, SIM | {"total_steps": 4_000_000, "num_seeds": 3} | c, {}, {})
    ec3 = run({"algo": "ec", "total_steps": 4_600_000, "ec_pretrain_epochs": 3})
    command = tables.missing_command("maze-dense", "ec", [run({}), run({}), ec3])
    assert "--total-steps 4600000 --num-seeds 3 --ec-pretrain-epochs 3 --out" in command
    assert "--ec-pretrain-epochs" not in tables.missing_command("maze-dense", "ec", [run({}), run({})])
    assert "--ec-pretrain-epochs" not in tables.missing_command("maze-dense", "sim", [run({}), ec3])


def test_collect_inserts_the_section_after_the_first_heading_then_replaces_only_it(tmp_path):
    (tmp_path / "results" / "paper-x").mkdir(parents=True)
    (tmp_path / "results" / "paper-x" / "x.md").write_text("# Table X\n\n| a |\n|---|\n| 0.5 |\n\n![x](x.png)\n")
    (tmp_path / "docs").mkdir()
    page = tmp_path / "docs" / "results.md"
    page.write_text("# Results\n\nintro\n\n## old\n")
    collect.main(["--page", str(page), "--results", str(tmp_path / "results")])
    text = page.read_text()
    assert text.startswith("# Results\n\n" + collect.BEGIN) and text.endswith("intro\n\n## old\n")
    assert "### Table X" in text and "](../results/paper-x/x.png)" in text and "| 0.5 |" in text
    (tmp_path / "results" / "paper-x" / "x.md").write_text("# Table X\n\n| 0.7 |\n")
    collect.main(["--page", str(page), "--results", str(tmp_path / "results")])
    again = page.read_text()
    assert "| 0.7 |" in again and "| 0.5 |" not in again and again.count(collect.BEGIN) == 1
    assert again.endswith("intro\n\n## old\n")


def test_a_runs_command_spells_out_what_differs_from_its_tasks_defaults():
    ec = {"env": "maze-very-sparse", "algo": "ec", "total_steps": 1000, "num_seeds": 3, "ec_pretrain_epochs": 1}
    assert report.config_flags(ec) == ["--env", "maze-very-sparse", "--algo", "ec", "--total-steps", "1000",
                                       "--num-seeds", "3", "--ec-pretrain-epochs", "1", "--ec-beta", "0.5"]
    assert "--ec-beta" not in report.config_flags({**ec, "ec_beta": 1.0})  # maze-very-sparse's default
    assert "--ec-beta" not in report.config_flags({**ec, "env": "explore-goals", "ec_beta": 0.5})
    sim = {"env": "maze-very-sparse", "algo": "sim", "total_steps": 1000, "num_seeds": 1, "ec_beta": 0.5}
    assert report.config_flags(sim) == ["--env", "maze-very-sparse", "--algo", "sim", "--total-steps", "1000",
                                        "--num-seeds", "1"]


def test_fisher_exact_by_hand():
    """Fisher's tea-tasting table, 3 of 4 against 1 of 4: two-sided p = (1 + 16 + 1 + 16) / 70,
    every table no more likely than the one seen (the hypergeometric weights are 1, 16, 36, 16, 1)."""
    assert protocol.fisher_exact(3, 4, 1, 4) == pytest.approx(34 / 70)
    assert protocol.fisher_exact(2, 4, 2, 4) == pytest.approx(1.0)
    assert protocol.fisher_exact(0, 1000, 30, 1000) < 1e-8


def test_the_screen_counts_whole_rows_of_the_second_half_and_calls_an_arm_that_beats_the_control(tmp_path, capsys):
    """experiments/screen.py: the second half is the rows that start at or after half the arm's
    last step; an arm whose second half is far above the control's (Fisher p < 0.01) helps, and
    one like the control does not; an arm at another precision than the control's says so."""
    sys.path.insert(0, str(PAPER.parent))
    import screen

    s = series([0.0, 0.5, 0.25, 1.0], [10, 10, 4, 2], step=25)  # rows (0, 25], (25, 50], (50, 75], (75, 100]
    assert screen.counts(s, 50, 100) == (1 + 2, 4 + 2)
    assert screen.counts(s, 40, 100) == (3, 6)  # the row (25, 50] starts before 40: left out whole
    assert screen.counts(s, 0, 75) == (0 + 5 + 1, 24)
    config = SIM | {"total_steps": 100}
    control = write_folder(tmp_path / "control", config, [
        {"env_steps": 25 * (i + 1), "seed": seed, "success_ratio": 0.0, "episodes": 100} for i in range(8)
        for seed in range(3)])
    better = write_folder(tmp_path / "better", config, [
        {"env_steps": 25 * (i + 1), "seed": seed, "success_ratio": 0.0 if i < 2 else 0.2, "episodes": 100}
        for i in range(4) for seed in range(3)])
    same = write_folder(tmp_path / "same", config | {"precision": "bfloat16"}, [
        {"env_steps": 25 * (i + 1), "seed": seed, "success_ratio": 0.0, "episodes": 100}
        for i in range(4) for seed in range(3)])
    assert screen.main([str(better), str(same), "--control", str(control)]) == 0
    out = capsys.readouterr().out
    assert "second half (50, 100]: 120/600 (20.000%) against the control's 0/600" in out
    assert out.count("HELPS") == 1 and "1 of 2 arm(s) help" in out
    assert out.count("precision bfloat16, the control's highest") == 1  # said of the arm that differs, only


# -- Figures 5 and 6: thresholds at any level, any per-episode column, the DMLab figure scripts ------

RETURN = "mean_extrinsic_return"


def return_series(returns, episodes, step=10):
    """One seed's rows with an episode return column: row i ends at (i + 1) * step agent steps."""
    n = len(returns)
    return protocol.Series.from_columns({"env_steps": [(i + 1) * step for i in range(n)], "seed": [0] * n,
                                         "success_ratio": [0.0] * n, "episodes": list(episodes), RETURN: list(returns)})


def test_steps_to_a_threshold_at_another_level_reaches_at_the_row_its_window_crosses_it():
    # 60 episodes a row, so each window is the last two rows: 72/120 = 0.6, 96/120 = 0.8, 102/120 = 0.85, 0.85
    s = series([0.5, 0.7, 0.9, 0.8, 0.9], [60] * 5)
    assert protocol.windowed_mean(s).tolist()[1:] == pytest.approx([0.6, 0.8, 0.85, 0.85])
    assert protocol.steps_to_threshold(s, 0.8) == 30  # exactly 0.8 counts
    assert protocol.steps_to_threshold(s, 0.81) == 40 and protocol.steps_to_threshold(s) is None  # 0.9: never


def test_the_return_window_weights_each_row_by_its_episodes():
    # row sums 600, 1500, 0, 640, 1750; windows of >= 100 episodes: rows 0-1 (110), 0-2 (110), 0-3 (150), 3-4 (110)
    s = return_series([10.0, 30.0, math.nan, 16.0, 25.0], [60, 50, 0, 40, 70])
    assert protocol.episode_sums(s, RETURN).tolist() == [600.0, 1500.0, 0.0, 640.0, 1750.0]
    windowed = protocol.windowed_mean(s, RETURN)
    assert math.isnan(windowed[0])
    assert windowed[1:].tolist() == pytest.approx([2100 / 110, 2100 / 110, 2740 / 150, 2390 / 110])
    # rows 0-1 average 20 unweighted, but 19.09 by episodes: 20 is first reached at row 4
    assert protocol.steps_to_threshold(s, 20.0, column=RETURN) == 50
    assert protocol.steps_to_threshold(s, 19.0, column=RETURN) == 20
    with pytest.raises(ValueError):
        protocol.episode_sums(return_series([math.nan], [3]), RETURN)


def test_level_is_final_success_of_any_column_and_at_any_step():
    # rows of 30k steps; up to 200k the rows end at 30k..180k, and the fewest last of them covering >= 100k
    # are the rows ending at 90k..180k (from 60k): returns 10, 20, 30, 40 over 10, 20, 30, 40 episodes
    returns = [0.0, 0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 50.0, 50.0, 50.0]
    s = return_series(returns, [5, 5, 10, 20, 30, 40, 10, 10, 10, 10], step=30_000)
    at = protocol.level(s, RETURN, until=200_000)
    assert (at.value, at.total, at.episodes, at.from_step, at.to_step) == (30.0, 3000.0, 100, 60_000, 180_000)
    final = protocol.level(s, RETURN)  # the last 4 rows: (180k, 300k]
    assert (final.value, final.episodes, final.from_step, final.to_step) == (50.0, 40, 180_000, 300_000)
    early = protocol.level(s, RETURN, until=20_000)  # no row ends by 20k
    assert math.isnan(early.value) and early.episodes == 0
    ratios = series([0.0] * 5 + [0.5] + [1.0] * 4, [20] * 10, step=24_640)
    success = protocol.level(ratios)
    assert (success.value, success.total, success.episodes) == (protocol.final_success(ratios).ratio, 90.0, 100)


def test_mean_curve_of_the_return_and_success_curve_is_it_on_success():
    seeds = {0: return_series([10.0, 20.0], [100, 100]), 1: return_series([30.0, 40.0], [100, 100])}
    curve = protocol.mean_curve(seeds, RETURN)
    assert curve.mean.tolist() == [20.0, 30.0] and curve.low.tolist() == [10.0, 20.0] and curve.high.tolist() == [30.0, 40.0]
    runs = {0: series([0.0, 0.2, 0.4], [100, 50, 50]), 1: series([1.0, 0.5, 1.0], [100, 100, 100])}
    a, b = protocol.success_curve(runs), protocol.mean_curve(runs, protocol.SUCCESS)
    assert all(np.array_equal(x, y, equal_nan=True) for x, y in zip((a.mean, a.low, a.high), (b.mean, b.low, b.high)))


def dmlab_run(root: Path, env: str, algo: str, budget: int, per_seed: list[list[float]], column: str) -> Path:
    """A run folder of rows of 100k agent steps and 100 episodes (so each window is one row)."""
    config = {"env": env, "algo": algo, "total_steps": budget, "num_seeds": len(per_seed), "seed": 0, "log_every": 100_000}
    rows = [{"env_steps": 100_000 * (i + 1), "seed": seed, "episodes": 100, "success_ratio": 0.0, column: v}
            for seed, values in enumerate(per_seed) for i, v in enumerate(values)]
    return write_folder(root / f"{env}-{algo}", config, rows)


def test_figure6_gives_each_seeds_steps_to_80_percent_and_the_claims_verdicts(tmp_path, capsys):
    import figure6

    up = lambda first: [0.5] * (first - 1) + [0.8] + [0.9] * (10 - first)  # first row (1-based) at >= 0.8
    sim = dmlab_run(tmp_path, "melon", "sim", 1_000_000, [up(2), up(1), up(3)], "success_ratio")
    rnd = dmlab_run(tmp_path, "melon", "rnd", 1_000_000, [up(7), up(8), [0.5] * 10], "success_ratio")
    a2c = dmlab_run(tmp_path, "melon", "a2c", 1_000_000, [[0.4] * 10] * 3, "success_ratio")
    other = dmlab_run(tmp_path, "maze-dense", "sim", 1_000_000, [[0.1] * 10], "success_ratio")
    out = tmp_path / "paper-figure6"
    assert figure6.main([str(sim), str(rnd), str(a2c), str(other), "--out", str(out)]) == 0
    md = (out / "figure6.md").read_text()
    assert "| 200k / 100k / 300k | 200k [100k, 300k] | 3/3 |" in md  # SIM: median 200k
    assert "| 700k / 800k / >1.00M | 800k [700k, >1.00M] | 2/3 |" in md  # RND: median 800k
    assert "0.400 (100) / 0.400 (100) / 0.400 (100) | 0.400 [0.400, 0.400]" in md  # LSTM-A3C's final success
    assert "RND: SIM : RND = 0.25 [" in md and "SIM 4.0x as fast (holds)" in md
    assert "LSTM-A3C: SIM : LSTM-A3C = <0.20" in md and "ICM: no run" in md and "EC: no run" in md
    verdicts = [line.rsplit("|", 2)[1].strip() for line in md.splitlines() if line.startswith(("| SIM passes", "| at least",
                                                                                                   "| LSTM-A3C converges"))]
    assert verdicts == ["**holds**", "**cannot tell**", "**holds**"]  # 3x: holds where run, ICM and EC missing
    assert "--algo ec --total-steps 1600000 --num-seeds 3 --ec-pretrain-epochs 3" in md and "`maze-dense-sim`" in md
    assert "running mean" in md and "0.111 [0.098, 0.126]" in md
    table = (out / "figure6.csv").read_text()
    assert "200000;100000;300000" in table and "700000;800000;," in table
    assert "missing ICM: python -m simjax.train --env melon --algo icm" in capsys.readouterr().out
    assert (out / "figure6.png").stat().st_size > 0 and "success_ratio" in (out / "figure6-curves.csv").read_text()


def test_figure5_gives_each_seeds_reward_at_1m_and_steps_to_20(tmp_path):
    import figure5

    reach = lambda first, after: [10.0] * (first - 1) + [after] * (21 - first)  # rows of 100k to 2M
    sim = dmlab_run(tmp_path, "explore-goals", "sim", 2_000_000, [reach(6, 25.0), reach(8, 24.0), reach(9, 23.0)], RETURN)
    icm = dmlab_run(tmp_path, "explore-goals", "icm", 2_000_000, [reach(16, 21.0), reach(17, 21.0), reach(18, 21.0)], RETURN)
    rnd = dmlab_run(tmp_path, "explore-goals", "rnd", 2_000_000, [reach(9, 22.0), reach(10, 22.0), reach(11, 22.0)], RETURN)
    a2c = dmlab_run(tmp_path, "explore-goals", "a2c", 2_000_000, [[9.0] * 20] * 3, RETURN)
    out = tmp_path / "paper-figure5"
    assert figure5.main([str(p) for p in (sim, icm, rnd, a2c)] + ["--out", str(out)]) == 0
    md = (out / "figure5.md").read_text()
    # SIM reaches 20 at 600k, 800k, 900k; at 1M (its last 100k: the row ending at 1M) it scores 25, 24, 23
    assert "| 600k / 800k / 900k | 800k [600k, 900k] | 3/3 | 25.00 (100) / 24.00 (100) / 23.00 (100) | 24.00 [" in md
    assert "| 1.60M / 1.70M / 1.80M | 1.70M [1.60M, 1.80M] | 3/3 |" in md  # ICM
    assert "| 900k / 1.00M / 1.10M | 1.00M [900k, 1.10M] | 3/3 |" in md  # RND: by 1M, not "about 2M"
    assert "9.00 (100) / 9.00 (100) / 9.00 (100) | 9.00 [9.00, 9.00] |" in md  # LSTM-A3C's final reward
    verdicts = [line.rsplit("|", 2)[1].strip() for line in md.splitlines() if line.startswith(("| SIM scores",
                                                                                                   "| ICM and RND", "| the agent"))]
    assert verdicts == ["**holds**", "**does not hold**", "**holds**"]
    assert "ICM: median 1.70M" in md and "(holds); RND: median 1.00M" in md and "4.91 [4.42, 5.41]" in md
    table = (out / "figure5.csv").read_text()
    assert "600000;800000;900000" in table and "25;24;23" in table and "missing" not in md
