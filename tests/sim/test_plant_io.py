"""The plant's CAN edge: one table (SIGNALS) of what each signal the plant sends or reads is in SI, checked against
the DBC, and the encoder written out from it."""

from __future__ import annotations

import math
import random

import pytest

from dsg_hil.physics.plant import PlantOutputs
from dsg_hil.protocol import load_dbc
from dsg_hil.protocol.e2e import COUNTER, CRC
from dsg_hil.sim.plant_io import (LOCKSTEP, PLANT_RX, PLANT_TX, PLANT_USES, SIGNALS, commanded_pressures,
                                  encoder_source, plant_signals)
from dsg_hil.sim.scenario import DriverInput

# The DBC's unit of a signal -> SI per that unit, by hand
PER_UNIT = {"rpm": 2 * math.pi / 60, "MPa": 1e6, "%": 0.01}


def test_the_table_covers_every_signal_the_plant_sends_and_reads():
    db = load_dbc()
    for name, signals in PLANT_USES.items():
        in_dbc = {s.name for s in db.get_message_by_name(name).signals} - {COUNTER, CRC}
        assert set(signals) == in_dbc, name  # the plant names every signal of its messages
        for signal in signals:
            assert ((name, signal) in SIGNALS) != ((name, signal) in LOCKSTEP), (name, signal)
    assert {message for message, _ in SIGNALS} <= set(PLANT_USES)


def test_each_factor_is_the_dbc_units_si_factor():
    db = load_dbc()
    for (message, signal), (_, factor) in SIGNALS.items():
        unit = db.get_message_by_name(message).get_signal_by_name(signal).unit
        assert factor == pytest.approx(PER_UNIT.get(unit, 1.0), rel=1e-15), (message, signal, unit)


def test_what_the_plant_sends_are_its_outputs_and_the_drivers_input():
    driver = set(DriverInput.__dataclass_fields__)
    for message, signals in PLANT_TX.items():
        for signal in signals:
            quantity = SIGNALS[message, signal][0]
            assert quantity in (driver if message == "DRIVER" else PlantOutputs._fields), (message, signal)
    quantities = [SIGNALS[key][0] for key in SIGNALS]
    assert len(set(quantities)) == len(quantities)  # one signal per quantity


def outputs(rng: random.Random) -> PlantOutputs:
    values = [rng.uniform(0.0, 2e6) if name in ("P_CL", "P_CH") else rng.uniform(-300.0, 300.0)
              for name in PlantOutputs._fields]
    return PlantOutputs._make(values)


def test_the_encoder_converts_by_hand_and_as_the_plant_always_did():
    """Hand values, and bit for bit the operations the plant's encoder was written with before the table (the
    frames of a run stay the same)."""
    out = PlantOutputs(*([0.0] * len(PlantOutputs._fields)))._replace(omega_e=100.0, P_CL=0.5e6, M_CL=42.0)
    values = plant_signals(out, DriverInput(0.0, True, 0.25, 0.2))
    assert values["PLANT_ENGINE"]["EngineSpeed"] == pytest.approx(954.9296585513721)
    assert values["PLANT_PRESSURE"]["P_CL"] == 0.5 and values["SIM_TRUTH_CL"]["Torque"] == 42.0
    assert values["DRIVER"] == {"CreepRequest": 1.0, "BrakePedal": 25.0, "DesiredCreepSpeed": 0.2}
    assert set(values) == set(PLANT_TX) and all(set(values[m]) == set(s) for m, s in PLANT_TX.items())
    rng = random.Random(15)
    for _ in range(2000):
        out, brake = outputs(rng), rng.random()
        values = plant_signals(out, DriverInput(0.0, False, brake, 0.2))
        assert values["PLANT_SPEEDS"]["ClutchInputSpeed"] == out.omega_in * (60.0 / (2.0 * math.pi))
        assert values["PLANT_VEHICLE"]["TransOutputSpeed"] == out.omega_out * (60.0 / (2.0 * math.pi))
        assert values["PLANT_PRESSURE"]["P_CH"] == out.P_CH / 1e6
        assert values["DRIVER"]["BrakePedal"] == brake * 100.0
        assert values["SIM_HEAT"]["HeatDissCH"] == out.Q_diss_CH


def test_the_encoders_source_inlines_the_tables_constants():
    source = encoder_source()
    assert "out.omega_e * 9.549296585513721" in source and "out.P_CL / 1000000.0" in source
    assert "float(driver.creep_request)" in source  # a bool, sent as a number


def test_commanded_pressures_in_pa():
    assert commanded_pressures({"P_CL_Cmd": 0.55, "P_CH_Cmd": 1.2, "SyncEcho": 3.0}) == (0.55 * 1e6, 1.2 * 1e6)
    assert ("TCU_CMD", "P_CL_Cmd") in SIGNALS and "P_CL_Cmd" in PLANT_RX["TCU_CMD"]
