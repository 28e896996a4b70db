"""CAN FD from the database: the shipped DBC with three messages made CAN FD in its text (VFrameFormat, CANFD_BRS),
one of them 10 bytes long (sent in a 12-byte frame), runs the creep in lock-step through python-can's ``virtual``
interface with every frame in its message's format; the logs keep the frames' format and decode; a frame of the
wrong format is rejected; faults hit CAN FD frames as classic ones."""

from __future__ import annotations

import re
from pathlib import Path

import can
import pytest

from dsg_hil.protocol import Codec, load_dbc
from dsg_hil.protocol.bus import FrameLog, has_fd, open_bus
from dsg_hil.protocol.codec import DEFAULT_DBC, FrameError, bitrate_switch, frame_length
from dsg_hil.protocol.frame import FD_LENGTHS, data_frame, fd_length
from dsg_hil.protocol.logs import decoded_frames, log_codec
from dsg_hil.protocol.validity import NEW, REJECTED, RxMonitor
from dsg_hil.sim.plant_io import PLANT_USES
from dsg_hil.sim.run import RunConfig, open_run
from ecu_stub.runner import TCU_USES, TcuRunner

FD = {"PLANT_OIL_TEMP": (10, 1), "TCU_CMD": (8, 1), "PLANT_SPEEDS": (8, 0)}  # message: (length, CANFD_BRS)
IDS = {"PLANT_OIL_TEMP": 272, "TCU_CMD": 512, "PLANT_SPEEDS": 257}
FRAME_FORMAT = ('BA_DEF_ BO_ "VFrameFormat" ENUM "StandardCAN","ExtendedCAN","reserved","reserved","reserved",'
                '"reserved","reserved","reserved","reserved","reserved","reserved","reserved","reserved","reserved",'
                '"StandardCAN_FD","ExtendedCAN_FD";\nBA_DEF_ BO_ "CANFD_BRS" ENUM "0","1";\n')


def fd_dbc_text() -> str:
    """The shipped DBC's text with the messages of :data:`FD` CAN FD (their lengths and bit-rate switches)."""
    text = DEFAULT_DBC.read_text(encoding="utf-8")
    for name, (length, _) in FD.items():
        text, n = re.subn(rf"^BO_ (\d+) {name}: 8 ", rf"BO_ \1 {name}: {length} ", text, flags=re.M)
        assert n == 1
    text = text.replace('BA_DEF_ BO_ "GenMsgCycleTime"', FRAME_FORMAT + 'BA_DEF_ BO_ "GenMsgCycleTime"', 1)
    text = text.replace('BA_DEF_DEF_ "GenMsgCycleTime" 0;',
                        'BA_DEF_DEF_ "GenMsgCycleTime" 0;\nBA_DEF_DEF_ "VFrameFormat" "StandardCAN";\n'
                        'BA_DEF_DEF_ "CANFD_BRS" "1";', 1)
    attributes = "".join(f'BA_ "VFrameFormat" BO_ {IDS[name]} 14;\nBA_ "CANFD_BRS" BO_ {IDS[name]} {brs};\n'
                         for name, (_, brs) in FD.items())
    return text.replace('BA_ "GenMsgCycleTime" BO_ 256 10;', attributes + 'BA_ "GenMsgCycleTime" BO_ 256 10;', 1)


