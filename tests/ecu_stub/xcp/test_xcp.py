"""ecu-stub as an XCP slave with pyxcp as the master (its python-can transport on python-can's virtual bus, in this
process): identification and upload, DAQ of the predicted plate temperature each control period against TCU_STATUS,
the state and clutch in the TCU's own numbers (the A2L's) on a matrix numbering them otherwise, a calibration value
changed at run time and one refused; the A2L read by pya2ldb; the slave's error packets; the lock-step frames of a
run with the slave idle."""

from __future__ import annotations

import logging
import struct
import subprocess
import sys
import threading
from contextlib import contextmanager
from types import SimpleNamespace

import can
import pytest

from dsg_hil.protocol import Codec, load_dbc
from dsg_hil.protocol.bus import UDP_MULTICAST, bus_args, fresh_udp_group
from dsg_hil.sim.run import RunConfig, open_run
from ecu_stub.calibration import load_calibration
from ecu_stub.controller import CreepController
from dsg_hil.protocol.binding import load_binding
from ecu_stub.runner import TCU_USES, TcuRunner
from ecu_stub.tcu_io import CLUTCH_VALUES, STATE_VALUES, TcuIO
from ecu_stub.xcp import DEFAULT_IDS, xcp_slave
from ecu_stub.xcp.a2l import a2l_text, symbol
from ecu_stub.xcp.memory import CAL_BASE, MEAS_BASE, MEASUREMENTS, cal_values, tcu_memory
from ecu_stub.xcp.slave import XcpSlave

pyxcp = pytest.importorskip("pyxcp", reason="the XCP master of the tests (extra 'xcp')")
from pyxcp.config import create_application_from_config  # noqa: E402
from pyxcp.daq_stim import DaqList, DaqOnlinePolicy  # noqa: E402
from pyxcp.master import Master  # noqa: E402
from pyxcp.types import XcpResponseError  # noqa: E402

CRO, DTO = DEFAULT_IDS
ADDRESS = {m.name: m.address for m in MEASUREMENTS}
CAL = {v.name: v for v in cal_values()}
DB = load_dbc()
STATUS = DB.get_message_by_name("TCU_STATUS")
STATES = {int(v): str(n) for v, n in (STATUS.get_signal_by_name("State").choices or {}).items()}
T_SAFE = CAL["strategy.T_safe_c"]


class Samples(DaqOnlinePolicy):
    """The DAQ lists' samples as {measurement: value} (pyxcp orders a list's measurements its own way)."""

    def __init__(self, daq_lists):
        super().__init__(daq_lists, logger=logging.getLogger("xcp-test"))
        self.pid_off = False  # (pyxcp 0.29 leaves it unset when given a logger)
        self.rows: list[dict] = []

    def initialize(self):
        pass

    def finalize(self):
        pass

    def on_daq_list(self, daq_list, timestamp0, timestamp1, payload):
        self.rows.append(dict(zip([h[0] for h in self.daq_lists[daq_list].headers], payload)))


def daq_list(*names: str) -> DaqList:
    types = {"FLOAT32_IEEE": "F32", "ULONG": "U32", "UBYTE": "U8"}
    kinds = {m.name: types[m.datatype] for m in MEASUREMENTS}
    return DaqList("tcu", 0, False, False, [(n, ADDRESS[n], 0, kinds[n]) for n in names], 0, 1)


@contextmanager
def pyxcp_master(bus, policy=None, ids=DEFAULT_IDS):
    """A connected pyxcp master (python-can transport) on the python-can bus configuration ``bus``, talking to the
    slave of CAN IDs ``ids`` (CRO, DTO)."""
    app = create_application_from_config({"Transport": {"CAN": {
        "interface": bus["interface"], "channel": bus["channel"], "can_id_master": ids[0], "can_id_slave": ids[1]}},
        "General": {"disable_error_handling": True}},  # an error packet raises XcpResponseError, no retries
        log_level=logging.ERROR)
    app.transport.layer = "CAN"
    if "port" in bus:
        app.transport.can.udp_multicast.port = bus["port"]
    with Master("can", config=app, policy=policy) as master:
        master.connect()
        master.getCommModeInfo()
        yield master
        master.disconnect()


