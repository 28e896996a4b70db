"""The binding (dsg_hil.protocol.binding): the shipped DBC's binding gives the plant's tables as they were written
by hand, so the shipped pair's frames stay the same bit for bit; a binding that does not fit its DBC fails with one
line naming the file and the key."""

from __future__ import annotations

import itertools
from pathlib import Path

import can
import pytest

from dsg_hil.common.units import CV
from dsg_hil.physics.params import load_params
from dsg_hil.physics.plant import Plant
from dsg_hil.protocol import Codec, RxMonitor, load_dbc
from dsg_hil.protocol.binding import DEFAULT_BINDING, BindingError, check_binding, conversion, load_binding
from dsg_hil.sim.plant_io import SHIPPED, PlantIO, from_binding
from dsg_hil.sim.runner import PlantRunner
from dsg_hil.sim.scenario import load_scenario
from ecu_stub.runner import TCU_USES, TcuRunner

_RPM, _MPA, _PERCENT = CV.RPM_TO_RAD_S, CV.MPA_TO_PA, CV.PERCENT_TO_FRACTION
# The plant's tables as dsg_hil/sim/plant_io.py wrote them by hand before the binding (order included: it is the
# order of a period's frames and of each message's signals)
HAND_TX = {
    "PLANT_ENGINE": ("EngineSpeed", "EngineTorque"),
    "PLANT_SPEEDS": ("ClutchInputSpeed", "CLOutputSpeed", "CHOutputSpeed"),
    "PLANT_VEHICLE": ("TransOutputSpeed", "VehicleSpeed", "LongAccel"),
    "PLANT_PRESSURE": ("P_CL", "P_CH"),
    "PLANT_OIL_TEMP": ("T_OilCL", "T_OilCH", "T_Sump", "T_RadiatorOut"),
    "DRIVER": ("CreepRequest", "BrakePedal", "DesiredCreepSpeed"),
    "SIM_TRUTH_CL": ("T_Plate", "Mu", "Torque", "HeatFlux"),
    "SIM_TRUTH_CH": ("T_Plate", "Mu", "Torque", "HeatFlux"),
    "SIM_HEAT": ("HeatDissCL", "HeatDissCH"),
}
HAND_RX = {
    "TCU_CMD": ("P_CL_Cmd", "P_CH_Cmd", "SyncEcho", "DecelRequest"),
    "TCU_STATUS": ("State", "ActiveClutch", "BrakeRequest", "T_CL_Pred", "T_CH_Pred", "FaultBits"),
}
HAND_SIGNALS = {
    ("PLANT_ENGINE", "EngineSpeed"): ("omega_e", _RPM), ("PLANT_ENGINE", "EngineTorque"): ("M_e", 1.0),
    ("PLANT_SPEEDS", "ClutchInputSpeed"): ("omega_in", _RPM), ("PLANT_SPEEDS", "CLOutputSpeed"): ("omega_CL", _RPM),
    ("PLANT_SPEEDS", "CHOutputSpeed"): ("omega_CH", _RPM),
    ("PLANT_VEHICLE", "TransOutputSpeed"): ("omega_out", _RPM), ("PLANT_VEHICLE", "VehicleSpeed"): ("v", 1.0),
    ("PLANT_VEHICLE", "LongAccel"): ("a_x", 1.0),
    ("PLANT_PRESSURE", "P_CL"): ("P_CL", _MPA), ("PLANT_PRESSURE", "P_CH"): ("P_CH", _MPA),
    ("PLANT_OIL_TEMP", "T_OilCL"): ("T_oil_CL", 1.0), ("PLANT_OIL_TEMP", "T_OilCH"): ("T_oil_CH", 1.0),
    ("PLANT_OIL_TEMP", "T_Sump"): ("T_sump", 1.0), ("PLANT_OIL_TEMP", "T_RadiatorOut"): ("T_radiator_out", 1.0),
    ("DRIVER", "CreepRequest"): ("creep_request", 1.0), ("DRIVER", "BrakePedal"): ("brake", _PERCENT),
    ("DRIVER", "DesiredCreepSpeed"): ("desired_speed_mps", 1.0),
    ("SIM_TRUTH_CL", "T_Plate"): ("T_CL", 1.0), ("SIM_TRUTH_CL", "Mu"): ("mu_CL", 1.0),
    ("SIM_TRUTH_CL", "Torque"): ("M_CL", 1.0), ("SIM_TRUTH_CL", "HeatFlux"): ("Q_CL", 1.0),
    ("SIM_TRUTH_CH", "T_Plate"): ("T_CH", 1.0), ("SIM_TRUTH_CH", "Mu"): ("mu_CH", 1.0),
    ("SIM_TRUTH_CH", "Torque"): ("M_CH", 1.0), ("SIM_TRUTH_CH", "HeatFlux"): ("Q_CH", 1.0),
    ("SIM_HEAT", "HeatDissCL"): ("Q_diss_CL", 1.0), ("SIM_HEAT", "HeatDissCH"): ("Q_diss_CH", 1.0),
    ("TCU_CMD", "P_CL_Cmd"): ("P_CL_cmd", _MPA), ("TCU_CMD", "P_CH_Cmd"): ("P_CH_cmd", _MPA),
    ("TCU_CMD", "DecelRequest"): ("decel_request", 1.0),
    ("TCU_STATUS", "State"): ("tcu_state", 1.0), ("TCU_STATUS", "ActiveClutch"): ("active_clutch", 1.0),
    ("TCU_STATUS", "BrakeRequest"): ("brake_request", 1.0), ("TCU_STATUS", "T_CL_Pred"): ("T_CL_pred", 1.0),
    ("TCU_STATUS", "T_CH_Pred"): ("T_CH_pred", 1.0), ("TCU_STATUS", "FaultBits"): ("fault_bits", 1.0),
}
HAND = PlantIO(HAND_TX, HAND_RX, HAND_SIGNALS, ("SIM_SYNC", "Tick"), ("TCU_CMD", "SyncEcho"))
_channels = itertools.count()


