"""The end-to-end tests' judge of a sender's pace (``frames_over_cycle``), on made-up send times."""

from __future__ import annotations

import random

import pytest

from dsg_hil.e2e.conftest import frames_over_cycle

CYCLE = 0.1


def on_grid(n: int, late: dict[int, float] | None = None, phase: float = 0.013) -> list[float]:
    """``n`` frames, one per grid slot, each ``late[k]`` seconds after its slot (0 by default)."""
    late = late or {}
    return [phase + k * CYCLE + late.get(k, 0.0) for k in range(n)]


def test_a_sender_on_its_grid_has_no_excess():
    assert frames_over_cycle(on_grid(400), CYCLE) == pytest.approx(0.0, abs=1e-9)


def test_a_late_first_frame_is_not_counted_against_the_sender():
    """The CI run of 2026-12-03: the first TCU_STATUS left ~80 ms late, the second on time; counted from the first
    the span was short, 447 frames in 44.49 s against at most 446.9."""
    times = on_grid(447, late={0: 0.18})
    assert (len(times) - 1) > (times[-1] - times[0]) / CYCLE + 1.0  # the old count from the first frame: over
    assert frames_over_cycle(times, CYCLE) == pytest.approx(0.0, abs=1e-9)


def test_skipped_cycles_and_random_lateness_stay_within_one_frame():
    rng = random.Random(7)
    times = [t for k, t in enumerate(on_grid(600, late={k: rng.uniform(0.0, 0.3) for k in range(600)}))
             if k % 37 != 5]  # a starved sender skips cycles; every frame up to 3 cycles late
    times.sort()
    assert frames_over_cycle(times, CYCLE) <= 1.0


@pytest.mark.parametrize("extra", [0.5, 0.2])
def test_a_sender_faster_than_its_cycle_is_caught(extra):
    """One frame every cycle / (1 + extra): the excess grows with the run."""
    period = CYCLE / (1.0 + extra)
    times = [k * period for k in range(400)]
    assert frames_over_cycle(times, CYCLE) > 10.0


def test_a_double_send_now_and_then_is_caught():
    times = sorted(on_grid(200) + [t + 0.001 for t in on_grid(200)[::20]])
    assert frames_over_cycle(times, CYCLE) > 1.0
