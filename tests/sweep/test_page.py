"""The sweep page's sections on hand-built rows (dsg_hil.sweep.page)."""

from __future__ import annotations

from dsg_hil.sweep.page import ROLLBACK_DRIVABLE_MPS, drivability_lines, latent_lines


def row(run_id: str, rollback_mps: float | None) -> dict:
    return {"run_id": run_id, "rollback_mps": rollback_mps, "rollback_m": 0.001, "in.grade_rad": 0.2}


def test_drivability_lists_the_runs_rolling_back_faster_than_the_target_worst_first():
    rows = [row("slow", -0.005), row("fast", -0.095), row("edge", -ROLLBACK_DRIVABLE_MPS), row("mid", -0.02),
            row("none", None)]
    text = "\n".join(drivability_lines(rows, ["in.grade_rad"]))
    assert "**2 of 5**" in text
    table = [line for line in text.splitlines() if line.startswith("| ") and "run_id" not in line]
    assert [line.split(" | ")[0].removeprefix("| ") for line in table] == ["fast", "mid"]
    assert "| fast | -0.095 | 0.001 | 0.2 |" in table


def test_drivability_without_a_fast_roll_back_has_no_table():
    lines = drivability_lines([row("slow", -0.005)], [])
    assert "**0 of 1**" in "\n".join(lines) and not any(line.startswith("|") for line in lines)


def test_drivability_lists_the_runs_whose_speed_left_the_band_through_a_handover_worst_first():
    """Worst first, with the deviation through the handovers without the driver's pedal in their window: a's 42.7 %
    came with a light drag (its unbraked handovers 12 %), c's without one."""
    rows = [row("a", -0.001) | {"handover_deviation_pct": 42.7, "handover_deviation_unbraked_pct": 12.0,
                                "max_speed_creep_mps": 0.436},
            row("b", -0.001) | {"handover_deviation_pct": 20.0, "handover_deviation_unbraked_pct": 20.0,
                                "max_speed_creep_mps": 0.24},
            row("c", -0.001) | {"handover_deviation_pct": 25.1, "handover_deviation_unbraked_pct": 25.1,
                                "max_speed_creep_mps": 0.25},
            row("d", -0.001) | {"handover_deviation_pct": None, "handover_deviation_unbraked_pct": None,
                                "max_speed_creep_mps": 0.5},
            row("e", -0.001) | {"handover_deviation_pct": 30.0, "handover_deviation_unbraked_pct": None,
                                "max_speed_creep_mps": 0.3}]  # its only handover braked
    text = "\n".join(drivability_lines(rows, ["in.grade_rad"]))
    assert "**3 of the 4 with such a handover**; through a handover without the driver's pedal in its window: **1**" \
        in text
    assert "| a | 42.7 | 12 | 0.436 | 0.2 |" in text and "| c | 25.1 | 25.1 | 0.25 | 0.2 |" in text
    assert text.index("| a |") < text.index("| e |") < text.index("| c |") and "| b |" not in text


def test_the_page_counts_the_violating_runs_by_their_latent_faults():
    rows = [{"latent_x": 1.4, "verdict": "violation"}, {"latent_x": 0.9, "verdict": "violation"},
            {"latent_x": None, "verdict": "ok"}, {"latent_x": 2.0, "verdict": "ok"}]
    (line, _) = latent_lines(rows, rows[:2])
    assert line == ("Latent sensor faults: of the 4 runs, 2 with a latent fault beyond its detection threshold, "
                    "1 with latent faults all within their thresholds, 1 without a latent fault; of the 2 violating, "
                    "1 with a latent fault beyond its detection threshold, 1 with latent faults all within their "
                    "thresholds.")
    assert latent_lines(rows[2:3], []) == []  # a space without latent faults: no line
