"""Codec round trips, counters, CRC, clamping and RX validity with explicit timestamps."""

from __future__ import annotations

import can
import pytest

from dsg_hil.protocol import Codec, FrameError, ProtocolError, RxMonitor, TxScheduler, crc8_j1850, load_dbc
from dsg_hil.protocol.codec import DEFAULT_DBC

USES = {"TCU_CMD": ("P_CL_Cmd", "P_CH_Cmd", "SyncEcho"), "PLANT_OIL_TEMP": ("T_OilCL", "T_Sump"),
        "PLANT_SPEEDS": ("ClutchInputSpeed",)}


@pytest.fixture(scope="module")
def codec():
    return Codec(load_dbc(), USES)


def test_crc8_sae_j1850_check_value():
    assert crc8_j1850(b"123456789") == 0x4B


def test_round_trip_within_resolution(codec):
    data = codec.encode("TCU_CMD", {"P_CL_Cmd": 0.4321, "P_CH_Cmd": 0.0, "SyncEcho": 7}, counter=5)
    frame = codec.decode(codec.frame_id("TCU_CMD"), data)
    assert frame.name == "TCU_CMD" and frame.counter == 5
    assert frame.values["P_CL_Cmd"] == pytest.approx(0.4321, abs=1e-4) and frame.values["SyncEcho"] == 7
    speeds = codec.decode(codec.frame_id("PLANT_SPEEDS"),
                          codec.encode("PLANT_SPEEDS", {"ClutchInputSpeed": -123.45}, 0))
    assert speeds.values["ClutchInputSpeed"] == pytest.approx(-123.4, abs=0.051)


def test_encode_clamps_to_dbc_range_and_fills_defaults(codec):
    data = codec.encode("TCU_CMD", {"P_CL_Cmd": 7.0, "P_CH_Cmd": -1.0, "SyncEcho": float("nan")}, 0)
    v = codec.decode(codec.frame_id("TCU_CMD"), data).values
    assert v["P_CL_Cmd"] == 1.5 and v["P_CH_Cmd"] == 0.0 and v["SyncEcho"] == 0.0
    temps = codec.decode(codec.frame_id("PLANT_OIL_TEMP"), codec.encode("PLANT_OIL_TEMP", {"T_OilCL": 500.0}, 0))
    assert temps.values["T_OilCL"] == pytest.approx(369.5) and temps.values["T_Sump"] == pytest.approx(25.0)


@pytest.mark.parametrize("mutate, reason", [
    (lambda d: d[:7], "dlc"),
    (lambda d: d[:3] + bytes([d[3] ^ 0x01]) + d[4:], "crc"),
])
def test_bad_frames_are_rejected_with_reason(codec, mutate, reason):
    data = codec.encode("TCU_CMD", {"P_CL_Cmd": 0.5}, 1)
    with pytest.raises(FrameError) as err:
        codec.decode(codec.frame_id("TCU_CMD"), mutate(data))
    assert err.value.reason == reason


def test_out_of_range_raw_value_is_rejected(codec):
    raw = bytearray(codec.encode("TCU_CMD", {}, 0))
    raw[0], raw[1] = 0xFF, 0xFF  # P_CL_Cmd raw 65535 = 6.55 MPa > 1.5
    raw = codec.protection("TCU_CMD").seal(raw)
    with pytest.raises(FrameError) as err:
        codec.decode(codec.frame_id("TCU_CMD"), bytes(raw))
    assert err.value.reason == "range"


def test_missing_message_or_signal_fails_at_start_up():
    db = load_dbc()
    with pytest.raises(ProtocolError, match="message NOPE"):
        Codec(db, {"NOPE": ()})
    with pytest.raises(ProtocolError, match="TCU_CMD.P_XX"):
        Codec(db, {"TCU_CMD": ("P_XX",)})
    with pytest.raises(ProtocolError, match="not found"):
        load_dbc("/nonexistent.dbc")


def msg(codec, name, counter, values=None):
    return can.Message(arbitration_id=codec.frame_id(name), data=codec.encode(name, values or {}, counter),
                       is_extended_id=False)


