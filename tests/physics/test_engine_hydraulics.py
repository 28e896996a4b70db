from __future__ import annotations

import math

import pytest

from dsg_hil.physics.engine import full_load_torque, governor, net_torque
from dsg_hil.physics.hydraulics import clamp_command, pressure_step


def test_governor_limits_and_anti_windup(params):
    e = params.engine
    fuel, d_int = governor(e.omega_idle - 5.0, 0.0, e.omega_idle, e)
    assert fuel == pytest.approx(e.Kp_gov * 5.0) and d_int == pytest.approx(e.Ki_gov * 5.0)
    fuel, d_int = governor(e.omega_idle - 500.0, 1e4, e.omega_idle, e)  # saturated high: integral frozen
    assert fuel == e.M_max and d_int == 0.0
    fuel, d_int = governor(e.omega_idle + 50.0, -1e3, e.omega_idle, e)  # saturated at zero fuel
    assert fuel == 0.0 and d_int == 0.0
    assert net_torque(0.0, e) == -e.M_drag
    assert full_load_torque(1.2 * e.omega_rated, e) == 0.0


def test_pressure_lag_exact_and_clamped(params):
    h = params.hydraulics
    P = pressure_step(0.0, 0.5e6, h.tau, h)
    assert P == pytest.approx(0.5e6 * (1 - math.exp(-1)))
    assert pressure_step(0.0, 9e6, 10.0, h) == pytest.approx(h.P_max)
    assert clamp_command(-1.0, h) == 0.0
    assert clamp_command(float("nan"), h) == 0.0  # a garbled command opens the clutch
    assert pressure_step(1e6, 0.0, 1.0, h) == pytest.approx(1e6 * math.exp(-1.0 / h.tau))


def test_relax_with_its_decay_is_the_step(params):
    """The plant's loop computes each decay exp(-dt / tau) once: the same values bit for bit as the steps."""
    from dsg_hil.physics.friction import slip_memory_relax, slip_memory_step
    from dsg_hil.physics.hydraulics import pressure_relax

    h, f, dt = params.hydraulics, params.friction, 1e-3
    for P, P_cmd in ((0.0, 0.5e6), (4e5, 1e5), (1e6, float("nan")), (0.0, 9e9)):
        assert pressure_relax(P, P_cmd, math.exp(-dt / h.tau), h) == pressure_step(P, P_cmd, dt, h)
    for memory, slip in ((0.0, 30.0), (12.0, -3.0), (5.0, 0.0)):
        relaxed = slip_memory_relax(memory, slip, math.exp(-dt / f.tau_slip))
        assert relaxed == slip_memory_step(memory, slip, dt, f)
        assert relaxed == pytest.approx(abs(slip) + (memory - abs(slip)) * math.exp(-dt / f.tau_slip), rel=1e-15)