def test_the_shipped_binding_gives_the_tables_written_by_hand():
    binding = load_binding()
    assert binding.tx == HAND_TX and list(binding.tx) == list(HAND_TX)
    assert binding.rx == HAND_RX and list(binding.rx) == list(HAND_RX)
    assert list(binding.signals.items()) == list(HAND_SIGNALS.items())  # the factors to the last bit, in order
    assert binding.offsets == {} and binding.protection == {} and binding.cycle_times_ms == {}
    assert (SHIPPED.sync, SHIPPED.tick, SHIPPED.command, SHIPPED.echo, SHIPPED.status) == (
        "SIM_SYNC", "Tick", "TCU_CMD", "SyncEcho", "TCU_STATUS")
    assert SHIPPED.encoder_source() == HAND.encoder_source()


def lockstep_frames(io: PlantIO, db, duration: float = 1.0) -> list[tuple[float, int, bytes]]:
    """The plant's log of the shipped creep's first ``duration`` s in lock-step against ecu-stub in this process."""
    channel = f"binding-{next(_channels)}"
    plant_bus, tcu_bus = can.Bus(interface="virtual", channel=channel), can.Bus(interface="virtual", channel=channel)
    frames: list[tuple[float, int, bytes]] = []
    runner = PlantRunner(Plant(load_params()), load_scenario().with_duration(duration), Codec(db, io.uses),
                         plant_bus, listeners=(lambda m: frames.append((m.timestamp, m.arbitration_id,
                                                                        bytes(m.data))),), io=io)
    tcu = TcuRunner(Codec(load_dbc(), TCU_USES), tcu_bus)
    try:
        runner.run_lockstep(reply_timeout=5.0, pump=tcu.pump, startup_timeout=5.0)
    finally:
        plant_bus.shutdown()
        tcu_bus.shutdown()
    return frames


def test_the_shipped_binding_runs_the_frames_of_the_hand_written_tables():
    """Bit for bit: the plant's frames (sent and taken, with their times) from the binding's I/O and from the
    tables written by hand."""
    shipped = lockstep_frames(from_binding(load_binding(str(DEFAULT_BINDING))), load_dbc())
    assert len(shipped) > 500
    assert shipped == lockstep_frames(HAND, load_dbc())


