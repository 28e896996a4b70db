"""The TCU's friction-map lookup (built once per map, ``ecu_stub.clutch_model``) gives the very floats of the plain
trilinear interpolation it replaced, at the grid points, between them and clamped beyond them."""

from __future__ import annotations

import random
from bisect import bisect_right

from ecu_stub.calibration import Clutch, FrictionMap, load_calibration
from ecu_stub.clutch_model import friction_coefficient, friction_heat, torque_per_mpa
from dsg_hil.common.units import CV


def locate(grid: tuple[float, ...], x: float) -> tuple[int, float]:
    if x <= grid[0]:
        return 0, 0.0
    if x >= grid[-1]:
        return len(grid) - 2, 1.0
    i = bisect_right(grid, x) - 1
    return i, (x - grid[i]) / (grid[i + 1] - grid[i])


def plain_mu(m: FrictionMap, T_c: float, slip_rpm: float, P_mpa: float) -> float:
    """The straightforward lookup: each axis located, the four (T, slip) corners interpolated in P, summed."""
    i, wt = locate(m.T_grid_c, T_c)
    j, ws = locate(m.slip_grid_rpm, abs(slip_rpm))
    k, wp = locate(m.P_grid_mpa, P_mpa)
    lo, hi = m.mu[i], m.mu[i + 1]
    a, b, c, d = lo[j], lo[j + 1], hi[j], hi[j + 1]
    vt, vs, vp = 1 - wt, 1 - ws, 1 - wp
    mu = 0.0
    mu += vt * vs * (vp * a[k] + wp * a[k + 1])
    mu += vt * ws * (vp * b[k] + wp * b[k + 1])
    mu += wt * vs * (vp * c[k] + wp * c[k + 1])
    mu += wt * ws * (vp * d[k] + wp * d[k + 1])
    return mu


def samples(grid: tuple[float, ...], rng: random.Random, n: int) -> list[float]:
    """Grid points, points beyond both ends and random points inside."""
    span = grid[-1] - grid[0]
    return [*grid, grid[0] - 1.0, grid[-1] + 1.0, *(rng.uniform(grid[0] - 0.1 * span, grid[-1] + 0.1 * span)
                                                    for _ in range(n))]


def test_map_lookup_is_bit_identical_to_the_plain_interpolation():
    cal = load_calibration()
    m, rng = cal.friction, random.Random(17)
    temps, slips = samples(m.T_grid_c, rng, 40), samples(m.slip_grid_rpm, rng, 40)
    pressures = samples(m.P_grid_mpa, rng, 20)
    checked = 0
    for T in temps[::3]:
        for slip in slips[::2]:
            for P in pressures:
                for s in (slip, -slip):
                    assert friction_coefficient(m, T, s, P) == plain_mu(m, T, s, P), (T, s, P)
                    checked += 1
    assert checked > 1000
    c: Clutch = cal.CL
    for T, slip, P in ((150.0, 120.0, 0.4), (30.0, -800.0, -0.1), (400.0, 3.0, 2.0)):
        per_mpa = plain_mu(m, T, slip, P) * c.k_geom_m3 * CV.MPA_TO_PA
        assert torque_per_mpa(m, c, T, slip, P) == per_mpa
        p_on = max(P, 0.0)
        assert friction_heat(m, c, T, slip, P) == \
            plain_mu(m, T, slip, p_on) * c.k_geom_m3 * CV.MPA_TO_PA * p_on * abs(slip) * CV.RPM_TO_RAD_S


def test_a_new_map_is_looked_up_anew():
    m = FrictionMap((0.0, 1.0), (0.0, 1.0), (0.0, 1.0), (((0.1, 0.1), (0.1, 0.1)), ((0.1, 0.1), (0.1, 0.1))))
    other = FrictionMap((0.0, 1.0), (0.0, 1.0), (0.0, 1.0), (((0.2, 0.2), (0.2, 0.2)), ((0.2, 0.2), (0.2, 0.2))))
    assert friction_coefficient(m, 0.5, 0.5, 0.5) == 0.1
    assert friction_coefficient(other, 0.5, 0.5, 0.5) == 0.2
    assert friction_coefficient(m, 0.5, 0.5, 0.5) == 0.1


def test_repeated_and_alternating_states_give_each_its_own_mu():
    """The lookup remembers its last two states: asked again, in any order among three, each gets its own value."""
    m = load_calibration().friction
    states = [(150.0, 90.0, 0.4), (150.0, 90.0, 0.41), (151.0, 90.0, 0.4), (150.0, 91.0, 0.4)]
    order = [0, 0, 1, 0, 1, 2, 0, 2, 3, 1, 3, 3, 2, 0]
    assert [friction_coefficient(m, *states[n]) for n in order] == [plain_mu(m, *states[n]) for n in order]
    assert len({plain_mu(m, *state) for state in states}) == len(states)
