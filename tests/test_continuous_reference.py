"""The fixed-step plant (1 ms, exact linear steps, inputs held) against a tight-tolerance solve_ivp solution of
the same equations: plate temperature within 0.1 degC and speeds within 0.5 % over 100 s."""

from __future__ import annotations


import numpy as np
import pytest
from scipy.integrate import solve_ivp

from dsg_hil.continuous import pack, rhs
from dsg_hil.physics.friction import RAD_S_TO_RPM, friction_coefficient, torque_per_mu
from dsg_hil.physics.powertrain import IDX, N_STATE
from dsg_hil.physics.thermal import NODES, gearbox_network, heat_sources
from dsg_hil.plant import Plant, PlantInputs
from dsg_hil.reference import RIG_CASES
from dsg_hil.rig import RigCase, rig_configuration, run_rig

SPEEDS = ("e", "in", "1", "2", "3", "4", "5")


def slipping_vehicle_case(params):
    """Level road, engine held at 2000 r/min, vehicle rolling at 0.5 m/s, CH pressure rising from 0 to 0.4 MPa:
    CH slips for the whole 100 s (governor, hydraulics, friction, heat and vehicle all move). CH, not CL: the
    vehicle's CL is light and barely cooled (Section V.B), so any CL case that keeps slipping 100 s on the
    level overheats it far beyond the range of (6)."""
    plant = Plant(params, T_init=40.0, v_init=0.5)
    inputs = PlantInputs(P_CH_cmd=0.4e6, grade=0.0, brake=0.0, engine_speed_request=2000.0 / RAD_S_TO_RPM)
    return plant, inputs


@pytest.mark.slow
def test_plant_matches_solve_ivp_over_100_s(params):
    plant, inputs = slipping_vehicle_case(params)
    y0 = pack(plant)
    f = rhs(plant, inputs)
    samples = np.arange(1, 101) * 1.0
    got = []
    for k in range(1, 100_001):
        out = plant.step(inputs)
        assert not (out.locked_CH or out.vehicle_held), f"CH locked or vehicle held at {out.t} s"
        if k % 1000 == 0:
            got.append(np.concatenate([plant.state.x[:7], [out.T_CH]]))
    got = np.array(got)
    sol = solve_ivp(f, (0.0, 100.0 + 1e-9), y0, method="Radau", rtol=1e-9, atol=1e-9, t_eval=samples)
    assert sol.success
    ref_speeds = sol.y[:7].T
    ref_T = sol.y[N_STATE + NODES.index("CH")]
    assert ref_T[-1] - ref_T[0] > 30.0  # the case really heats the clutch
    np.testing.assert_allclose(got[:, 7], ref_T, atol=0.1)
    for i, name in enumerate(SPEEDS):
        np.testing.assert_allclose(got[:, i], ref_speeds[:, i], rtol=5e-3, atol=1e-6, err_msg=f"omega_{name}")
    v = got[:, IDX["5"]]
    assert v.max() - v.min() > 0.05  # and really moves the vehicle


@pytest.mark.slow
@pytest.mark.parametrize("ref", RIG_CASES, ids=lambda r: f"case{r.case}")
def test_rig_matches_solve_ivp(params, ref):
    trace = run_rig(params, RigCase(ref.pressure_mpa, ref.speed_rpm), 100.0, 1e-3, 40.0, every=1000)
    rig = rig_configuration(params, 40.0)
    net = gearbox_network(rig)
    P, omega = ref.pressure_mpa * 1e6, ref.speed_rpm / RAD_S_TO_RPM
    k = torque_per_mu(params.clutch.test, P)
    i_CL = NODES.index("CL")

    def f(t, T):
        mu = friction_coefficient(ref.speed_rpm, T[i_CL], ref.pressure_mpa, params.friction)
        return net.derivative(T, heat_sources(rig, mu * k * omega, 0.0, P, 0.0))

    sol = solve_ivp(f, (0.0, 100.0), np.full(len(NODES), 40.0), method="Radau", rtol=1e-10, atol=1e-10,
                    t_eval=trace.t)
    np.testing.assert_allclose(trace.T_CL, sol.y[i_CL], atol=0.1)


@pytest.mark.slow
def test_plate_temperature_through_stick_slip_matches_solve_ivp_with_events(params):
    """CL slips against the vehicle held by the brake, the brake is released at 1 s and the vehicle drives away:
    the plant's plate temperature within 0.1 degC of solve_ivp with stick/slip as events (continuous.solve_hybrid),
    the vehicle held while braked and moving after the release in both."""
    from dsg_hil.continuous import solve_hybrid

    def inputs_at(t):
        return PlantInputs(P_CL_cmd=0.5e6, brake=1.0) if t < 1.0 else PlantInputs(P_CL_cmd=1.0e6)

    samples = np.arange(1, 9) * 0.25
    ref, _ = solve_hybrid(Plant(params, T_init=80.0), inputs_at, [1.0, 2.0], samples, rtol=1e-8)
    plant = Plant(params, T_init=80.0)
    got = []
    for k in range(1, 2001):
        out = plant.step(inputs_at((k - 1) * plant.dt))
        if k % 250 == 0:
            got.append((out.T_CL, out.omega_out))
    got = np.array(got)
    i_CL = N_STATE + NODES.index("CL")
    assert ref[-1, i_CL] - ref[0, i_CL] > 1.0  # the slip really heats the plates
    np.testing.assert_allclose(got[:, 0], ref[:, i_CL], atol=0.1)
    assert np.all(np.abs(ref[:3, IDX["5"]]) < 1e-9) and np.all(np.abs(got[:3, 1]) < 1e-9)  # held while braked
    assert ref[-1, IDX["5"]] > 1.0 and got[-1, 1] > 1.0  # driving away