@pytest.mark.parametrize("signal_unit, quantity_unit, expected", [
    ("rpm", "rad/s", (CV.RPM_TO_RAD_S, 0.0)), ("MPa", "Pa", (1e6, 0.0)), ("%", "1", (0.01, 0.0)),
    ("km/h", "m/s", (1 / 3.6, 0.0)), ("K", "degC", (1.0, -273.15)), ("degC", "degC", (1.0, 0.0)),
    ("-", "1", (1.0, 0.0)), ("bar", "Pa", (1e5, 0.0)),
    ("rpm", "Pa", None), ("furlong", "m/s", None), ("degC", "m/s", None),
])
def test_unit_conversions(signal_unit, quantity_unit, expected):
    assert conversion(signal_unit, quantity_unit) == expected


SHIPPED_TEXT = DEFAULT_BINDING.read_text(encoding="utf-8")


@pytest.mark.parametrize("change, message", [
    (('omega_e = "PLANT_ENGINE.EngineSpeed"', 'omega_e = "PLANT_ENGINE.EngineSped"'),
     "quantities.omega_e: signal PLANT_ENGINE.EngineSped is not in the database"),
    (('omega_e = "PLANT_ENGINE.EngineSpeed"', 'omega_e = "PLANT_ENGIN.EngineSpeed"'),
     "quantities.omega_e: message PLANT_ENGIN is not in the database"),
    (('omega_e = "PLANT_ENGINE.EngineSpeed"', 'omega_e = "EngineSpeed"'),
     "quantities.omega_e must be \"MESSAGE.Signal\""),
    (('omega_e = "PLANT_ENGINE.EngineSpeed"', 'omega_e = { signal = "PLANT_ENGINE.EngineSpeed", unit = "MPa" }'),
     "quantities.omega_e: unit 'MPa' of PLANT_ENGINE.EngineSpeed does not convert to rad/s"),
    (('P_CL_cmd = "TCU_CMD.P_CL_Cmd"\n', ''), "quantities: P_CL_cmd is not mapped (the plant needs it)"),
    (('M_e = "PLANT_ENGINE.EngineTorque"', 'M_ee = "PLANT_ENGINE.EngineTorque"'),
     "quantities.M_ee: not a quantity of the plant"),
    (('M_e = "PLANT_ENGINE.EngineTorque"', 'M_e = "PLANT_ENGINE.EngineSpeed"'),
     "quantities.M_e: signal PLANT_ENGINE.EngineSpeed carries another quantity already"),
    (('decel_request = "TCU_CMD.DecelRequest"', 'decel_request = { signal = "TCU_STATUS.FaultBits", unit = "m/s2" }',
      'fault_bits = "TCU_STATUS.FaultBits"\n', ''),
     "quantities.decel_request: must be in TCU_CMD"),
    (('omega_e = "PLANT_ENGINE.EngineSpeed"', 'omega_e = "TCU_CMD.DecelRequest"'),
     "quantities.omega_e: message TCU_CMD is not in send"),
    (('read = ["TCU_CMD", "TCU_STATUS"]', 'read = ["TCU_STATUS"]'),
     "lockstep.echo: message TCU_CMD is not one the plant reads"),
    (('echo = "TCU_CMD.SyncEcho"', ''), "lockstep must be a table with tick and echo"),
    (('send = [', 'speed = 3\nsend = ['), "unknown key 'speed'"),
    (('[quantities]', '[messages.TCU_CMD]\nprotection = { profile = "P05", data_id = 0x1234 }\n[quantities]'),
     "messages.TCU_CMD.protection: TCU_CMD: signal P_CH_Cmd lies partly in the P05 counter field"),
    (('[quantities]', '[messages.TCU_CMD]\ncycle_time_ms = 0\n[quantities]'),
     "messages.TCU_CMD.cycle_time_ms must be a whole number of ms above 0, got 0"),
    (('[quantities]', '[messages.TCU_CMD]\nprotection = { profile = "P05" }\n[quantities]'),
     "messages.TCU_CMD.protection: TCU_CMD: protection data_id is missing"),
    (('[quantities]', '[messages.SIM_SYNC]\ntimeout_ms = 30\n[quantities]'),
     "messages.SIM_SYNC.timeout_ms: the lock-step tick has no receive timeout"),
    (('[quantities]', '[messages.TCU_CMD]\ntimeout_ms = 2.5\n[quantities]'),
     "messages.TCU_CMD.timeout_ms must be a whole number of ms above 0, got 2.5"),
    (('[quantities]', '[messages.NOPE]\ncycle_time_ms = 10\n[quantities]'),
     "messages.NOPE: not a message the plant sends or reads"),
    (('send = [', 'send = ["NOPE", '), "send: message NOPE is not in the database"),
    (('send = [', 'send = 3 #'), "not TOML"),
])
def test_a_bad_binding_fails_naming_the_file_and_key(tmp_path: Path, change, message):
    text = SHIPPED_TEXT
    for old, new in zip(change[::2], change[1::2]):  # (old, new, old, new ...)
        assert old in text
        text = text.replace(old, new, 1)
    path = tmp_path / "bad.binding.toml"
    path.write_text(text, encoding="utf-8")
    binding, problems = check_binding(path)
    assert binding is None and any(message in line for line in problems), problems
    assert all(line.startswith(f"{path}: ") and "\n" not in line for line in problems), problems
    with pytest.raises(BindingError) as caught:
        load_binding(path)
    assert str(caught.value) == problems[0]


