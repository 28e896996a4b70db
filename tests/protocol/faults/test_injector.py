"""Each fault changes the frames as specified, and the receiver's protection detects it by the right cause."""

from __future__ import annotations

import can
import pytest

from dsg_hil.protocol.faults import FaultError, FaultInjector, FaultyBus, bridge_step, outside_range, parse_fault
from dsg_hil.protocol import Codec, RxMonitor, TxScheduler, load_dbc

USES = {"TCU_CMD": ("P_CL_Cmd", "P_CH_Cmd", "SyncEcho"), "PLANT_VEHICLE": ("VehicleSpeed", "TransOutputSpeed"),
        "PLANT_OIL_TEMP": ("T_OilCL", "T_OilCH", "T_Sump"), "PLANT_SPEEDS": ("ClutchInputSpeed",)}


@pytest.fixture(scope="module")
def db():
    return load_dbc()


@pytest.fixture()
def codec(db):
    return Codec(db, USES)


def frames(codec, name, n, values, t0=0.0):
    tx = TxScheduler(codec, [name])
    period = codec.cycle_time(name)
    return [(t0 + k * period, tx.frame(name, values, timestamp=t0 + k * period)) for k in range(n)]


def through(injector, stream):
    out = []
    for t, msg in stream:
        out += injector.release(t) + injector.apply(msg, t)
    return out


def receive_all(codec, names, msgs):
    rx = RxMonitor(codec, names)
    accepted = [f for m in msgs if (f := rx.receive(m, m.timestamp)) is not None]
    return rx, accepted


CMD = {"P_CL_Cmd": 0.5, "P_CH_Cmd": 0.0, "SyncEcho": 0}


def test_no_fault_outside_the_window(db, codec):
    stream = frames(codec, "TCU_CMD", 20, CMD)
    inj = FaultInjector(db, [parse_fault("corrupt_crc:TCU_CMD@1-2")])
    out = through(inj, stream)
    assert [bytes(m.data) for m in out] == [bytes(m.data) for _, m in stream] and inj.injected == 0


def test_drop_in_window_is_seen_as_lost_frames(db, codec):
    stream = frames(codec, "TCU_CMD", 20, CMD)
    inj = FaultInjector(db, [parse_fault("drop:TCU_CMD@0.05-0.07")])  # 2 frames: t = 0.05, 0.06
    out = through(inj, stream)
    assert len(out) == 18 and inj.counts["drop:TCU_CMD@0.05-0.07"] == 2
    rx, accepted = receive_all(codec, ["TCU_CMD"], out)
    state = rx.states["TCU_CMD"]
    assert len(accepted) == 18 and state.counter_jumps == 1 and state.lost == 2  # detected by the counter


def test_longer_drop_times_the_message_out(db, codec):
    out = through(FaultInjector(db, [parse_fault("drop:TCU_CMD@0.05-0.1")]), frames(codec, "TCU_CMD", 20, CMD))
    before, _ = receive_all(codec, ["TCU_CMD"], [m for m in out if m.timestamp < 0.05])
    assert before.valid("TCU_CMD", 0.07) and not before.valid("TCU_CMD", 0.08)  # 3 cycles without one: invalid
    rx, accepted = receive_all(codec, ["TCU_CMD"], out)
    assert len(accepted) == 15 and rx.rejected_total == 0  # the first frame after the timeout resynchronises


def test_probability_is_deterministic_for_a_seed(db, codec):
    stream = frames(codec, "TCU_CMD", 200, CMD)
    runs = [through(FaultInjector(db, [parse_fault("drop:TCU_CMD,probability=0.3")], seed=s), stream)
            for s in (7, 7, 8)]
    assert [m.data for m in runs[0]] == [m.data for m in runs[1]]
    assert [m.data for m in runs[0]] != [m.data for m in runs[2]]
    assert 100 < len(runs[0]) < 180  # about 70 % kept


