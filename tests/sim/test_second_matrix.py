"""The plant on the second example matrix (``dbc/examples/dct_fd``: other IDs and names, Motorola byte order, other
scalings and offsets, CAN FD messages of 12 and 16 bytes, AUTOSAR E2E Profile 5 on the TCU's frames and 11 on the
sensor frames, a multiplexed message) runs the default creep by its binding alone, driven by ecu-stub built only
from the same pair of files: in lock-step and in real time in one process, and as two processes (``dsg-hil plant``
and ``ecu-stub``) on udp_multicast with CAN FD frames. The plant's truth is the shipped pair's, but for the
multiplexed oil message: ecu-stub's inputs are whole once its last page has come, one cycle of it after the first."""

from __future__ import annotations

import json
from importlib import resources
from pathlib import Path

import can
import pytest

from dsg_hil.common.units import CV
from dsg_hil.protocol import Codec
from dsg_hil.protocol.binding import Binding, check_binding, load_binding
from dsg_hil.protocol.logs import decoded_frames, log_codec
from dsg_hil.sim.run import RunConfig, open_run
from dsg_hil.sim.scenario import load_scenario
from ecu_stub.calibration import DEFAULT_CALIBRATION, load_calibration
from ecu_stub.cli import main as ecu_stub_main
from ecu_stub.controller import TcuOutputs
from ecu_stub.runner import TcuRunner
from ecu_stub.tcu_io import CLUTCH_VALUES, STATE_VALUES, TcuIO
from dsg_hil.sim.plant_io import from_binding as plant_from_binding
from ecu_stub.controller import CreepController

from .test_binding_run import run_two_processes

EXAMPLE = resources.files("dsg_hil") / "data" / "examples" / "dct_fd"
DBC, BINDING = Path(str(EXAMPLE / "dct_fd.dbc")), Path(str(EXAMPLE / "dct_fd.binding.toml"))
DURATION = 40.0  # s of the default creep: CL engages, creeps, hands over to CH
SHORT = 8.0  # s: the two-process run (CL engages and creeps)
OIL = "TCM_OilTemps"  # the multiplexed message
STATUS_CYCLE = 0.1  # s: TCU_STATUS's and TCU_Info's cycle (test_the_status_cycles_are_the_same)


def pages(binding: Binding) -> list[int]:
    """The multiplexed oil message's pages."""
    message = binding.db.get_message_by_name(OIL)
    return sorted({page for signal in message.signals for page in signal.multiplexer_ids or ()})


def oil_delay(binding: Binding) -> float:
    """[s]: how much later than on the shipped matrix ecu-stub's inputs are first whole: the shipped oil frame
    carries every oil temperature from t = 0, the multiplexed one a page per frame, the last page's first frame
    (pages - 1) cycles of the message later."""
    cycle = binding.db.get_message_by_name(OIL).cycle_time
    assert cycle is not None
    return (len(pages(binding)) - 1) * cycle / 1000


def test_the_example_passes_binding_check():
    binding, problems = check_binding(BINDING, dbc=DBC)
    assert problems == [] and binding is not None
    db = binding.db
    fd = {m.name: m.length for m in db.messages if m.is_fd}
    assert max(fd.values()) > 8 and len(fd) >= 2
    assert all(s.byte_order == "big_endian" for m in db.messages for s in m.signals)
    assert any(m.is_multiplexed() for m in db.messages if m.name in binding.tx)
    profiles = {name: table["profile"] for name, table in binding.protection.items()}
    assert profiles["TCU_Demand"] == profiles["TCU_Info"] == "P05"
    assert {profiles[name] for name in binding.tx if not name.startswith("SIM_")} == {"P11"}