@contextmanager
def xcp_tcu(policy=None, binding=None):
    """ecu-stub's TCU with its XCP slave serving a fresh virtual bus in a thread (as the ecu-stub process would),
    and a connected pyxcp master on it: yields (master, TCU, the bus configuration). ``binding``: the TCU on that
    loaded binding's matrix (else the shipped DBC)."""
    config = {"interface": "virtual", "channel": f"xcp-{id(object()):x}"}
    bus = can.Bus(**config)
    if binding is None:
        tcu = TcuRunner(Codec(DB, TCU_USES), bus, xcp=xcp_slave())
    else:
        io = TcuIO(binding)
        tcu = TcuRunner(Codec(binding.db, io.uses, protection=io.protection), bus, io=io, xcp=xcp_slave())
    stop = threading.Event()
    thread = threading.Thread(target=tcu.run, kwargs={"should_stop": stop.is_set})
    thread.start()
    try:
        with pyxcp_master(config, policy) as master:
            yield master, tcu, config
    finally:
        stop.set()
        thread.join()
        bus.shutdown()


def write_double(master, address, x):
    """A calibration value: SET_MTA, then DOWNLOAD 6 bytes and 2 (each answered; pyxcp 0.29's push() expects no
    answer to a full packet in normal mode, and loses step with a slave that gives one)."""
    data = struct.pack("<d", x)
    master.setMta(address)
    master.download(data[:6])
    master.download(data[6:])


def read_double(master, address):
    master.setMta(address)
    return struct.unpack("<d", bytes(master.fetch(8)))[0]


def run_frames(bus=None, tcu=None, on_period=None, duration=3.0, **matrix):
    """The frames of a lock-step run of the default scenario (the TCU's XCP frames left out): in this process on
    the direct bus (``tcu`` a factory, or the bundled TCU), or with the TCU serving ``bus``; ``matrix``: RunConfig's
    ``dbc`` and ``binding`` (default: the shipped pair)."""
    config = RunConfig(duration=duration, capture=True, on_period=on_period, **matrix,
                       **({"bus": bus, "tcu": None} if bus is not None else {"tcu": tcu} if tcu else {}))
    with open_run(config) as run:
        run.run()
    return [(m.arbitration_id, bytes(m.data), m.timestamp) for m in run.frames
            if m.arbitration_id not in DEFAULT_IDS]


def drain(policy, tcu):
    """Stop the DAQ once pyxcp's thread has decoded every sample the slave sent (at most 30 s)."""
    odts = sum(len(d.odts) for d in tcu.xcp.daq)
    for _ in range(3000):
        if len(policy.rows) * odts >= tcu.xcp.dto_sent:
            break
        threading.Event().wait(0.01)
    policy.stop()


@pytest.fixture(scope="module")
def quiet():
    return run_frames()


def test_connect_identify_and_upload():
    cal = load_calibration()
    with xcp_tcu() as (master, tcu, _):
        assert master.slaveProperties.supportsDaq and master.slaveProperties.supportsCalpag
        assert master.identifier(1) == "ecu_stub"  # the A2L's name
        assert not master.getStatus().sessionStatus.daqRunning
        data = master.shortUpload(7, T_SAFE.address) + master.upload(1)  # 7 bytes + the 8th from the MTA
        assert struct.unpack("<d", bytes(data))[0] == cal.strategy.T_safe_c
        master.setMta(CAL["clutch.CH.C_plate_j_k"].address)
        assert struct.unpack("<d", bytes(master.fetch(8)))[0] == cal.CH.C_plate_j_k
        with pytest.raises(XcpResponseError):
            master.shortUpload(4, MEAS_BASE + 0x1000)  # beyond the measurements
    assert tcu.xcp.errors == 1