def test_duplicate_is_counted_as_a_duplicate_and_ignored(db, codec):
    stream = frames(codec, "TCU_CMD", 5, CMD)
    out = through(FaultInjector(db, [parse_fault("duplicate:TCU_CMD@0.02-0.03")]), stream)
    assert len(out) == 6
    rx, accepted = receive_all(codec, ["TCU_CMD"], out)
    assert len(accepted) == 5 and rx.states["TCU_CMD"].duplicates == 1 and rx.rejected_total == 0


def test_delay_holds_frames_until_due(db, codec):
    stream = frames(codec, "TCU_CMD", 10, CMD)
    inj = FaultInjector(db, [parse_fault("delay:TCU_CMD@0.02-0.03,delay_s=0.035")])
    out = through(inj, stream)
    assert len(out) == 10  # the frame of 0.02 is due at 0.055: it goes out just before the frame of 0.06
    counters = [codec.decode(m.arbitration_id, bytes(m.data)).counter for m in out]
    assert counters == [0, 1, 3, 4, 5, 2, 6, 7, 8, 9]
    assert inj.release(10.0) == []


def test_corrupt_crc_detected_as_crc(db, codec):
    out = through(FaultInjector(db, [parse_fault("corrupt_crc:TCU_CMD@0.03-0.05")]), frames(codec, "TCU_CMD", 8, CMD))
    rx, accepted = receive_all(codec, ["TCU_CMD"], out)
    assert rx.rejected["crc"] == 2 and len(accepted) == 6


def moving_commands(codec, n):
    tx, period = TxScheduler(codec, ["TCU_CMD"]), codec.cycle_time("TCU_CMD")
    return [(k * period, tx.frame("TCU_CMD", {**CMD, "P_CL_Cmd": 0.1 + 0.01 * k}, timestamp=k * period))
            for k in range(n)]


def test_frozen_counter_detected_as_counter(db, codec):
    out = through(FaultInjector(db, [parse_fault("freeze_counter:TCU_CMD@0.03-0.07")]), moving_commands(codec, 10))
    rx, accepted = receive_all(codec, ["TCU_CMD"], out)
    assert rx.rejected["counter"] == 3 and rx.rejected["crc"] == 0  # the CRC was recomputed: only the counter
    assert len(accepted) == 7


def test_frozen_sender_with_frozen_data_times_out(db, codec):
    """A sender stuck on one frame repeats it byte for byte: duplicates, never taken, so the message times out."""
    out = through(FaultInjector(db, [parse_fault("freeze_counter:TCU_CMD@0.03-")]), frames(codec, "TCU_CMD", 10, CMD))
    rx, accepted = receive_all(codec, ["TCU_CMD"], out)
    assert len(accepted) == 4 and rx.states["TCU_CMD"].duplicates == 6 and not rx.valid("TCU_CMD", 0.09)


def test_out_of_range_detected_as_range_with_valid_crc(db, codec):
    out = through(FaultInjector(db, [parse_fault("out_of_range:TCU_CMD.P_CL_Cmd@0-0.02")]),
                  frames(codec, "TCU_CMD", 4, CMD))
    rx, accepted = receive_all(codec, ["TCU_CMD"], out)
    assert rx.rejected["range"] == 2 and rx.rejected["crc"] == 0 and len(accepted) == 2


def test_out_of_range_value_is_representable_and_outside(db):
    signal = db.get_message_by_name("TCU_CMD").get_signal_by_name("P_CL_Cmd")
    assert outside_range(signal) == pytest.approx(1.5001)
    counter = db.get_message_by_name("TCU_CMD").get_signal_by_name("Counter")
    with pytest.raises(ValueError, match="cannot carry"):
        outside_range(counter)


def test_wrong_dlc_detected_as_dlc(db, codec):
    out = through(FaultInjector(db, [parse_fault("wrong_dlc:TCU_CMD@0-0.01,dlc=6")]), frames(codec, "TCU_CMD", 3, CMD))
    assert [len(m.data) for m in out] == [6, 8, 8]
    rx, _ = receive_all(codec, ["TCU_CMD"], out)
    assert rx.rejected["dlc"] == 1