@pytest.fixture(scope="module")
def fd_dbc(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("fd") / "dsg_hil_fd.dbc"
    path.write_text(fd_dbc_text(), encoding="utf-8")
    return path


def test_fd_lengths_snap_to_the_dlc_table():
    assert [fd_length(n) for n in (0, 8, 9, 10, 12, 13, 33, 49, 64)] == [0, 8, 12, 12, 12, 16, 48, 64, 64]
    assert FD_LENGTHS[15] == 64 and len(FD_LENGTHS) == 16
    with pytest.raises(ValueError, match="at most 64"):
        fd_length(65)


def test_the_database_says_which_messages_are_fd_and_switch_the_bit_rate(fd_dbc):
    db = load_dbc(fd_dbc)
    fd = {m.name for m in db.messages if m.is_fd}
    assert fd == set(FD) and has_fd(db.messages) and not has_fd(load_dbc().messages)
    assert {name: bitrate_switch(db.get_message_by_name(name), db) for name in FD} == \
        {name: bool(brs) for name, (_, brs) in FD.items()}
    assert frame_length(db.get_message_by_name("PLANT_OIL_TEMP")) == 12
    codec = Codec(db, PLANT_USES)
    assert codec.fd == {IDS[name]: bool(brs) for name, (_, brs) in FD.items() if name in PLANT_USES}


@pytest.mark.parametrize("reference", [False, True])
def test_a_10_byte_fd_message_travels_in_a_12_byte_frame(fd_dbc, reference):
    db = load_dbc(fd_dbc)
    codec = Codec(db, PLANT_USES, reference=reference)
    values = {"T_OilCL": 95.5, "T_OilCH": 80.0, "T_Sump": 70.0, "T_RadiatorOut": 60.5}
    data = codec.encode("PLANT_OIL_TEMP", values, 3)
    assert len(data) == 12 and data[10:] == bytes(2)
    frame = codec.decode(IDS["PLANT_OIL_TEMP"], data)
    assert {k: frame.values[k] for k in values} == values and frame.counter == 3
    for length in (8, 10, 16):
        with pytest.raises(FrameError) as err:
            codec.decode(IDS["PLANT_OIL_TEMP"], data[:length].ljust(length, b"\0"))
        assert err.value.reason == "dlc"
    fused = codec.expression_encoder("PLANT_OIL_TEMP", ("a",), {"T_OilCL": "a", "T_OilCH": "80.0", "T_Sump": "70.0",
                                                                 "T_RadiatorOut": "60.5"})
    assert fused(95.5, 3) == data


def test_a_classic_message_over_8_bytes_is_refused(tmp_path):
    text = DEFAULT_DBC.read_text(encoding="utf-8").replace("BO_ 272 PLANT_OIL_TEMP: 8 ", "BO_ 272 PLANT_OIL_TEMP: 12 ")
    (tmp_path / "long.dbc").write_text(text, encoding="utf-8")
    with pytest.raises(Exception, match="PLANT_OIL_TEMP: 12 bytes on classic CAN"):
        Codec(load_dbc(tmp_path / "long.dbc"), PLANT_USES)


def test_a_frame_in_the_other_format_is_rejected(fd_dbc):
    db = load_dbc(fd_dbc)
    tcu_codec, plant_codec = Codec(db, TCU_USES), Codec(db, PLANT_USES)
    rx = RxMonitor(tcu_codec, ["PLANT_OIL_TEMP", "PLANT_ENGINE"])
    oil = plant_codec.encode("PLANT_OIL_TEMP", {}, 0)
    engine = plant_codec.encode("PLANT_ENGINE", {}, 0)
    assert rx.take(data_frame(272, oil, fd=plant_codec.fd), 0.0)[0] == NEW
    assert rx.take(data_frame(272, plant_codec.encode("PLANT_OIL_TEMP", {}, 1)), 0.0)[0] == REJECTED  # classic
    assert rx.take(data_frame(256, engine, fd={256: True}), 0.0)[0] == REJECTED  # FD frame of a classic message
    assert rx.take(data_frame(256, engine), 0.0)[0] == NEW
    assert rx.rejected == {"dlc": 2}


def _fd_run(dbc: Path, channel: str, tcus: list | None = None, **extra) -> tuple[dict, list[can.Message]]:
    tcus = tcus if tcus is not None else []

    def tcu(db, bus):
        tcus.append(TcuRunner(Codec(db, TCU_USES), bus))
        return tcus[-1]

    config = RunConfig(duration=3.0, dbc=dbc, capture=True, tcu=tcu, direct=False,
                       bus={"interface": "virtual", "channel": channel}, **extra)
    with open_run(config) as run:
        summary = run.run().as_json()
    return summary, run.frames


@pytest.fixture(scope="module")
def fd_runs(fd_dbc):
    with open_run(RunConfig(duration=3.0, capture=True)) as run:
        classic = run.run().as_json(), run.frames
    return classic, _fd_run(fd_dbc, "can-fd-run"), fd_dbc


def test_the_creep_runs_on_fd_frames_through_python_can(fd_runs):
    """Lock-step through python-can's ``virtual`` bus: every frame of an FD message is CAN FD (its bit-rate switch
    the DBC's, 12 bytes for the 10-byte message), every other classic; nothing rejected; the same creep as on
    classic frames, frame for frame the same data (but the 10-byte message's CRC, its padding)."""
    (classic, classic_frames), (summary, frames), fd_dbc = fd_runs
    db = load_dbc(fd_dbc)
    assert summary["frames"]["rejected"] == 0 and summary["frames"]["received"] > 300
    by_name = {}
    for msg in frames:
        name = db.get_message_by_frame_id(msg.arbitration_id).name
        by_name.setdefault(name, set()).add((msg.is_fd, msg.bitrate_switch, len(msg.data)))
    for name, kinds in by_name.items():
        length, brs = FD.get(name, (8, 0))
        assert kinds == ({(True, bool(brs), fd_length(length))} if name in FD else {(False, False, 8)}), name
    assert set(by_name) >= set(FD)
    def head(msg):  # the oil temperatures' CRC (byte 7) covers its 10 bytes: the signals' bytes compared
        return msg.arbitration_id, bytes(msg.data)[:7 if msg.arbitration_id == IDS["PLANT_OIL_TEMP"] else 8]
    assert [head(m) for m in frames] == [head(m) for m in classic_frames]
    for key in ("creep_time_s", "max_plate_temp_c", "phases"):
        assert summary[key] == classic[key], key


def test_the_in_process_bus_gives_the_same_fd_frames(fd_runs):
    """The direct in-process bus (frames handed over as ID and data) logs the frames python-can's carried."""
    (_, _), (summary, frames), fd_dbc = fd_runs
    with open_run(RunConfig(duration=3.0, dbc=fd_dbc, capture=True)) as run:
        direct = run.run().as_json()
    assert direct["frames"]["rejected"] == 0

    def key(msg):
        return msg.arbitration_id, msg.is_fd, msg.bitrate_switch, bytes(msg.data), msg.timestamp
    assert [key(m) for m in run.frames] == [key(m) for m in frames]


@pytest.mark.parametrize("suffix", [".asc", ".blf", ".log"])
def test_logs_keep_fd_frames_and_decode_them(fd_runs, tmp_path, suffix):
    (_, _), (_, frames), fd_dbc = fd_runs
    path = tmp_path / f"fd{suffix}"
    log = FrameLog(str(path), "vcan0")
    for msg in frames:
        log(msg)
    log.stop()
    with can.LogReader(str(path)) as reader:
        back = [m for m in reader if not m.is_error_frame]
    assert [(m.arbitration_id, m.is_fd, m.bitrate_switch, bytes(m.data)) for m in back] == \
        [(m.arbitration_id, m.is_fd, m.bitrate_switch, bytes(m.data)) for m in frames]
    counts: dict[str, int] = {}
    decoded = [frame for _, frame in decoded_frames(path, log_codec(load_dbc(fd_dbc)), counts)]
    assert counts == {"decoded": len(frames), "rejected": 0, "unknown": 0}
    assert {f.name for f in decoded if f is not None} >= set(FD)


@pytest.mark.parametrize("fault, cause", [("corrupt_crc:PLANT_OIL_TEMP@0.5-1", "crc"),
                                          ("freeze_counter:PLANT_OIL_TEMP@0.5-1", "counter")])
def test_faults_hit_fd_frames(fd_dbc, fault, cause):
    """A plant-side fault on the 12-byte CAN FD frame: the TCU rejects it for the fault's cause, and the frames
    stay CAN FD."""
    tcus: list[TcuRunner] = []
    summary, frames = _fd_run(fd_dbc, f"can-fd-{cause}", tcus, faults=[fault])
    oil = [m for m in frames if m.arbitration_id == IDS["PLANT_OIL_TEMP"]]
    assert oil and all(m.is_fd and len(m.data) == 12 for m in oil)
    rejected = tcus[-1].rx.states["PLANT_OIL_TEMP"].rejected
    assert set(rejected) == {cause} and rejected[cause] >= 5  # 0.5-1 s of a 100-ms message (and the re-sends)
    assert tcus[-1].rx.rejected_total == rejected[cause]


def test_open_bus_opens_an_fd_bus():
    bus = open_bus({"interface": "virtual", "channel": "fd-open"}, fd=True)
    try:
        assert bus.protocol == can.CanProtocol.CAN_FD
    finally:
        bus.shutdown()
    bus = open_bus({"interface": "virtual", "channel": "fd-open"})
    try:
        assert bus.protocol == can.CanProtocol.CAN_20
    finally:
        bus.shutdown()


def test_the_creep_runs_on_fd_frames_over_udp_multicast(fd_dbc):
    """The plant and a TCU (its own loop, on a thread) on two udp_multicast ends opened for CAN FD, in lock-step:
    nothing rejected on either side, and a third end hears every FD message as CAN FD frames of its length."""
    import threading

    from dsg_hil.physics.params import load_params
    from dsg_hil.physics.plant import Plant
    from dsg_hil.protocol.bus import UDP_MULTICAST, fresh_udp_group
    from dsg_hil.sim.plant_io import PLANT_RX
    from dsg_hil.sim.runner import PlantRunner
    from dsg_hil.sim.scenario import load_scenario
    from ecu_stub.runner import TCU_RX

    db = load_dbc(fd_dbc)
    config = {"interface": UDP_MULTICAST, **fresh_udp_group()}
    tap = open_bus(config, fd=True)
    plant_bus = open_bus(config, receive=[db.get_message_by_name(n) for n in PLANT_RX], fd=True)
    tcu_bus = open_bus(config, receive=[db.get_message_by_name(n) for n in TCU_RX], fd=True)
    tcu = TcuRunner(Codec(db, TCU_USES), tcu_bus)
    done, errors, heard = threading.Event(), [], []

    def serve():
        try:
            tcu.run(should_stop=done.is_set)
        except Exception as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    def listen():
        while not done.is_set():
            msg = tap.recv(0.1)
            if msg is not None:
                heard.append(msg)

    threads = [threading.Thread(target=serve, daemon=True), threading.Thread(target=listen, daemon=True)]
    for thread in threads:
        thread.start()
    runner = PlantRunner(Plant(load_params()), load_scenario().with_duration(1.0), Codec(db, PLANT_USES), plant_bus)
    try:
        runner.run_lockstep(reply_timeout=30.0)
    finally:
        done.set()
        for thread in threads:
            thread.join(10)
        for bus in (tap, plant_bus, tcu_bus):
            bus.shutdown()
    assert not errors
    assert runner.frames()["rejected"] == 0 and tcu.rx.rejected_total == 0 and runner.frames()["received"] >= 100
    kinds = {(m.arbitration_id, m.is_fd, m.bitrate_switch, len(m.data)) for m in heard if m.arbitration_id in
             IDS.values()}
    assert kinds == {(IDS[name], True, bool(brs), fd_length(length)) for name, (length, brs) in FD.items()}