def test_daq_each_period_gives_the_predicted_plate_temperature_on_the_bus():
    """A DAQ list on the control period's event: one sample every 10 ms of TCU time, none missed, and its
    T_CL_Pred is TCU_STATUS's T_CL_Pred of the same period (within the signal's step); the run's frames are those
    of a run nobody measures."""
    policy = Samples([daq_list("t_ms", "T_CL_Pred", "State")])
    with xcp_tcu(policy) as (master, tcu, bus):
        policy.setup()
        policy.start()
        frames = run_frames(bus, duration=2.0)
        drain(policy, tcu)
    times = [row["t_ms"] for row in policy.rows]
    assert times == list(range(0, 2000, 10))
    by_time = {row["t_ms"]: row for row in policy.rows}
    status = [(round(t * 1000), STATUS.decode(data)) for frame_id, data, t in frames if frame_id == STATUS.frame_id]
    assert len(status) == 20
    step = STATUS.get_signal_by_name("T_CL_Pred").scale
    for t_ms, signals in status:
        assert abs(by_time[t_ms]["T_CL_Pred"] - signals["T_CL_Pred"]) <= step / 2 + 1e-4, t_ms
        assert STATES[by_time[t_ms]["State"]] == str(signals["State"])
    assert max(row["T_CL_Pred"] for row in policy.rows) > min(row["T_CL_Pred"] for row in policy.rows) + 1.0


def test_the_state_and_clutch_are_the_a2l_s_on_a_matrix_numbering_them_otherwise(tmp_path):
    """dct_fd renumbered (CREEP is its 'Creeping' = 3, CL its 'ClutchA' = 0), its binding naming them
    (tests/sim/test_second_matrix.py): the TCU_Info frames carry the matrix's numbers, XCP's State and ActiveClutch
    the TCU's own, the ones the A2L's value tables name: at each status frame the A2L's name of the DAQ sample is
    the state the frame's name stands for (a run through IDLE, ENGAGE and CREEP, both clutches' names)."""
    from tests.sim.test_second_matrix import renumbered

    dbc, binding_file = renumbered(tmp_path)
    binding = load_binding(binding_file, dbc=dbc)
    tables = {m.name: dict(m.names) for m in MEASUREMENTS if m.names}
    assert tables == {"State": {n: s for s, n in STATE_VALUES.items()},
                      "ActiveClutch": {n: s for s, n in CLUTCH_VALUES.items()}}
    a2l = a2l_text()
    for name, table in tables.items():  # the A2L's value tables are these
        pairs = " ".join(f'{n} "{s}"' for n, s in sorted(table.items()))
        assert f"/begin COMPU_VTAB VT_{name} " in a2l and f" {pairs} " in a2l
    policy = Samples([daq_list("t_ms", "State", "ActiveClutch")])
    with xcp_tcu(policy, binding) as (master, tcu, bus):
        policy.setup()
        policy.start()
        frames = run_frames(bus, duration=2.0, dbc=str(dbc), binding=str(binding_file))
        drain(policy, tcu)
    by_time = {row["t_ms"]: row for row in policy.rows}
    info = binding.db.get_message_by_name("TCU_Info")
    # the matrix's name of each of the TCU's states and clutches (the binding's values)
    theirs = {signal: {str(info.get_signal_by_name(signal).choices[binding.values[quantity][n]]): ours
                       for ours, n in numbers.items()}
              for signal, quantity, numbers in (("GbxState", "tcu_state", STATE_VALUES),
                                                ("ActClutch", "active_clutch", CLUTCH_VALUES))}
    seen = []
    for frame_id, data, t in frames:
        if frame_id != info.frame_id:
            continue
        signals, row = info.decode(data), by_time[round(t * 1000)]
        state, clutch = theirs["GbxState"][str(signals["GbxState"])], theirs["ActClutch"][str(signals["ActClutch"])]
        assert (tables["State"][row["State"]], tables["ActiveClutch"][row["ActiveClutch"]]) == (state, clutch), t
        seen.append((state, clutch, info.get_signal_by_name("GbxState").choice_to_number(signals["GbxState"]),
                     row["State"]))
    assert len(seen) == 20 and {s for s, *_ in seen} >= {"IDLE", "ENGAGE", "CREEP"}
    assert {c for _, c, *_ in seen} >= {"NONE", "CL"}
    assert any(number != ours for *_, number, ours in seen)  # the frame's number is not the TCU's