def test_stuck_and_offset_pass_protection_with_wrong_values(db, codec):
    values = {"VehicleSpeed": 0.1, "TransOutputSpeed": 100.0}
    stream = frames(codec, "PLANT_VEHICLE", 4, values)
    inj = FaultInjector(db, [parse_fault("stuck:PLANT_VEHICLE.VehicleSpeed,value=0"),
                             parse_fault("offset:PLANT_VEHICLE.TransOutputSpeed,value=25")])
    rx, accepted = receive_all(codec, ["PLANT_VEHICLE"], through(inj, stream))
    assert rx.rejected_total == 0 and len(accepted) == 4  # undetectable by CRC and counter ...
    assert all(f.values["VehicleSpeed"] == 0.0 for f in accepted)  # ... the values are wrong
    assert all(f.values["TransOutputSpeed"] == pytest.approx(125.0) for f in accepted)


def test_a_gain_multiplies_the_physical_value_and_passes_protection(db, codec):
    """``value`` multiplies the physical value (not the raw bits: T_OilCL's DBC offset is -40 degC), frame by frame,
    in the window only, with a valid CRC and counter."""
    stream = frames(codec, "PLANT_OIL_TEMP", 2, {"T_OilCL": 200.0, "T_OilCH": 150.0, "T_Sump": 100.0}) + \
        frames(codec, "PLANT_OIL_TEMP", 2, {"T_OilCL": 100.0, "T_OilCH": 150.0, "T_Sump": 100.0}, t0=1.0)
    inj = FaultInjector(db, [parse_fault("gain:PLANT_OIL_TEMP.T_OilCL@0-1.05,value=0.9")])
    rx, accepted = receive_all(codec, ["PLANT_OIL_TEMP"], through(inj, stream))
    assert rx.rejected_total == 0 and len(accepted) == 4
    assert [f.values["T_OilCL"] for f in accepted] == pytest.approx([180.0, 180.0, 90.0, 100.0])
    assert all(f.values["T_OilCH"] == pytest.approx(150.0) for f in accepted)  # the other signals untouched
    negative = FaultInjector(db, [parse_fault("gain:PLANT_SPEEDS.ClutchInputSpeed,value=-2")])
    _, got = receive_all(codec, ["PLANT_SPEEDS"], through(negative, frames(codec, "PLANT_SPEEDS", 1,
                                                                             {"ClutchInputSpeed": 150.0})))
    assert got[0].values["ClutchInputSpeed"] == pytest.approx(-300.0)


def test_a_gain_pushing_one_value_off_its_bits_is_counted_and_that_frame_sent_unchanged(db, codec):
    stream = frames(codec, "PLANT_VEHICLE", 2, {"VehicleSpeed": 1.0}) + \
        frames(codec, "PLANT_VEHICLE", 1, {"VehicleSpeed": 20.0}, t0=1.0)
    spec = parse_fault("gain:PLANT_VEHICLE.VehicleSpeed,value=2")
    inj = FaultInjector(db, [spec])
    out = through(inj, stream)
    assert out[2].data == stream[2][1].data
    _, accepted = receive_all(codec, ["PLANT_VEHICLE"], out)
    assert [f.values["VehicleSpeed"] for f in accepted] == pytest.approx([2.0, 2.0, 20.0])
    assert inj.encode_errors[spec.describe()] == 1


def test_flood_adds_unknown_ids_the_receiver_ignores(db, codec):
    inj = FaultInjector(db, [parse_fault("flood@0-1,rate=50")])
    out = through(inj, frames(codec, "TCU_CMD", 10, CMD))
    assert len(out) == 10 * 51 and sum(m.arbitration_id == 0x5A5 for m in out) == 500
    rx, accepted = receive_all(codec, ["TCU_CMD"], out)
    assert len(accepted) == 10 and rx.rejected_total == 0