def test_the_example_shares_nothing_with_the_shipped_matrix():
    shipped, other = load_binding(), load_binding(BINDING, dbc=DBC)
    assert {m.frame_id for m in other.db.messages}.isdisjoint(m.frame_id for m in shipped.db.messages)
    assert {m.name for m in other.db.messages}.isdisjoint(m.name for m in shipped.db.messages)
    assert {s for _, s in other.signals}.isdisjoint(s for _, s in shipped.signals)

    def scaling(binding: Binding) -> dict[str, tuple[float, float, str]]:
        out = {}
        for (message, signal), (quantity, _) in binding.signals.items():
            found = binding.db.get_message_by_name(message).get_signal_by_name(signal)
            out[quantity] = (found.scale, found.offset, binding.units[quantity])
        return out
    a, b = scaling(shipped), scaling(other)
    same = sorted(q for q in a if a[q] == b[q] and a[q][:2] != (1, 0))
    assert same == [] and len(a) == len(b) == 36
    assert sum(a[q][2] != b[q][2] for q in a) >= 12  # other units (1/min, rad/s, km/h, bar, K, kW ...)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    with open_run(RunConfig(duration=DURATION)) as run:
        shipped_summary = run.run().as_json()
    other = load_binding(BINDING, dbc=DBC)
    log = tmp_path_factory.mktemp("dct_fd") / "creep.blf"
    config = RunConfig(duration=DURATION, dbc=DBC, binding=BINDING, capture=True, log=log)
    with open_run(config) as run:
        assert run.tcu.io.names[:4] == ("SIM_Step", "StepCnt", "TCU_Demand", "StepEcho")  # ecu-stub, on dct_fd
        other_summary = run.run().as_json()
    return shipped_summary, (other, run.frames, other_summary, log)


def same_creep(a: dict, b: dict, delay: float) -> None:
    """``b``'s creep is ``a``'s but for ecu-stub's inputs being whole ``delay`` later: CL engages exactly that much
    later (the closed loop is otherwise the same), so the creep is that much shorter and the standstill longer;
    the handovers are the same, each within ``delay`` of its time; each phase's friction energy and each clutch's
    peak plate temperature differ by no more than ``delay`` of the shipped phase's mean friction power and
    heating rate; the TCU's predicted peaks also by half of either matrix's step of the status signal."""
    assert [p["clutch"] for p in b["phases"]] == [p["clutch"] for p in a["phases"]]
    assert b["phases"][0]["start_s"] == pytest.approx(a["phases"][0]["start_s"] + delay, abs=1e-9)
    assert b["creep_time_s"] == pytest.approx(a["creep_time_s"] - delay, abs=1e-9)
    assert b["standstill_time_s"] == pytest.approx(a["standstill_time_s"] + delay, abs=1e-9)
    assert [(h["from"], h["to"]) for h in b["handovers"]] == [(h["from"], h["to"]) for h in a["handovers"]]
    for pa, pb in zip(a["phases"][1:], b["phases"][1:]):  # (the plant's own phase boundaries, to the ms)
        assert abs(pb["start_s"] - pa["start_s"]) <= delay + 1e-9
    for ha, hb in zip(a["handovers"], b["handovers"]):  # (as the status frames, each STATUS_CYCLE, tell them)
        assert abs(hb["t_s"] - ha["t_s"]) <= delay + STATUS_CYCLE + 1e-9
    steps = 0.5 * (0.1 + 0.5)  # K: half the steps of TCU_STATUS.T_CL_Pred (0.1 degC) and TCU_Info.T_ClutchA_Est
    scenario = load_scenario()
    initial = {"CL": scenario.T_CL_c, "CH": scenario.T_CH_c}
    for k, phase in enumerate(a["phases"]):  # (each clutch slips in one phase of the default creep)
        clutch, duration = phase["clutch"], phase["duration_s"]
        start = a["phases"][k - 1][f"T_{clutch}_end_c"] if k else initial[clutch]  # degC: at the phase's start
        power = a["friction_energy_kj"][clutch] / a["slip_time_s"][clutch]  # kW: mean while it slips
        assert abs(b["friction_energy_kj"][clutch] - a["friction_energy_kj"][clutch]) <= power * delay + 0.05
        heating = (phase[f"T_{clutch}_end_c"] - start) / duration  # K/s: the phase's mean
        assert heating > 0.0
        bound = heating * delay
        assert abs(b["max_plate_temp_c"][clutch] - a["max_plate_temp_c"][clutch]) <= bound + 0.01, clutch
        assert abs(b["max_predicted_temp_c"][clutch] - a["max_predicted_temp_c"][clutch]) <= bound + steps + 0.05
    assert b["frames"]["rejected"] == b["frames"]["unanswered_ticks"] == 0