def test_a_calibration_value_changed_at_run_time_changes_the_tcus_behaviour(quiet):
    """T_safe lowered to 100 degC at 1.5 s, while CL creeps with its plate above it: the first period that runs
    with the new value (its thermal margin T_safe - bound moves by the change) stops the vehicle (the monitor's
    bound passes T_safe: STOPPED_OVERHEAT), and TCU_STATUS says so; the run unchanged stays in CREEP."""
    policy = Samples([daq_list("t_ms", "State", "Margin_CL", "Bound_CL", "T_CL_Pred")])
    with xcp_tcu(policy) as (master, tcu, bus):
        policy.setup()
        policy.start()

        def change(runner):
            if runner.tick == 150:
                write_double(master, T_SAFE.address, 100.0)

        frames = run_frames(bus, on_period=change, duration=2.0)
        drain(policy, tcu)
        assert read_double(master, T_SAFE.address) == 100.0
    assert tcu.controller.cal.strategy.T_safe_c == 100.0
    rows = policy.rows
    old = load_calibration().strategy.T_safe_c
    first = next(i for i, r in enumerate(rows) if abs(r["Margin_CL"] - (100.0 - r["Bound_CL"])) < 1e-3)
    assert all(abs(r["Margin_CL"] - (old - r["Bound_CL"])) < 1e-3 for r in rows[:first])
    assert 1490 <= rows[first]["t_ms"] <= 1520
    assert {STATES[r["State"]] for r in rows[first - 20:first]} == {"CREEP"} and rows[first - 1]["T_CL_Pred"] > 100
    assert rows[first]["Bound_CL"] > 100.0 and STATES[rows[first]["State"]] == "STOPPED_OVERHEAT"
    changed = rows[first]["t_ms"] / 1000.0
    assert [f for f in frames if f[2] < changed] == [f for f in quiet if f[2] < changed]  # the same run up to then

    def states(run, after):
        return {str(STATUS.decode(d)["State"]) for i, d, t in run if i == STATUS.frame_id and after < t < 2.0}

    assert states(frames, changed) == {"STOPPED_OVERHEAT"} and states(quiet, changed) == {"CREEP"}


def test_an_out_of_limits_download_is_refused_and_nothing_changes(quiet):
    """T_safe of 50 degC (its limits: 100-400) at 1.5 s: an error packet (ERR_OUT_OF_RANGE), the value and the
    controller as they were, and the run's frames those of the run nobody talked to, bit for bit."""
    with xcp_tcu() as (master, tcu, bus):
        refused = []

        def change(runner):
            if runner.tick == 150:
                with pytest.raises(XcpResponseError) as exc:
                    write_double(master, T_SAFE.address, 50.0)
                refused.append(exc.value)

        frames = run_frames(bus, on_period=change)
        value = read_double(master, T_SAFE.address)
    assert refused and "OUT_OF_RANGE" in str(refused[0])
    assert value == tcu.controller.cal.strategy.T_safe_c == load_calibration().strategy.T_safe_c
    assert tcu.xcp.errors == 1 and tcu.xcp.memory.changes == 0
    assert frames == quiet


def test_lockstep_frames_bit_for_bit_with_the_slave_idle(quiet):
    def with_slave(db, bus):
        return TcuRunner(Codec(db, TCU_USES), bus, xcp=xcp_slave())

    assert run_frames(tcu=with_slave) == quiet