def test_rx_validity_deadline_and_counters(codec):
    rx = RxMonitor(codec, ["TCU_CMD"])
    period = codec.cycle_time("TCU_CMD")
    assert period == pytest.approx(0.010)
    assert not rx.valid("TCU_CMD", 0.0)
    assert rx.receive(msg(codec, "TCU_CMD", 0, {"P_CL_Cmd": 0.3}), now=1.000)
    assert rx.valid("TCU_CMD", 1.000 + 3 * period) and not rx.valid("TCU_CMD", 1.000 + 3 * period + 1e-6)
    assert rx.receive(msg(codec, "TCU_CMD", 0), now=1.010) is None  # repeated counter: frozen sender
    assert rx.rejected["counter"] == 1 and rx.values("TCU_CMD")["P_CL_Cmd"] == pytest.approx(0.3)
    assert rx.receive(msg(codec, "TCU_CMD", 3), now=1.020)  # two frames lost: accepted, counted
    assert rx.states["TCU_CMD"].counter_jumps == 1
    bad = msg(codec, "TCU_CMD", 4)
    bad.data[7] ^= 0xFF
    assert rx.receive(bad, now=1.030) is None and rx.rejected["crc"] == 1
    other = can.Message(arbitration_id=0x123, data=bytes(8), is_extended_id=False)
    assert rx.receive(other, now=1.04) is None and rx.rejected_total == 2  # not ours: ignored, not rejected


def test_tx_scheduler_absolute_deadlines_and_counter_wrap(codec):
    tx = TxScheduler(codec, ["TCU_CMD", "PLANT_OIL_TEMP"])
    assert tx.due(0.0) == ["TCU_CMD", "PLANT_OIL_TEMP"]
    assert tx.due(0.005) == [] and tx.due(0.010) == ["TCU_CMD"]
    assert tx.due(0.0351) == ["TCU_CMD"]  # late: sends once, keeps the 10 ms grid
    assert tx.next_due["TCU_CMD"] == pytest.approx(0.040)
    counters = [codec.decode(codec.frame_id("TCU_CMD"), bytes(tx.frame("TCU_CMD", {}).data)).counter
                for _ in range(18)]
    assert counters == list(range(16)) + [0, 1]


def test_schedule_and_deadlines_count_in_integers(codec):
    """No drift: over 2 * 10**5 ticks of 10 ms TCU_CMD is due at every tick and PLANT_OIL_TEMP at every n-th,
    whether the time comes in whole ms or as the float stamp tick x period (not always the decimal); a
    command stays valid exactly 3 cycle times after it came, not 1 us longer."""
    period, period_ms = codec.cycle_time("TCU_CMD"), codec.cycle_time_ms("TCU_CMD")
    every = codec.cycle_time_ms("PLANT_OIL_TEMP") // period_ms
    names = ["TCU_CMD", "PLANT_OIL_TEMP"]
    by_ms, by_float = TxScheduler(codec, names), TxScheduler(codec, names)
    ticks = range(200_000)
    assert any(tick * period != tick * period_ms / 1000 for tick in ticks)  # the float stamp is not the decimal
    for tick in ticks:
        expected = names if tick % every == 0 else ["TCU_CMD"]
        assert by_ms.due_ms(tick * period_ms) == expected and by_float.due(tick * period) == expected, tick
    state = RxMonitor(codec, ["TCU_CMD"]).states["TCU_CMD"]
    for tick in ticks:
        state.last_time = tick * period
        assert state.valid((tick + 3) * period) and not state.valid((tick + 3) * period + 1e-6), tick


def test_start_value_of_a_signal_with_value_names_is_its_default(tmp_path):
    """A GenSigStartValue on a signal with VAL_ names: cantools gives its initial value as a NamedSignalValue;
    encoding without the signal (or with NaN) takes that start value instead of failing."""
    text = DEFAULT_DBC.read_text(encoding="utf-8")
    assert 'VAL_ 528 State ' in text
    path = tmp_path / "start_value.dbc"
    path.write_text(text + '\nBA_ "GenSigStartValue" SG_ 528 State 2;\n', encoding="utf-8")
    codec = Codec(load_dbc(path), {"TCU_STATUS": ("State",)})
    for given in ({}, {"State": float("nan")}):
        frame = codec.decode(codec.frame_id("TCU_STATUS"), codec.encode("TCU_STATUS", given, 0))
        assert frame.values["State"] == 2.0
