"""Thermal network (1)-(4): exact steps against hand solutions, energy conservation, the oil circuit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dsg_hil.physics.thermal import (NODES, NetworkBuilder, clutch_element, discretize, gearbox_network,
                                     heat_sources)


def test_single_node_step_is_exact():
    """C dT/dt = Q - g (T - T_E): T(t) = T_E + Q/g (1 - exp(-g t / C)) from T_E."""
    b = NetworkBuilder(("a",), T_E=20.0)
    b.capacity("a", 1400.0)
    b.conductance("a", "E", 50.0)
    disc = discretize(b.build(), 0.5)
    T = np.array([20.0])
    for _ in range(40):
        T = disc.step(T, np.array([1000.0]))
    assert T[0] == pytest.approx(20.0 + 1000.0 / 50.0 * (1 - math.exp(-50.0 * 20.0 / 1400.0)), rel=1e-12)


def test_two_node_steady_state_by_hand():
    """Plate -> oil -> E in series: T_plate = T_E + Q (1/K + 1/g) at steady state."""
    b = NetworkBuilder(("p", "o"), T_E=25.0)
    b.capacity("p", 1400.0)
    b.capacity("o", 170.0)
    b.conductance("p", "o", 150.0)
    b.conductance("o", "E", 113.0)
    disc = discretize(b.build(), 1.0)
    T = np.array([25.0, 25.0])
    for _ in range(2000):
        T = disc.step(T, np.array([4000.0, 0.0]))
    assert T[0] == pytest.approx(25.0 + 4000.0 * (1 / 150.0 + 1 / 113.0), rel=1e-9)
    assert T[1] == pytest.approx(25.0 + 4000.0 / 113.0, rel=1e-9)


def test_advection_carries_heat_downstream_only():
    b = NetworkBuilder(("up", "down"), T_E=0.0)
    b.capacity("up", 100.0)
    b.capacity("down", 100.0)
    b.flow("up", "down", 10.0)
    b.flow("down", "up", 10.0)  # closed loop
    net = b.build()
    dT = net.derivative(np.array([50.0, 30.0]), np.zeros(2))
    assert dT[1] == pytest.approx(10.0 * (50.0 - 30.0) / 100.0)
    assert dT[0] == pytest.approx(10.0 * (30.0 - 50.0) / 100.0)
    assert net.C @ dT == pytest.approx(0.0)


def test_gearbox_network_conserves_energy(params):
    """sum C dT/dt = sum q - heat to E, for any temperatures: the oil loop neither makes nor loses heat."""
    net = gearbox_network(params)
    rng = np.random.default_rng(1)
    for _ in range(20):
        T = rng.uniform(20.0, 250.0, len(NODES))
        q = rng.uniform(0.0, 5000.0, len(NODES))
        assert net.C @ net.derivative(T, q) == pytest.approx(q.sum() - net.heat_to_environment(T), rel=1e-10)


def test_uniform_temperature_at_environment_is_a_steady_state(params):
    net = gearbox_network(params)
    T = np.full(len(NODES), params.thermal.T_E)
    np.testing.assert_allclose(net.derivative(T, np.zeros(len(NODES))), 0.0, atol=1e-12)


def test_clutch_conductance_from_geometry(params):
    e = clutch_element(params.clutch.test, params.thermal.clutch.test)
    assert e.K_io == pytest.approx(params.thermal.clutch.test.h_plate_oil * 2 * math.pi * (0.125**2 - 0.086**2))
    assert e.C == params.clutch.test.C_plate and e.V_o == params.thermal.clutch.test.V_o


def test_hydraulic_sources_turn_all_pump_power_into_heat(params):
    c = params.circuit
    q = heat_sources(params, 1000.0, 2000.0, 0.5e6, 0.7e6)
    assert q[NODES.index("CL")] == 1000.0 and q[NODES.index("CH")] == 2000.0
    assert q[NODES.index("CLo")] == pytest.approx(params.thermal.clutch.CL.Q_cool * 0.5e6)
    assert q[NODES.index("CHo")] == pytest.approx(params.thermal.clutch.CH.Q_cool * 0.7e6)
    assert q.sum() - 3000.0 == pytest.approx(c.Q_pump * c.p_line / c.eta_pump)


def test_discretize_rejects_bad_step(params):
    with pytest.raises(ValueError):
        discretize(gearbox_network(params), 0.0)


def _without_clutch_losses(params):
    """The parameters with clutch CL's paths to E removed, so its steady state is a hand calculation."""
    from dataclasses import replace
    cool = params.thermal.clutch
    CL = replace(cool.CL, K_iE=0.0, K_oE=0.0)
    return replace(params, thermal=replace(params.thermal, clutch=replace(cool, CL=CL)))


def test_clutch_steady_state_by_hand(params):
    """Heat Q into CL's plates leaves only with its own cooling flow: at steady state the oil leaving CL is
    Q / (rho c_p Q_cool) above the valve's oil, and the plates Q / K_io above their oil ((2)-(3), K_iE = K_oE = 0)."""
    p = _without_clutch_losses(params)
    net = gearbox_network(p)
    disc = discretize(net, 50.0)
    T = np.full(len(NODES), p.thermal.T_E)
    q = heat_sources(p, 2000.0, 0.0, 0.0, 0.0)
    for _ in range(4000):
        T = disc.step(T, q)
    np.testing.assert_allclose(net.derivative(T, q), 0.0, atol=1e-9)
    cool = p.thermal.clutch.CL
    W = p.oil.rho * p.oil.c_p * cool.Q_cool
    K_io = clutch_element(p.clutch.CL, cool).K_io
    i = {n: NODES.index(n) for n in ("CL", "CLo", "Vo")}
    assert T[i["CLo"]] - T[i["Vo"]] == pytest.approx(2000.0 / W, rel=1e-6)
    assert T[i["CL"]] - T[i["CLo"]] == pytest.approx(2000.0 / K_io, rel=1e-6)


def test_each_clutch_has_its_own_cooling_flow(params):
    """The flow terms of L: CL's oil takes m_dot c_p Q_cool,CL from V's oil, CH's its own; the rest bypasses to R."""
    net = gearbox_network(params)
    W = params.oil.rho * params.oil.c_p
    i = {n: NODES.index(n) for n in ("Vo", "CLo", "CHo", "Ro")}
    assert -net.L[i["CLo"], i["Vo"]] == pytest.approx(W * params.thermal.clutch.CL.Q_cool)
    assert -net.L[i["CHo"], i["Vo"]] == pytest.approx(W * params.thermal.clutch.CH.Q_cool)
    c = params.circuit
    bypass = c.Q_pump - c.Q_relief - params.thermal.clutch.CL.Q_cool - params.thermal.clutch.CH.Q_cool
    assert -net.L[i["Ro"], i["Vo"]] == pytest.approx(W * bypass)
