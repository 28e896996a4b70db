"""Torsional model (7)-(17): structure, stability, constraints, and the static load by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dsg_hil.physics.powertrain import (
    IDX,
    N_DOF,
    build_model,
    discretize,
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


def test_contacts_stick_when_they_can_and_slip_at_capacity_otherwise():
    W = np.array([[-0.1, -0.005, 0.0], [-0.005, -0.04, 0.0], [0.0, 0.0, -1e-4]])
    v_free = np.array([2.0, -1.0, 0.3])
    big = np.array([1e6, 1e6, 1e6])
    f = np.array(solve_contacts(v_free, W, big, np.zeros(3)))
    np.testing.assert_allclose(v_free + W @ f, 0.0, atol=1e-6)  # all stick
    small = np.array([5.0, 5.0, 100.0])
    f = np.array(solve_contacts(v_free, W, small, np.zeros(3)))
    v = v_free + W @ f
    assert f[0] == 5.0 and v[0] > 0.0  # slips forward at capacity, slip not reversed
    assert f[1] == -5.0 and v[1] < 0.0
    assert f[2] == 100.0 and v[2] > 0.0
    assert solve_contacts(v_free, W, np.zeros(3), np.ones(3)).tolist() == [0.0, 0.0, 0.0]  # no capacity, no torque


def test_contacts_solved_in_place_as_into_a_new_array():
    """solve_contacts_into (the plant's step) starts from f and leaves the same torques in it as solve_contacts."""
    W = np.array([[-0.1, -0.005, 0.0], [-0.005, -0.04, 0.0], [0.0, 0.0, -1e-4]])
    v_free, cap, f0 = np.array([2.0, -1.0, 0.3]), np.array([50.0, 5.0, 1e4]), np.array([60.0, -1.0, 0.0])
    f = f0.copy()
    solve_contacts_into(v_free, W, cap, f)
    assert f.tolist() == solve_contacts(v_free, W, cap, f0).tolist() and f0.tolist() == [60.0, -1.0, 0.0]
    assert f[1] == -5.0  # CH slips backward at capacity; CL sticks (CH's torque coupled in), the vehicle held
    assert f[0] == pytest.approx((2.0 + 0.005 * 5.0) / 0.1, rel=1e-9) and f[2] == pytest.approx(3000.0, rel=1e-9)


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