def test_faulty_bus_and_bridge_on_virtual(db, codec):
    channel = "faults-test"
    a, b, c = (can.Bus(interface="virtual", channel=channel) for _ in range(3))
    try:
        now = [0.0]
        faulty = FaultyBus(a, FaultInjector(db, [parse_fault("corrupt_crc:TCU_CMD@0-0.015")]), clock=lambda: now[0])
        for t, msg in frames(codec, "TCU_CMD", 3, CMD):
            now[0] = t
            faulty.send(msg)
        got = [b.recv(1.0) for _ in range(3)]
        rx, accepted = receive_all(codec, ["TCU_CMD"], got)
        assert rx.rejected["crc"] == 2 and len(accepted) == 1
        # a bridge from b's side to a second channel, with a drop on the way
        other = can.Bus(interface="virtual", channel="faults-test-2")
        sink = can.Bus(interface="virtual", channel="faults-test-2")
        try:
            for _, msg in frames(codec, "TCU_CMD", 4, CMD):
                c.send(msg)
            sent = bridge_step(b, sink, FaultInjector(db, [parse_fault("drop:TCU_CMD")]), 0.0, timeout=0.5)
            assert sent == 0 and other.recv(0.1) is None
        finally:
            other.shutdown()
            sink.shutdown()
    finally:
        faulty.shutdown()
        b.shutdown()
        c.shutdown()


@pytest.mark.parametrize("text, words", [
    ("stuck:PLANT_VEHICLE.VehicleSpeed@1-2,value=1000", "stuck value 1000 m/s cannot be encoded in "
     "PLANT_VEHICLE.VehicleSpeed: its bits carry -32.768 to 32.767 m/s (DBC range -30 to 30 m/s)"),
    ("offset:TCU_CMD.P_CL_Cmd@1-2,value=-7", "offset value -7 MPa cannot be encoded in TCU_CMD.P_CL_Cmd: its bits "
     "carry 0 to 6.5535 MPa"),
    ("gain:PLANT_PRESSURE.P_CL,value=1e5", "gain value 100000 cannot be encoded in PLANT_PRESSURE.P_CL: it takes one "
     "step of 0.0001 MPa to 10 MPa, beyond all its bits carry (0 to 6.5535 MPa)"),
])
def test_a_value_the_dbc_cannot_encode_is_refused_before_any_frame(db, text, words):
    """Not at the first frame in the window, mid-run, with cantools' bare 'out of range' (issue 20, item 2)."""
    with pytest.raises(FaultError) as info:
        FaultInjector(db, [parse_fault(text)])
    assert str(info.value).startswith(f"--fault {text!r}: {words}")


def test_an_offset_pushing_one_value_off_its_bits_is_counted_and_that_frame_sent_unchanged(db, codec):
    """An offset fine for most values but not for this one (30 + 5 m/s > 32.767): the frame goes out as it was,
    valid, and is counted in ``encode_errors``; the sender never dies of it."""
    stream = frames(codec, "PLANT_VEHICLE", 3, {"VehicleSpeed": 1.0}) + \
        frames(codec, "PLANT_VEHICLE", 2, {"VehicleSpeed": 30.0}, t0=1.0)
    spec = parse_fault("offset:PLANT_VEHICLE.VehicleSpeed,value=5")
    inj = FaultInjector(db, [spec])
    out = through(inj, stream)
    assert [m.data for m in out[3:]] == [m.data for _, m in stream[3:]]  # unchanged
    rx, accepted = receive_all(codec, ["PLANT_VEHICLE"], out)
    assert [f.values["VehicleSpeed"] for f in accepted] == pytest.approx([6.0, 6.0, 6.0, 30.0, 30.0])
    assert inj.counts[spec.describe()] == 5 and inj.encode_errors[spec.describe()] == 2
    assert "(2 not encodable: sent unchanged)" in inj.hits()