@pytest.mark.slow
def test_the_a2l_parses_with_pya2ldb_and_lists_the_memory_map(tmp_path):
    pya2l = pytest.importorskip("pya2l", reason="the A2L reader of the tests (extra 'xcp')")
    from pya2l import model

    path = tmp_path / "ecu_stub.a2l"
    path.write_text(a2l_text(0x123, 0x124, "1.2.3"), encoding="latin-1")
    session = pya2l.import_a2l(str(path), in_memory=True, progress_bar=False, loglevel="ERROR")
    measurements = {m.name: m for m in session.query(model.Measurement).all()}
    assert set(measurements) == set(ADDRESS)
    for m in MEASUREMENTS:
        assert (measurements[m.name].datatype, measurements[m.name].ecu_address.address) == (m.datatype, m.address)
    characteristics = {c.name: c for c in session.query(model.Characteristic).all()}
    assert set(characteristics) == {symbol(v.name) for v in cal_values()}
    units = {c.name: c.unit for c in session.query(model.CompuMethod).all()}
    methods = {c.name: c for c in session.query(model.CompuMethod).all()}
    tables = {t.name: {int(p.inVal): p.outVal for p in t.pairs} for t in session.query(model.CompuVtab).all()}
    for m in MEASUREMENTS:  # the state and the clutch by the TCU's names, the numbers its UDS DIDs give
        method = methods[measurements[m.name].conversion]
        if m.names:
            assert method.conversionType == "TAB_VERB" and tables[method.compu_tab_ref.conversionTable] == dict(m.names)
        else:
            assert method.conversionType == "IDENTICAL"
    assert dict(next(m for m in MEASUREMENTS if m.name == "State").names) == {n: s for s, n in STATE_VALUES.items()}
    for v in cal_values():
        c = characteristics[symbol(v.name)]
        assert (c.address, c.lowerLimit, c.upperLimit, units[c.conversion]) == (v.address, v.lo, v.hi, v.unit)
        assert bool(c.read_only) == v.read_only
    if_data = " ".join(i.raw for i in session.query(model.IfData).all())
    assert "CAN_ID_MASTER 0x123 CAN_ID_SLAVE 0x124" in if_data and '/begin EVENT "control period"' in if_data
    assert CAL_BASE == min(v.address for v in cal_values())


@pytest.mark.slow
def test_the_ecu_stub_process_serves_xcp_and_writes_its_a2l(tmp_path):
    """``ecu-stub --xcp`` on udp_multicast with other IDs (its receive filters pass the master's): pyxcp connects
    and reads a calibration value; ``ecu-stub --a2l`` writes the A2L of those IDs and exits 0."""
    ids = "0x6F0,0x6F1"
    a2l = tmp_path / "tcu.a2l"
    assert subprocess.run([sys.executable, "-m", "ecu_stub", "--a2l", str(a2l), "--xcp-ids", ids],
                          capture_output=True, timeout=60).returncode == 0
    assert "CAN_ID_MASTER 0x6F0 CAN_ID_SLAVE 0x6F1" in a2l.read_text(encoding="latin-1")
    bus = {"interface": UDP_MULTICAST, **fresh_udp_group()}
    proc = subprocess.Popen([sys.executable, "-m", "ecu_stub", *bus_args(bus), "--xcp", "--xcp-ids", ids,
                             "--duration", "60"], stderr=subprocess.PIPE, text=True)
    try:
        assert "XCP slave on CAN, master 0x6F0, slave 0x6F1" in "".join(proc.stderr.readline() for _ in range(2))
        with pyxcp_master(bus, ids=(0x6F0, 0x6F1)) as master:
            assert master.identifier(1) == "ecu_stub"
            assert read_double(master, T_SAFE.address) == load_calibration().strategy.T_safe_c
    finally:
        proc.terminate()
        proc.communicate(timeout=30)


# -- the slave's answers to bad requests (no bus)
@pytest.fixture
def slave():
    runner = SimpleNamespace(controller=CreepController(), states={"IDLE": 0}, clutches={"NONE": 0})
    return XcpSlave(tcu_memory(runner), CRO, DTO, lambda frame_id, data: None)