@pytest.mark.slow
def test_every_frame_is_in_its_message_s_format(runs):
    _, (other, frames, _, _) = runs
    seen = {}
    for msg in frames:
        message = other.db.get_message_by_frame_id(msg.arbitration_id)
        seen.setdefault(message.name, set()).add((msg.is_fd, msg.bitrate_switch, len(msg.data)))
    assert seen["TCM_ShaftSpeeds"] == {(True, True, 12)} and seen["TCU_Demand"] == {(True, True, 16)}
    assert seen["SIM_ClutchA"] == {(True, False, 16)} and seen["EMS_TorqueSpeed"] == {(False, False, 8)}
    sent = [int(other.db.get_message_by_name(OIL).decode(bytes(m.data), decode_choices=False)["OilTemp_Page"])
            for m in frames if m.arbitration_id == 0x0E1]
    # the pages in turn, also where Profile 11's 0-14 counter wraps (page 0 is not sent twice in a row)
    assert len(sent) > 15 and sent == [pages(other)[k % 2] for k in range(len(sent))]


def test_the_status_cycles_are_the_same():
    for binding, status in ((load_binding(), "TCU_STATUS"), (load_binding(BINDING, dbc=DBC), "TCU_Info")):
        assert binding.db.get_message_by_name(status).cycle_time == STATUS_CYCLE * 1000


def test_ecu_stub_on_the_example_matrix_drives_the_shipped_creep_in_lockstep(runs):
    """ecu-stub built from dct_fd's DBC and binding alone, in lock-step in one process: the shipped creep, its
    engagement one oil cycle later (the multiplexed message's second page, 50 ms)."""
    a, (other, _, b, _) = runs
    assert oil_delay(other) == 0.05
    assert [p["clutch"] for p in a["phases"]] == ["CL", "CH"] and len(a["handovers"]) == 1
    same_creep(a, b, oil_delay(other))
    assert b["frames"]["received"] > 4000


def test_ecu_stub_s_checks_take_the_example_matrix_s_steps_with_a_calibration_given():
    """``dsg-hil run --calibration`` builds ecu-stub's controller itself (dsg_hil.sim.run.attach_tcu): on dct_fd its
    half steps of the speeds are dct_fd's (VehSpd 0.01 km/h, the shaft speeds 0.05 rad/s), not the shipped DBC's."""
    with open_run(RunConfig(duration=1.0, dbc=DBC, binding=BINDING, calibration=str(DEFAULT_CALIBRATION))) as run:
        controller = run.tcu.controller
    assert isinstance(controller, CreepController) and controller.cal == load_calibration()
    assert controller.steps == run.tcu.io.matrix_steps
    assert controller.speed_q_mps == pytest.approx(0.5 * 0.01 * CV.KMH_TO_MPS, rel=1e-15)
    assert controller.shaft_q_rpm == pytest.approx(0.05 * CV.RAD_S_TO_RPM, rel=1e-15)