def test_a_missing_binding_file(tmp_path: Path):
    with pytest.raises(BindingError, match="nope.toml: binding file not found"):
        load_binding(tmp_path / "nope.toml")


def test_the_binding_overrides_cycle_times_and_gives_protection(tmp_path: Path):
    path = tmp_path / "b.toml"
    path.write_text(SHIPPED_TEXT + '\n[messages.PLANT_OIL_TEMP]\ncycle_time_ms = 50\n'
                    '[messages.TCU_STATUS]\nprotection = { profile = "none" }\ntimeout_ms = 250\n', encoding="utf-8")
    binding = load_binding(path)
    assert binding.cycle_times_ms == {"PLANT_OIL_TEMP": 50} and binding.timeouts_ms == {"TCU_STATUS": 250}
    assert binding.db.get_message_by_name("PLANT_OIL_TEMP").cycle_time == 50
    codec = Codec(binding.db, binding.uses, protection=binding.protection, timeouts={"TCU_STATUS": 0.25})
    assert codec.cycle_time_ms("PLANT_OIL_TEMP") == 50 and codec.protection("TCU_STATUS").profile == "none"
    monitor = RxMonitor(codec, list(binding.rx))
    assert monitor.states["TCU_STATUS"].deadline == 0.25 and monitor.states["TCU_CMD"].deadline == 0.03
    assert load_dbc().get_message_by_name("PLANT_OIL_TEMP").cycle_time == 100  # the file's DBC unchanged


def test_the_plant_reads_a_command_in_the_unit_of_its_signal(tmp_path: Path):
    """TCU_CMD's pressures in kPa (the same raw values, scale 0.1): the plant's commanded pressures in Pa."""
    text = load_dbc_text().replace(' SG_ P_CL_Cmd : 0|16@1+ (0.0001,0) [0|1.5] "MPa" PLANT',
                                   ' SG_ P_CL_Cmd : 0|16@1+ (0.1,0) [0|1500] "kPa" PLANT')
    dbc = tmp_path / "kpa.dbc"
    dbc.write_text(text, encoding="utf-8")
    io = from_binding(load_binding(dbc=dbc))
    assert io.commanded_pressures({"P_CL_Cmd": 557.0, "P_CH_Cmd": 0.25, "SyncEcho": 3.0}) == (557e3, 0.25e6)
    assert SHIPPED.commanded_pressures({"P_CL_Cmd": 0.557, "P_CH_Cmd": 0.25, "SyncEcho": 3.0}) == (0.557e6, 0.25e6)


def load_dbc_text() -> str:
    from dsg_hil.protocol.codec import DEFAULT_DBC

    return DEFAULT_DBC.read_text(encoding="utf-8")