@pytest.mark.parametrize("request_, error", [
    (b"\xc9", 0x20),  # a command it does not know: ERR_CMD_UNKNOWN
    (b"\xf6\x00\x00\x00\x00\x00", 0x21),  # SET_MTA without its address: ERR_CMD_SYNTAX
    (b"\xf4\x04\x00\x00\x00\x00\x05\x00", 0x22),  # SHORT_UPLOAD from 0x50000: outside the map
    (b"\xf4\x08\x00\x00\x00\x00\x01\x00", 0x22),  # 8 bytes: more than a response carries
    (b"\xf4\x04\x00\x01\x00\x00\x01\x00", 0x22),  # address extension 1
    (b"\xfc", 0x00),  # SYNCH: ERR_CMD_SYNCH
    (b"\xef\x02\x00\x00", 0x20),  # DOWNLOAD_NEXT: no block mode
    (b"\xf0\x07\x00\x00\x00\x00\x00\x00", 0x22),  # DOWNLOAD of 7 bytes: more than a packet carries
    (b"\xf0\x04\x00\x00", 0x21),  # DOWNLOAD of 4 bytes carrying 2
    (b"\xd4\x00\x00\x00\x01", 0x29),  # ALLOC_ODT before ALLOC_DAQ
    (b"\xe1\xff\x04\x00\x00\x00\x02\x00", 0x29),  # WRITE_DAQ without SET_DAQ_PTR
    (b"\xde\x01\x00\x00", 0x22),  # START_STOP_DAQ_LIST of a list that is not there
])
def test_bad_requests_get_error_packets(slave, request_, error):
    assert slave.handle(b"\xff\x00")[0] == 0xFF  # CONNECT
    assert slave.handle(request_) == bytes((0xFE, error))


def test_writes_outside_the_calibration_are_refused(slave):
    slave.handle(b"\xff\x00")
    assert slave.handle(b"\xf6\x00\x00\x00" + struct.pack("<I", MEAS_BASE)) == b"\xff"  # SET_MTA
    assert slave.handle(b"\xf0\x04\x00\x00\x00\x00") == b"\xfe\x23"  # measurements: ERR_WRITE_PROTECTED
    read_only = CAL["vehicle.input_ratio"]
    assert slave.handle(b"\xf6\x00\x00\x00" + struct.pack("<I", read_only.address)) == b"\xff"
    assert slave.handle(b"\xf0\x02\x00\x00") == b"\xfe\x23"
    assert slave.handle(b"\xf6\x00\x00\x00" + struct.pack("<I", 0x30000)) == b"\xff"
    assert slave.handle(b"\xf0\x02\x00\x00") == b"\xfe\x22"  # not mapped


def test_a_value_written_in_two_downloads_is_taken_when_whole(slave):
    """A double comes in two DOWNLOADs (6 + 2 bytes): taken with the second, checked then."""
    slave.handle(b"\xff\x00")
    cal = slave.memory.controller().cal
    ki = CAL["speed.ki_n_per_m"]
    data = struct.pack("<d", 1234.5)
    assert slave.handle(b"\xf6\x00\x00\x00" + struct.pack("<I", ki.address)) == b"\xff"
    assert slave.handle(b"\xf0\x06" + data[:6]) == b"\xff"
    assert slave.memory.controller().cal is cal  # not yet
    assert slave.handle(b"\xf0\x02" + data[6:]) == b"\xff"
    assert slave.memory.controller().cal.speed.ki_n_per_m == 1234.5 == slave.memory.controller().pid.ki
    bad = struct.pack("<d", float("nan"))
    slave.handle(b"\xf6\x00\x00\x00" + struct.pack("<I", ki.address))
    assert slave.handle(b"\xf0\x06" + bad[:6]) == b"\xff"
    assert slave.handle(b"\xf0\x02" + bad[6:]) == b"\xfe\x22"
    assert slave.memory.controller().cal.speed.ki_n_per_m == 1234.5


def test_a_disconnected_slave_answers_connect_only(slave):
    assert slave.handle(b"\xfd") is None and slave.handle(b"\xc9") is None
    assert slave.handle(b"\xff\x00")[0] == 0xFF and slave.handle(b"\xfd")[0] == 0xFF
    assert slave.handle(b"\xfe") == b"\xff" and slave.handle(b"\xfd") is None
    assert slave.handle(b"") is None
