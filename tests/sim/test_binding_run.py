"""Both ends on another communication matrix by configuration alone: a copy of the shipped DBC with every message
and signal renamed, every ID moved and scalings changed (vehicle speed in km/h, the clutch pressures in kPa, the
TCU's predicted plate temperatures in K), with its binding, runs the shipped creep in lock-step, the plant and
ecu-stub each reading the same pair of files: in one process, and as two processes (``dsg-hil plant`` and
``ecu-stub``) on udp_multicast. The frames, decoded with the renamed DBC and its binding, carry the physical values
of the shipped pair's run, and the plant's truth is the shipped run's."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import can
import pytest

from dsg_hil.protocol.bus import UDP_MULTICAST, bus_args, fresh_udp_group

from dsg_hil.protocol import load_dbc
from dsg_hil.protocol.binding import DEFAULT_BINDING, Binding, check_binding, load_binding
from dsg_hil.protocol.e2e import COUNTER, CRC
from dsg_hil.sim.run import RunConfig, open_run

DURATION = 8.0  # s of the shipped creep: the TCU engages CL and creeps
NEW = {  # shipped message -> (renamed, new ID)
    "PLANT_ENGINE": ("EMS_Engine", 0x0C0), "PLANT_SPEEDS": ("TCM_Speeds", 0x0C8),
    "PLANT_VEHICLE": ("ESP_Vehicle", 0x0D0), "PLANT_PRESSURE": ("TCM_Pressure", 0x0D8),
    "PLANT_OIL_TEMP": ("TCM_OilTemp", 0x0E0), "DRIVER": ("DRV_Request", 0x0E8),
    "TCU_CMD": ("TCU_Command", 0x1A0), "TCU_STATUS": ("TCU_State", 0x1B0),
    "SIM_TRUTH_CL": ("SIM_TruthA", 0x7A0), "SIM_TRUTH_CH": ("SIM_TruthB", 0x7A1), "SIM_HEAT": ("SIM_HeatDiss", 0x7A2),
    "SIM_SYNC": ("SIM_Step", 0x7E0),
}
# (message, signal) -> (k, offset, unit): the value in the new unit is k times the shipped one plus offset. The same
# raw values: the plant's commands (TCU_CMD) keep their scaling, so the plant reads bit for bit the commands of the
# shipped pair's run and both runs are one closed loop (the unit conversions' last bits feed no physics)
RESCALED = {("PLANT_VEHICLE", "VehicleSpeed"): (3.6, 0.0, "km/h"), ("PLANT_PRESSURE", "P_CL"): (1e3, 0.0, "kPa"),
            ("PLANT_PRESSURE", "P_CH"): (1e3, 0.0, "kPa"), ("TCU_STATUS", "T_CL_Pred"): (1.0, 273.15, "K"),
            ("TCU_STATUS", "T_CH_Pred"): (1.0, 273.15, "K")}


def renamed(signal: str) -> str:
    return signal if signal in (COUNTER, CRC) else "s" + signal


def write_renamed_pair(tmp_path: Path) -> tuple[Path, Path]:
    """The renamed DBC and its binding (the shipped binding's text with the new names)."""
    from cantools.database.conversion import BaseConversion  # noqa: PLC0415

    db = load_dbc()
    for message in db.messages:
        for signal in message.signals:
            if (message.name, signal.name) in RESCALED:
                k, offset, unit = RESCALED[message.name, signal.name]
                signal.conversion = BaseConversion.factory(scale=signal.scale * k, offset=signal.offset * k + offset,
                                                           is_float=False)
                assert signal.minimum is not None and signal.maximum is not None
                signal.minimum, signal.maximum = signal.minimum * k + offset, signal.maximum * k + offset
                signal.unit = unit
            signal.name = renamed(signal.name)
        message.name, message.frame_id = NEW[message.name]
    db.refresh()
    dbc = tmp_path / "renamed.dbc"
    dbc.write_text(db.as_dbc_string(), encoding="utf-8")
    text = DEFAULT_BINDING.read_text(encoding="utf-8")
    text = re.sub(r'"([A-Z_]+)\.(\w+)"', lambda m: f'"{NEW[m[1]][0]}.{renamed(m[2])}"', text)
    text = re.sub(r'"([A-Z_]+)"', lambda m: f'"{NEW[m[1]][0]}"', text)
    binding = tmp_path / "renamed.binding.toml"
    binding.write_text(text, encoding="utf-8")
    return dbc, binding


def quantities(frames: list[can.Message], binding: Binding) -> dict[str, list[tuple[float, float]]]:
    """By quantity, its (time, value in SI) of every frame (decoded with the binding's DBC)."""
    out: dict[str, list[tuple[float, float]]] = {}
    for msg in frames:
        try:
            message = binding.db.get_message_by_frame_id(msg.arbitration_id)
        except KeyError:
            continue
        decoded = message.decode(bytes(msg.data), decode_choices=False)
        assert isinstance(decoded, dict)
        for signal, value in decoded.items():
            if (message.name, signal) in binding.signals:
                quantity, factor = binding.signals[message.name, signal]
                out.setdefault(quantity, []).append(
                    (msg.timestamp, float(value) * factor  # type: ignore[arg-type]
                     + binding.offsets.get((message.name, signal), 0.0)))
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    dbc, binding_path = write_renamed_pair(tmp_path_factory.mktemp("renamed"))
    with open_run(RunConfig(duration=DURATION, capture=True, truth=True)) as run:
        shipped_summary = run.run().as_json()
    shipped_frames = run.frames
    shipped, other = load_binding(), load_binding(binding_path, dbc=dbc)
    config = RunConfig(duration=DURATION, dbc=dbc, binding=binding_path, capture=True, truth=True)
    with open_run(config) as run:
        assert run.tcu.io.names[:4] == ("SIM_Step", "sTick", "TCU_Command", "sSyncEcho")  # ecu-stub, renamed
        other_summary = run.run().as_json()
    return (shipped, shipped_frames, shipped_summary), (other, run.frames, other_summary)


def test_the_renamed_matrix_moves_every_id_and_name(runs):
    (shipped, shipped_frames, _), (other, other_frames, _) = runs
    assert {m.frame_id for m in other.db.messages}.isdisjoint(m.frame_id for m in shipped.db.messages)
    assert {msg.arbitration_id for msg in other_frames} == {m.frame_id for m in other.db.messages
                                                            if m.name in other.uses}
    assert (other.units["v"], other.units["P_CL"], other.units["T_CL_pred"]) == ("km/h", "kPa", "K")
    status = NEW["TCU_STATUS"][0]
    assert other.offsets == {(status, "sT_CL_Pred"): -273.15, (status, "sT_CH_Pred"): -273.15}
    assert len(other_frames) == len(shipped_frames) > 1000


def test_the_plant_on_the_renamed_matrix_sends_and_reads_the_same_physical_values(runs):
    """Each quantity's every frame, the plant's and the TCU's: the same time, the same value but for the last bits
    of the unit conversions (the rescaled signals carry the same raw values)."""
    (shipped, shipped_frames, _), (other, other_frames, _) = runs
    a, b = quantities(shipped_frames, shipped), quantities(other_frames, other)
    assert set(a) == set(b) and len(a) == len(shipped.signals)
    for quantity in a:
        assert [t for t, _ in a[quantity]] == [t for t, _ in b[quantity]], quantity
        for (_, x), (_, y) in zip(a[quantity], b[quantity]):
            assert abs(x - y) <= 1e-9 * max(1.0, abs(x)), (quantity, x, y)


def test_the_creep_on_the_renamed_matrix_is_the_shipped_one(runs):
    """The summary: the plant's truth the same, and the TCU's status read through the renamed binding (its
    predictions in K) the same within half their 0.1 K step."""
    (_, _, a), (_, _, b) = runs
    assert [p["clutch"] for p in a["phases"]] == ["CL"] and b["phases"] == a["phases"]
    for key in ("creep_time_s", "standstill_time_s", "slip_time_s", "max_plate_temp_c", "friction_energy_kj"):
        assert b[key] == a[key], key
    for clutch in ("CL", "CH"):
        assert b["max_predicted_temp_c"][clutch] == pytest.approx(a["max_predicted_temp_c"][clutch], abs=0.05)
    assert a["max_predicted_temp_c"]["CL"] > 120.0  # the TCU's status was read (it predicts the heating)
    assert b["frames"]["rejected"] == b["frames"]["unanswered_ticks"] == 0 and b["frames"]["received"] > 800


def run_two_processes(dbc: Path, binding: Path, duration: float,
                      plant_args: list[str]) -> tuple[subprocess.CompletedProcess[str], str]:
    """``ecu-stub`` and a lock-step ``dsg-hil plant``, each with ``--dbc dbc --binding binding``, on a fresh
    udp_multicast group: the plant's finished process and ecu-stub's stderr (its closing counts)."""
    bus = bus_args({"interface": UDP_MULTICAST, **fresh_udp_group()})
    pair = ["--dbc", str(dbc), "--binding", str(binding)]
    tcu = subprocess.Popen([sys.executable, "-m", "ecu_stub", *bus, *pair, "--idle-exit", "10", "--quiet"],
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        plant = subprocess.run([sys.executable, "-m", "dsg_hil", "plant", *bus, *pair, "--mode", "lockstep",
                                "--duration", f"{duration:g}", *plant_args, "--quiet"],
                               capture_output=True, text=True, timeout=600)
    finally:
        tcu.terminate()
        tcu_err = tcu.communicate(timeout=60)[1]
    return plant, tcu_err


@pytest.mark.slow
def test_plant_and_ecu_stub_as_two_processes_on_the_renamed_matrix(tmp_path, runs):
    """``dsg-hil plant`` and ``ecu-stub``, each given ``--dbc renamed.dbc --binding renamed.binding.toml``, on
    udp_multicast: the creep of the in-process run (lock-step is the same whatever the bus)."""
    (_, _, shipped), (_, _, in_process) = runs
    dbc, binding = write_renamed_pair(tmp_path)
    summary = tmp_path / "summary.json"
    plant, tcu_err = run_two_processes(dbc, binding, DURATION, ["--summary", str(summary)])
    assert plant.returncode == 0, plant.stderr
    assert "rejected 0" in tcu_err, tcu_err  # ecu-stub's closing counts: it read the renamed frames
    b = json.loads(summary.read_text(encoding="utf-8"))
    assert b["phases"] == shipped["phases"] == in_process["phases"]
    for key in ("creep_time_s", "standstill_time_s", "slip_time_s", "max_plate_temp_c", "friction_energy_kj"):
        assert b[key] == shipped[key], key
    for clutch in ("CL", "CH"):
        assert b["max_predicted_temp_c"][clutch] == pytest.approx(shipped["max_predicted_temp_c"][clutch], abs=0.05)
    assert b["frames"]["rejected"] == b["frames"]["unanswered_ticks"] == 0


@pytest.mark.slow
def test_run_config_gives_the_pair_to_an_ecu_stub_process(tmp_path, runs):
    """RunConfig(dbc=..., binding=...) on udp_multicast starts ecu-stub as a process with --dbc and --binding (the
    files' absolute paths): it answers on the renamed matrix, and the creep is the shipped one."""
    (_, _, shipped), _ = runs
    dbc, binding = write_renamed_pair(tmp_path)
    config = RunConfig(duration=DURATION, dbc=dbc, binding=binding, quiet=True,
                       bus={"interface": UDP_MULTICAST, **fresh_udp_group()})
    with open_run(config) as run:
        command = run._process.command(run.bus_config)
        summary = run.run().as_json()
    assert command[command.index("--dbc") + 1] == str(dbc.resolve())
    assert command[command.index("--binding") + 1] == str(binding.resolve())
    assert summary["frames"]["rejected"] == summary["frames"]["unanswered_ticks"] == 0
    for key in ("creep_time_s", "slip_time_s", "max_plate_temp_c", "friction_energy_kj"):
        assert summary[key] == shipped[key], key


@pytest.mark.parametrize("timeout_ms, events", [(None, 1), (50, 0)])
def test_a_binding_s_timeout_is_the_command_s_deadline(tmp_path, timeout_ms, events):
    """TCU_CMD lost for 4 control periods (40 ms): past the default deadline (3 cycle times, 30 ms) the hydraulics
    fall back; with the binding's 50 ms they hold the last command."""
    binding = None
    if timeout_ms is not None:
        binding = tmp_path / "timeout.binding.toml"
        binding.write_text(DEFAULT_BINDING.read_text(encoding="utf-8")
                           + f"\n[messages.TCU_CMD]\ntimeout_ms = {timeout_ms}\n", encoding="utf-8")
    with open_run(RunConfig(duration=2.0, binding=binding, faults=["drop:TCU_CMD@1-1.04"])) as run:
        summary = run.run().as_json()
    assert summary["frames"]["unanswered_ticks"] == 4
    assert summary["command_fallback"]["events"] == events


@pytest.mark.parametrize("timeout_ms, dropouts", [(None, 1), (50, 0)])
def test_a_binding_s_timeout_on_a_plant_message_is_ecu_stub_s_deadline(tmp_path, timeout_ms, dropouts):
    """PLANT_VEHICLE lost for 4 control periods (40 ms) just after the launch: past ecu-stub's default deadline
    (3 cycle times, 30 ms) its inputs are invalid and it opens the clutch for a cycle (FAULT); with the binding's
    50 ms it controls on through the gap."""
    binding = None
    if timeout_ms is not None:
        binding = tmp_path / "timeout.binding.toml"
        binding.write_text(DEFAULT_BINDING.read_text(encoding="utf-8")
                           + f"\n[messages.PLANT_VEHICLE]\ntimeout_ms = {timeout_ms}\n", encoding="utf-8")
    with open_run(RunConfig(duration=1.5, binding=binding, faults=["drop:PLANT_VEHICLE@1-1.04"], capture=True)) as run:
        run.run()
    assert run.tcu.rx.states["PLANT_VEHICLE"].deadline == (timeout_ms or 30) / 1000
    command = run.tcu.codec.message("TCU_CMD")
    pressures = [command.decode(bytes(m.data))["P_CL_Cmd"] for m in run.frames if m.arbitration_id == command.frame_id]
    engaged = next(k for k, p in enumerate(pressures) if p > 0.1)
    assert sum(p == 0.0 for p in pressures[engaged:]) == dropouts


SIM_IDS = {"SIM_SYNC": 0x010, "SIM_TRUTH_CL": 0x7F0, "SIM_TRUTH_CH": 0x7F1, "SIM_HEAT": 0x7F2}  # the binding's


def write_matrix_without_simulation(tmp_path: Path) -> tuple[Path, Path]:
    """The renamed matrix without its simulation frames (a vehicle's matrix), and its binding, which adds the
    simulation database's on IDs of its own (SIM_SYNC the highest priority, 0x010)."""
    dbc, binding = write_renamed_pair(tmp_path)
    db = load_dbc(dbc)
    db.messages[:] = [m for m in db.messages if not m.name.startswith("SIM_")]
    db.refresh()
    dbc.write_text(db.as_dbc_string(), encoding="utf-8")
    text = binding.read_text(encoding="utf-8")
    for shipped in SIM_IDS:
        text = text.replace(f'"{NEW[shipped][0]}', f'"{shipped}')  # the names of the simulation database
    text = re.sub(r'"SIM_(\w+)\.s(\w+)"', r'"SIM_\1.\2"', text)  # and of its signals
    ids = ", ".join(f"{name} = 0x{frame_id:03X}" for name, frame_id in SIM_IDS.items())
    binding.write_text(text + f"\n[simulation]\nids = {{ {ids} }}\n", encoding="utf-8")
    return dbc, binding


def test_the_simulation_frames_are_added_to_a_matrix_without_them(tmp_path, runs):
    """A matrix with none of the simulation frames: the binding adds SIM_SYNC and the truth frames on its IDs, and
    the plant and ecu-stub run the shipped creep on it in lock-step."""
    (_, _, shipped), _ = runs
    dbc, binding_path = write_matrix_without_simulation(tmp_path)
    assert not any(m.name.startswith("SIM_") for m in load_dbc(dbc).messages)
    binding = load_binding(binding_path, dbc=dbc)
    assert {m.name: m.frame_id for m in binding.db.messages if m.name.startswith("SIM_")} == SIM_IDS
    assert binding.sync == ("SIM_SYNC", "Tick")
    with open_run(RunConfig(duration=DURATION, dbc=dbc, binding=binding_path, capture=True)) as run:
        summary = run.run().as_json()
    assert {msg.arbitration_id for msg in run.frames} >= set(SIM_IDS.values())
    assert summary["phases"] == shipped["phases"]
    for key in ("creep_time_s", "standstill_time_s", "slip_time_s", "max_plate_temp_c", "friction_energy_kj"):
        assert summary[key] == shipped[key], key


@pytest.mark.parametrize("ids, problem", [
    ("SIM_SYNC = 0x0C0", "simulation.ids.SIM_SYNC: 0xC0 is the ID of EMS_Engine in the matrix"),
    ("SIM_SYNC = 0x7E1", "simulation.ids.SIM_SYNC: 0x7E1 is the matrix's diagnostic request ID (DiagRequestId)"),
    ("SIM_SYNC = 0x7F0, SIM_TRUTH_CL = 0x7F0", "simulation.ids.SIM_TRUTH_CL: 0x7F0 is SIM_SYNC's too"),
    ("SIM_SYNC = 0x800", "simulation.ids.SIM_SYNC must be an 11-bit CAN ID (0x0-0x7FF), got 2048"),
    ("SIM_CLOCK = 0x010", "simulation.ids.SIM_CLOCK: not a message of the simulation database"),
])
def test_binding_check_refuses_a_simulation_id_the_matrix_uses(tmp_path, ids, problem):
    dbc, binding = write_matrix_without_simulation(tmp_path)
    text = re.sub(r"ids = \{.*\}", f"ids = {{ {ids} }}", binding.read_text(encoding="utf-8"))
    binding.write_text(text, encoding="utf-8")
    found, problems = check_binding(binding, dbc=dbc)
    assert found is None and any(problem in line for line in problems), problems


def test_a_simulation_message_the_matrix_has_already_is_refused(tmp_path):
    binding = tmp_path / "twice.binding.toml"
    binding.write_text(DEFAULT_BINDING.read_text(encoding="utf-8") + "\n[simulation]\nids = { SIM_SYNC = 0x010 }\n",
                       encoding="utf-8")
    found, problems = check_binding(binding)
    assert found is None and problems == [f"{binding}: simulation.ids.SIM_SYNC: the matrix has a message SIM_SYNC "
                                          f"already"]
