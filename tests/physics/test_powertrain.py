"""Torsional model (7)-(17): structure, stability, constraints, and the static load by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dsg_hil.physics.powertrain import (
    IDX,
    N_DOF,
    brake_for_decel,
    build_model,
    discretize,
    holding_torque,
    road_load,
    solve_contacts,
    solve_contacts_into,
)


def test_vehicle_inertia_moved_to_the_left_hand_side(params):
    pt, veh = params.powertrain, params.vehicle
    model = build_model(pt, veh)
    translational = veh.delta * veh.m * veh.r_w**2
    assert translational == pytest.approx(310.0, rel=0.01)
    assert model.J[IDX["5"]] == pytest.approx(pt.I_5 + (pt.I_R + translational) / pt.i_b**2)


def test_linear_model_is_stable(params):
    dm = discretize(build_model(params.powertrain, params.vehicle), 1e-3)
    assert np.abs(np.linalg.eigvals(dm.Phi)).max() <= 1.0 + 1e-9


def test_state_integral_matches_fine_steps(params):
    """Phi_int, Gamma_int give the exact integral of the state over the step."""
    model = build_model(params.powertrain, params.vehicle)
    dm, fine = discretize(model, 1e-3), discretize(model, 1e-6)
    rng = np.random.default_rng(4)
    x = np.concatenate([rng.uniform(0, 20, N_DOF), rng.uniform(-1e-4, 1e-4, 5)])
    u = np.array([100.0, 300.0, 200.0, 4000.0])
    integral = dm.Phi_int @ x + dm.Gamma_int @ u
    acc = np.zeros_like(x)
    for _ in range(1000):
        acc += fine.Phi_int @ x + fine.Gamma_int @ u
        x = fine.Phi @ x + fine.Gamma @ u
    np.testing.assert_allclose(integral, acc, rtol=1e-8, atol=1e-13)


ONES = np.ones(3)  # v_ramp: unused where limit = cap (Coulomb friction)


@pytest.mark.slow
def test_contacts_stick_when_they_can_and_slip_at_capacity_otherwise():
    W = np.array([[-0.1, -0.005, 0.0], [-0.005, -0.04, 0.0], [0.0, 0.0, -1e-4]])
    v_free = np.array([2.0, -1.0, 0.3])
    big = np.array([1e6, 1e6, 1e6])
    f = np.array(solve_contacts(v_free, W, big, big, ONES, np.zeros(3)))
    np.testing.assert_allclose(v_free + W @ f, 0.0, atol=1e-6)  # all stick
    small = np.array([5.0, 5.0, 100.0])
    f = np.array(solve_contacts(v_free, W, small, small, ONES, np.zeros(3)))
    v = v_free + W @ f
    assert f[0] == 5.0 and v[0] > 0.0  # slips forward at capacity, slip not reversed
    assert f[1] == -5.0 and v[1] < 0.0
    assert f[2] == 100.0 and v[2] > 0.0
    no_capacity = np.zeros(3)
    assert solve_contacts(v_free, W, no_capacity, no_capacity, ONES, np.ones(3)).tolist() == [0.0, 0.0, 0.0]


def test_contacts_solved_in_place_as_into_a_new_array():
    """solve_contacts_into (the plant's step) starts from f and leaves the same torques in it as solve_contacts."""
    W = np.array([[-0.1, -0.005, 0.0], [-0.005, -0.04, 0.0], [0.0, 0.0, -1e-4]])
    v_free, cap, f0 = np.array([2.0, -1.0, 0.3]), np.array([50.0, 5.0, 1e4]), np.array([60.0, -1.0, 0.0])
    f = f0.copy()
    solve_contacts_into(v_free, W, cap, cap, ONES, f)
    assert f.tolist() == solve_contacts(v_free, W, cap, cap, ONES, f0).tolist() and f0.tolist() == [60.0, -1.0, 0.0]
    assert f[1] == -5.0  # CH slips backward at capacity; CL sticks (CH's torque coupled in), the vehicle held
    assert f[0] == pytest.approx((2.0 + 0.005 * 5.0) / 0.1, rel=1e-9) and f[2] == pytest.approx(3000.0, rel=1e-9)


def test_a_ramp_adds_torque_in_proportion_to_the_slip_up_to_its_speed():
    """Contact 2 holds up to cap; slipping, its torque rises linearly with |v| from cap to limit at v_ramp (solved
    with v)."""
    W = np.array([[-0.1, 0.0, 0.0], [0.0, -0.04, 0.0], [0.0, 0.0, -1e-3]])
    cap, limit, v_ramp = np.array([1e6, 1e6, 100.0]), np.array([1e6, 1e6, 1100.0]), np.array([1.0, 1.0, 2.0])
    held = solve_contacts(np.array([0.0, 0.0, 0.05]), W, cap, limit, v_ramp, np.zeros(3))
    assert held[2] == pytest.approx(50.0)  # 0.05 rad/s stopped by 50 N m < cap: it sticks
    # v_free 0.6: slipping, v = 0.6 - 1e-3 f with f = 100 + 1000 v / 2  ->  v = 0.5 / 1.5, f = 100 + 500 / 3
    f = solve_contacts(np.array([0.0, 0.0, 0.6]), W, cap, limit, v_ramp, np.zeros(3))
    assert f[2] == pytest.approx(100.0 + 500.0 / 3.0) and 0.6 - 1e-3 * f[2] == pytest.approx(1.0 / 3.0)
    # v_free 5: past v_ramp, the full cap + ramp
    assert solve_contacts(np.array([0.0, 0.0, -5.0]), W, cap, limit, v_ramp, np.zeros(3))[2] == -1100.0


def test_holding_torque_is_the_breakaway_resistance_plus_the_brake(params):
    veh = params.vehicle
    assert holding_torque(0.08, 0.0, veh) == pytest.approx(7840 * 9.81 * veh.f_breakaway * math.cos(0.08) * 0.1935)
    assert holding_torque(0.0, 0.5, veh) == pytest.approx(7840 * 9.81 * veh.f_breakaway * 0.1935
                                                          + 0.5 * veh.M_brake_max)
    assert holding_torque(0.08, 0.0, veh) < road_load(0.0, 0.08, 0.0, veh)[1]


def test_a_deceleration_request_brakes_this_vehicle_by_that_much(params):
    """By hand (Table I: 7840 kg, r_w 0.1935 m, M_brake_max 40 kN m): 0.5 m/s^2 is 7840 x 0.5 x 0.1935 = 758.5 N m
    at the wheels, 0.01896 of the brake; none or less brakes nothing; beyond the brake's torque, all of it."""
    veh = params.vehicle
    assert brake_for_decel(0.5, veh) == pytest.approx(7840 * 0.5 * 0.1935 / 40000.0, rel=1e-12)
    assert brake_for_decel(0.5, veh) * veh.M_brake_max / veh.r_w / veh.m == pytest.approx(0.5)  # F = m a
    assert brake_for_decel(0.0, veh) == brake_for_decel(-1.0, veh) == 0.0
    assert brake_for_decel(40000.0 / (7840 * 0.1935), veh) == pytest.approx(1.0)
    assert brake_for_decel(100.0, veh) == 1.0


def test_exact_step_matches_fine_rk4(params):
    """One 1-ms exact step equals RK4 at 1 us over the same millisecond (inputs held)."""
    model = build_model(params.powertrain, params.vehicle)
    dm = discretize(model, 1e-3)
    rng = np.random.default_rng(3)
    x0 = np.concatenate([rng.uniform(0, 20, N_DOF), rng.uniform(-1e-4, 1e-4, 5)])
    u = np.array([100.0, 300.0, 200.0, 4000.0])
    x, h = x0.copy(), 1e-6
    for _ in range(1000):
        k1 = model.derivative(x, u)
        k2 = model.derivative(x + h / 2 * k1, u)
        k3 = model.derivative(x + h / 2 * k2, u)
        k4 = model.derivative(x + h * k3, u)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    np.testing.assert_allclose(dm.Phi @ x0 + dm.Gamma @ u, x, rtol=1e-9, atol=1e-12)


def test_road_load_by_hand(params):
    veh = params.vehicle
    fixed, resist = road_load(1.0, 0.174, 0.0, veh)
    air = 0.5 * 1.2 * 0.62 * 3.6 * 1.0
    assert fixed == pytest.approx((air + 7840 * 9.81 * math.sin(0.174)) * 0.1935)
    assert resist == pytest.approx(7840 * 9.81 * 0.123 * math.cos(0.174) * 0.1935)
    _, braked = road_load(0.0, 0.0, 1.0, veh)
    assert braked == pytest.approx(7840 * 9.81 * 0.123 * 0.1935 + veh.M_brake_max)


def test_the_contact_law_acts_on_the_clutches_mean_slips_and_the_vehicles_end_speed(params):
    """law_rows (issue 16): rows 0, 1 the clutches' slips averaged over the step (the exact integral / dt), row 2
    shaft III's speed at the step's end; W their response to the friction torques (M_CL, M_CH, M_R)."""
    from dsg_hil.physics.powertrain import CONTACT_INPUTS, contact_velocities

    dm = discretize(build_model(params.powertrain, params.vehicle), 1e-3)
    V = contact_velocities()
    rng = np.random.default_rng(5)
    x = np.concatenate([rng.uniform(0, 20, N_DOF), rng.uniform(-1e-4, 1e-4, 5)])
    u = np.array([100.0, 300.0, 200.0, 4000.0])
    v = dm.L_x @ x + dm.L_u @ u
    np.testing.assert_allclose(v[:2], V[:2] @ (dm.Phi_int @ x + dm.Gamma_int @ u) / 1e-3, rtol=1e-12)
    assert v[2] == pytest.approx((dm.Phi @ x + dm.Gamma @ u)[IDX["5"]], rel=1e-12)
    np.testing.assert_array_equal(dm.W, dm.L_u[:, list(CONTACT_INPUTS)])
    assert np.all(np.diag(dm.W) < 0.0)  # each friction torque slows its own contact