def test_ecu_stub_takes_a_fault_s_side_from_the_binding(capsys):
    """dct_fd's nodes are GBX_SIM and TCM, not PLANT and TCU: ``ecu-stub --fault`` on a message the binding reads
    (the TCU's: TCU_Demand) injects it in the TCU's frames, as ``dsg-hil run`` does; one the binding sends (the
    plant's: ESP_WheelAccel) is refused as the plant's, exit 2 (before: 'the DBC names no sender PLANT or TCU')."""
    pair = ["-i", "virtual", "-c", "dct-fd-fault-side", "--dbc", str(DBC), "--binding", str(BINDING)]
    assert ecu_stub_main([*pair, "--fault", "drop:TCU_Demand@1-2", "--duration", "0.05", "-q"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == "ecu-stub: faults injected (frames hit): drop:TCU_Demand@1-2 0", err  # the TCU's injector
    assert ecu_stub_main([*pair, "--fault", "drop:ESP_WheelAccel@1-2", "--duration", "0.05", "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["error: --fault 'drop:ESP_WheelAccel@1-2': changes the plant's frames: give it to dsg-hil, or "
                   "side=tcu"]


RENUMBERED = {  # dct_fd's value tables of the TCU's state and clutch, numbered otherwise (a variant in tests only)
    'VAL_ 472 GbxState 0 "Idle" 1 "Engaging" 2 "Creeping" 3 "Handover" 4 "ThermalStop" 5 "Fault" ;':
        'VAL_ 472 GbxState 0 "Fault" 1 "Idle" 2 "Engaging" 3 "Creeping" 4 "Handover" 5 "ThermalStop" ;',
    'VAL_ 472 ActClutch 0 "Open" 1 "ClutchA" 2 "ClutchB" ;': 'VAL_ 472 ActClutch 0 "ClutchA" 1 "ClutchB" 2 "Open" ;',
}
NAMES = ('tcu_state = { signal = "TCU_Info.GbxState", values = { IDLE = "Idle", ENGAGE = "Engaging", '
         'CREEP = "Creeping", HANDOVER = "Handover", STOPPED_OVERHEAT = "ThermalStop", FAULT = "Fault" } }\n'
         'active_clutch = { signal = "TCU_Info.ActClutch", values = { NONE = "Open", CL = "ClutchA", CH = "ClutchB" } }'
         '\n')


def renumbered(where: Path, names: str | None = NAMES) -> tuple[Path, Path]:
    """dct_fd with :data:`RENUMBERED`'s value tables, and its binding giving ``names`` for the two quantities
    (None: dct_fd's own binding, which names none)."""
    text = DBC.read_text(encoding="utf-8")
    for old, new in RENUMBERED.items():
        assert old in text
        text = text.replace(old, new)
    dbc, binding = where / "renumbered.dbc", where / "renumbered.binding.toml"
    dbc.write_text(text, encoding="utf-8")
    lines = BINDING.read_text(encoding="utf-8")
    if names is not None:
        lines = lines.replace('tcu_state = "TCU_Info.GbxState"\nactive_clutch = "TCU_Info.ActClutch"\n', names)
        assert names in lines
    binding.write_text(lines, encoding="utf-8")
    return dbc, binding


def test_the_tcu_s_state_and_clutch_go_out_as_the_matrix_numbers_them(tmp_path):
    """A matrix whose value tables number the TCU's states and clutches otherwise than the shipped DBC (CREEP is
    'Creeping' = 3, CL 'ClutchA' = 0), its binding naming them: ecu-stub sends its numbers, and the plant reads them
    back as the quantities' (the shipped DBC's); without the names both ends keep the shipped numbers."""
    dbc, binding = renumbered(tmp_path)
    loaded = load_binding(binding, dbc=dbc)
    io = TcuIO(loaded)
    assert io.state_values == {"IDLE": 1, "ENGAGE": 2, "CREEP": 3, "HANDOVER": 4, "STOPPED_OVERHEAT": 5, "FAULT": 0}
    assert io.clutch_values == {"NONE": 2, "CL": 0, "CH": 1}
    bus = can.Bus(interface="virtual", channel="renumbered")
    try:
        tcu = TcuRunner(Codec(loaded.db, io.uses, protection=io.protection), bus, io=io)
        data = tcu._frame_data["TCU_Info"](TcuOutputs(0.3, 0.0, "CREEP", "CL", False, 100.0, 90.0, 0), 0, 0)
    finally:
        bus.shutdown()
    decoded = loaded.db.get_message_by_name("TCU_Info").decode(data)
    assert (str(decoded["GbxState"]), str(decoded["ActClutch"])) == ("Creeping", "ClutchA")
    plant = plant_from_binding(loaded)
    read = plant.status_values({"GbxState": 3.0, "ActClutch": 0.0, "T_ClutchA_Est": 373.15,
                                "T_ClutchB_Est": 363.15})
    assert (read["State"], read["ActiveClutch"]) == (2.0, 1.0)  # CREEP, CL in the shipped DBC's numbers
    assert plant.status_values({"GbxState": 6.0, "ActClutch": 2.0, "T_ClutchA_Est": 373.15,
                                "T_ClutchB_Est": 363.15})["State"] == -1.0  # not in its value table: no state
    unnamed = TcuIO(load_binding(renumbered(tmp_path, None)[1], dbc=dbc))
    assert unnamed.state_values == STATE_VALUES and unnamed.clutch_values == CLUTCH_VALUES
    assert TcuIO(load_binding(BINDING, dbc=DBC)).state_values == STATE_VALUES  # dct_fd numbers them as shipped


@pytest.mark.parametrize("names, said", [
    ('tcu_state = { signal = "TCU_Info.GbxState", values = { IDLE = "Idle" } }\n'
     'active_clutch = "TCU_Info.ActClutch"\n',
     "quantities.tcu_state.values must give the matrix's name of each of IDLE, ENGAGE, CREEP, HANDOVER, "
     "STOPPED_OVERHEAT, FAULT"),
    (NAMES.replace('CL = "ClutchA", CH = "ClutchB"', 'CL = "ClutchA", CH = "ClutchA"'),
     "quantities.active_clutch.values: two of the values have one name"),
    (NAMES.replace('NONE = "Open"', 'NONE = "Neutral"'),
     "quantities.active_clutch.values.NONE: 'Neutral' is not in the value table of TCU_Info.ActClutch "
     "(ClutchA, ClutchB, Open)"),
    (NAMES + 'brake_request = { signal = "TCU_Info.BrkReq", values = { NO = "NoRequest" } }\n',
     'quantities.brake_request must be "MESSAGE.Signal" or {signal = ..., unit = ...}'),
])
def test_the_names_of_the_values_are_checked(tmp_path, names, said):
    dbc, binding = renumbered(tmp_path, names)
    if "brake_request = {" in names:  # (its own line gone)
        text = binding.read_text(encoding="utf-8").replace('brake_request = "TCU_Info.BrkReq"\n', "", 1)
        binding.write_text(text, encoding="utf-8")
    loaded, problems = check_binding(binding, dbc=dbc)
    assert loaded is None and len(problems) == 1 and problems[0].startswith(f"{binding}: {said}"), problems


def test_a_creep_on_the_renumbered_matrix_is_the_example_s(tmp_path):
    """The closed loop on the renumbered variant, its binding naming the values: the plant's summary (states,
    phases, handovers, predictions) is dct_fd's, though other numbers went over the bus."""
    dbc, binding = renumbered(tmp_path)
    summaries = []
    for pair in ((DBC, BINDING), (dbc, binding)):
        with open_run(RunConfig(duration=SHORT, dbc=pair[0], binding=pair[1])) as run:
            summaries.append(run.run().as_json())
    own = ("wall_time_s", "realtime_factor", "command_latency_ms", "interface")  # the run's, not the creep's
    a, b = ({k: v for k, v in s.items() if k not in own} for s in summaries)
    assert a["phases"] and a == b


@pytest.mark.slow
def test_ecu_stub_on_the_example_matrix_in_real_time():
    """The same pair in real time, in one process on python-can's virtual bus (ecu-stub on its own clock, no
    SIM_Step frames): short, no assertion on timing; nothing rejected at either end, ecu-stub reads every sensor
    frame and engages CL, the frames in their formats."""
    bus = {"interface": "virtual", "channel": "dct-fd-realtime", "preserve_timestamps": True}
    config = RunConfig(duration=4.0, dbc=DBC, binding=BINDING, mode="realtime", capture=True, bus=bus)
    with open_run(config) as run:
        summary = run.run().as_json()
        tcu = run.tcu
    assert summary["frames"]["rejected"] == 0 and tcu.rx.rejected_total == 0
    other = load_binding(BINDING, dbc=DBC)
    assert all(tcu.rx.states[name].received > 0 for name in tcu.io.required)
    assert [p["clutch"] for p in summary["phases"]][:1] == ["CL"]  # ecu-stub's commands engaged CL
    demand = other.db.get_message_by_name("TCU_Demand")
    assert {(m.is_fd, len(m.data)) for m in run.frames if m.arbitration_id == demand.frame_id} == {(True, 16)}
    assert not any(m.arbitration_id == other.db.get_message_by_name("SIM_Step").frame_id for m in run.frames)


@pytest.mark.slow
def test_plant_and_ecu_stub_as_two_processes_on_the_example_matrix(tmp_path, runs):
    """``dsg-hil plant`` and ``ecu-stub``, each given ``--dbc dct_fd.dbc --binding dct_fd.binding.toml``, on
    udp_multicast (CAN FD frames, the bus opened for them by both): lock-step is the same whatever the bus, so the
    creep is the in-process run's over the same time, and the shipped pair's within :func:`same_creep`."""
    other = runs[1][0]
    with open_run(RunConfig(duration=SHORT)) as run:
        shipped = run.run().as_json()
    with open_run(RunConfig(duration=SHORT, dbc=DBC, binding=BINDING)) as run:
        in_process = run.run().as_json()
    summary, log = tmp_path / "summary.json", tmp_path / "creep.log"
    plant, tcu_err = run_two_processes(DBC, BINDING, SHORT, ["--summary", str(summary), "--log", str(log)])
    assert plant.returncode == 0, plant.stderr
    assert "rejected 0" in tcu_err, tcu_err  # ecu-stub's closing counts: it read the dct_fd frames
    b = json.loads(summary.read_text(encoding="utf-8"))
    for key in ("phases", "creep_time_s", "standstill_time_s", "slip_time_s", "max_plate_temp_c",
                "friction_energy_kj", "max_predicted_temp_c"):
        assert b[key] == in_process[key], key
    same_creep(shipped, b, oil_delay(other))
    fd = {(line.split()[2].split("#")[0], "##" in line) for line in log.read_text().splitlines()}
    assert ("1C4", True) in fd and ("0B2", True) in fd and ("0A4", False) in fd  # candump -L: CAN FD as ID##


def test_the_log_of_the_example_run_decodes_with_its_binding(runs):
    _, (other, frames, _, log) = runs
    counts: dict[str, int] = {}
    names = {frame.name for _, frame in decoded_frames(log, log_codec(other.db, other.protection), counts)
             if frame is not None}
    assert counts["rejected"] == counts["unknown"] == 0 and counts["decoded"] == len(frames)
    assert names == set(other.uses)


def test_the_report_s_log_reader_reads_the_example_run(runs):
    """``dsg-hil report --from-log --dbc --binding``'s reader on the run's .blf log (CAN FD frames, Profile 5 and 11,
    the multiplexed oil temperatures): the creep time of the run's own summary, the plate temperature's peak of the
    truth frames it sent."""
    from dsg_hil.paper.report.log import read_log
    from dsg_hil.sim.plant_io import from_binding

    _, (other, frames, summary, log) = runs
    record = read_log(log, other.db, from_binding(other), other.protection)
    assert record.frames == {"decoded": len(frames), "rejected": 0, "unknown": 0} and record.has_status
    assert record.metrics["creep_time_s"] == pytest.approx(summary["creep_time_s"], abs=0.02)
    truth = other.db.get_message_by_name("SIM_ClutchA")
    sent = max(float(truth.decode(bytes(m.data)[:truth.length])["T_PlateA"]) for m in frames
               if m.arbitration_id == truth.frame_id) - 273.15  # the truth frames' own peak (every 100 ms)
    assert record.metrics["max_plate_temp_c"]["CL"] == pytest.approx(sent, abs=0.01)
    predicted = record.columns["T_CL_pred"]  # TCU_Info's, in K on the bus
    assert predicted.size > 700 and float(predicted[20:].min()) > 0.0  # (no NaN after the first status)
    assert float(predicted.max()) == pytest.approx(summary["max_predicted_temp_c"]["CL"], abs=0.01)


@pytest.mark.parametrize("message, signal, value", [("TCU_Demand", "PressReqA", 500.0),
                                                    ("TCM_ShaftSpeeds", "GbxOutSpd", 12.5)])
def test_faults_on_the_example_s_fd_frames(message, signal, value):
    """Profile 5 over the 16-byte TCU_Demand and Profile 11 over the 12-byte TCM_ShaftSpeeds: each fault kind on a
    CAN FD frame gives a CAN FD frame of its length that the receiver rejects for the fault's cause (a frozen
    counter: a repeat, once the frame before it was taken), or takes with the stuck value."""
    from dsg_hil.protocol.faults import FaultInjector
    from dsg_hil.protocol.faults.spec import parse_fault
    from dsg_hil.protocol.frame import data_frame
    from dsg_hil.protocol.validity import NEW, REJECTED, RxMonitor

    other = load_binding(BINDING, dbc=DBC)
    codec = Codec(other.db, other.uses, protection=other.protection)
    frame_id, length = codec.frame_id(message), codec.message(message).length

    def frames(n: int) -> list[can.Message]:
        return [data_frame(frame_id, codec.encode(message, {signal: value + k}, k), 0.01 * k, fd=codec.fd)
                for k in range(n)]  # (the values change: a frozen counter's frames are no byte-identical repeat)

    for fault, expected in ((f"corrupt_crc:{message}", ["crc"]), (f"freeze_counter:{message}", ["counter"]),
                            (f"stuck:{message}.{signal},value=100", [])):
        injector = FaultInjector(other.db, [parse_fault(fault)], protections=codec.protections())
        rx = RxMonitor(codec, [message])
        statuses = []
        for k, msg in enumerate(frames(3)):
            (out,) = injector.apply(msg, 0.01 * k)
            assert out.is_fd and out.bitrate_switch and len(out.data) == length
            status, frame = rx.take(out, 0.01 * k)
            statuses.append(status)
            if fault.startswith("stuck") and frame is not None:
                assert frame.values[signal] == pytest.approx(100.0)
        assert sorted(rx.rejected) == expected, fault
        assert statuses == ([NEW, NEW, NEW] if not expected else
                            [REJECTED] * 3 if expected == ["crc"] else [NEW, REJECTED, REJECTED])


@pytest.mark.parametrize("dlc", [12, 64, 5])
def test_wrong_dlc_gives_a_can_fd_length_on_an_fd_message(dlc):
    """``wrong_dlc`` on the 16-byte TCU_Demand with a CAN FD length (or a short one): a CAN FD frame of that length,
    which the receiver rejects as ``dlc``; a CAN FD length on a classic message is refused before the run."""
    from dsg_hil.protocol.faults import FaultInjector
    from dsg_hil.protocol.faults.spec import FaultError, check_faults, parse_fault
    from dsg_hil.protocol.frame import data_frame
    from dsg_hil.protocol.validity import REJECTED, RxMonitor

    other = load_binding(BINDING, dbc=DBC)
    codec = Codec(other.db, other.uses, protection=other.protection)
    spec = parse_fault(f"wrong_dlc:TCU_Demand,dlc={dlc},side=tcu")  # (dct_fd's senders are GBX_SIM and TCM)
    assert check_faults([spec], other.db)["tcu"] == [spec]
    injector = FaultInjector(other.db, [spec], protections=codec.protections())
    frame_id = codec.frame_id("TCU_Demand")
    (out,) = injector.apply(data_frame(frame_id, codec.encode("TCU_Demand", {"PressReqA": 500.0}, 0), 0.0,
                                       fd=codec.fd), 0.0)
    assert out.is_fd and out.bitrate_switch and len(out.data) == dlc
    rx = RxMonitor(codec, ["TCU_Demand"])
    assert rx.take(out, 0.0)[0] == REJECTED and dict(rx.rejected) == {"dlc": 1}
    if dlc > 8:
        with pytest.raises(FaultError, match=f"dlc {dlc} is a CAN FD length, and EMS_TorqueSpeed is a classic CAN"):
            check_faults([parse_fault(f"wrong_dlc:EMS_TorqueSpeed,dlc={dlc},side=plant")], other.db)
