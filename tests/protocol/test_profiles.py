"""The AUTOSAR E2E profiles (and "none") behind the one protection interface: the published check values of their
CRCs, the E2E Protocol Specification's example frames, frames of two other implementations (autosar-e2e, cantools'
``autosar.end_to_end``), the tables' errors, the codec, the receiver per profile and fault injection per profile."""

from __future__ import annotations

import random
import re
import tomllib
from pathlib import Path
from typing import Any

import can
import cantools
import pytest

from dsg_hil.common.errors import InputError
from dsg_hil.protocol import Codec, ProtocolError, RxMonitor, TxScheduler, load_dbc
from dsg_hil.protocol.crc import crc8_h2f, crc8_j1850, crc8_p01, crc16_ccitt
from dsg_hil.protocol.e2e import Protection, ProtectionError
from dsg_hil.protocol.faults import FaultError, FaultInjector, parse_fault
from dsg_hil.protocol.profiles import ProtectionSpec, protection_for

from .dbcs import one_message_db

e2e = pytest.importorskip("e2e", reason="autosar-e2e (the test extra) is the second implementation")
end_to_end = pytest.importorskip("cantools.autosar.end_to_end")

CHECK = b"123456789"
TABLES: dict[str, dict[str, Any]] = {  # one table per profile/variant, default layouts
    "P01-1A": {"profile": "P01", "variant": "1A", "data_id": 0x123},
    "P01-1B": {"profile": "P01", "variant": "1B", "data_id": 0x123},
    "P01-1C": {"profile": "P01", "variant": "1C", "data_id": 0x123},
    "P11-11A": {"profile": "P11", "variant": "11A", "data_id": 0x123},
    "P11-11C": {"profile": "P11", "variant": "11C", "data_id": 0x123},
    "P02": {"profile": "P02", "data_ids": list(range(0x10, 0x20))},
    "P05": {"profile": "P05", "data_id": 0x1234},
}


def _db(length: int = 8, signals: str = ' SG_ Value : 32|16@1+ (1,0) [0|65535] "-" B') -> cantools.database.Database:
    return one_message_db(length, signals)


def _bind(table, length=8, signals=' SG_ Value : 32|16@1+ (1,0) [0|65535] "-" B'):
    return ProtectionSpec.from_table(table, "MSG").bind(_db(length, signals).get_message_by_name("MSG"))


# ---- the CRCs ---------------------------------------------------------------------------------------------------
def test_crc_check_values_as_published():
    assert crc8_j1850(CHECK) == 0x4B  # CRC-8/SAE-J1850
    assert crc8_p01(CHECK) == 0x37  # CRC-8/GSM-A: J1850's polynomial, init and final XOR 0 (Profiles 1 and 11)
    assert crc8_h2f(CHECK) == 0xDF  # CRC-8/AUTOSAR (8H2F)
    assert crc16_ccitt(CHECK) == 0x29B1  # CRC-16/CCITT-FALSE (IBM-3740)
    assert (e2e.crc.CRC8_CHECK, e2e.crc.CRC8H2F_CHECK, e2e.crc.CRC16_CHECK) == (0x4B, 0xDF, 0x29B1)


def test_crcs_equal_autosar_e2es_on_random_data():
    rng = random.Random(1)
    for _ in range(300):
        data = rng.randbytes(rng.randrange(0, 40))
        assert crc8_j1850(data) == e2e.crc.calculate_crc8(data)
        assert crc8_h2f(data) == e2e.crc.calculate_crc8_h2f(data)
        assert crc16_ccitt(data) == e2e.crc.calculate_crc16(data)


def test_crcs_equal_crcchecks_on_random_data():
    """The table-driven CRCs (taken once from crccheck's classes, and binascii's CRC-CCITT) are crccheck's own,
    computed bit by bit, on every length a CAN FD frame takes and on every single byte."""
    from crccheck.crc import Crc8Autosar, Crc8SaeJ1850, Crc16CcittFalse

    rng = random.Random(2)
    samples = [bytes((b,)) for b in range(256)] + [rng.randbytes(n) for n in range(0, 70) for _ in range(5)]
    for data in samples:
        assert crc8_p01(data) == Crc8SaeJ1850.calc(data, initvalue=0x00) ^ 0xFF
        assert crc8_h2f(data) == Crc8Autosar.calc(data)
        assert crc16_ccitt(data) == Crc16CcittFalse.calc(data)


# ---- the specification's example frames (PRS E2E Protocol, protocol examples; DataID 0x123 / 0x1234) -------------
@pytest.mark.parametrize("variant, mode, frames", [
    ("1A", None, ("cc00", "9101")), ("1B", None, ("ce00", "0201")), (None, "low", ("ce00", "9301")),
    ("1C", None, ("2a10", "7711"))])
def test_profile_1_examples_of_the_specification(variant, mode, frames):
    table = {"profile": "P01", "data_id": 0x123, **({"variant": variant} if variant else {}),
             **({"data_id_mode": mode} if mode else {})}
    p = _bind(table, signals="")
    for counter, head in enumerate(frames):
        assert p.seal(bytes(8), counter) == bytes.fromhex(head) + bytes(6)


def test_profile_5_examples_of_the_specification():
    p = _bind({"profile": "P05", "data_id": 0x1234}, signals="")
    assert p.seal(bytes(8), 0).hex() == "1cca000000000000" and p.seal(bytes(8), 1).hex() == "cf8d010000000000"
    p = _bind({"profile": "P05", "data_id": 0x1234, "offset": 64}, length=16, signals="")
    assert p.seal(bytes(16), 0)[8:11].hex() == "289100" and p.seal(bytes(16), 1)[8:11].hex() == "fbd601"


def test_profile_2_examples():
    assert _bind({"profile": "P02", "data_ids": [0] * 16}, signals="").seal(bytes(8), 1).hex() == "4501000000000000"
    p = _bind({"profile": "P02", "data_ids": list(range(16))}, signals="")
    assert p.seal(bytes(range(8)), 2).hex() == "bc02020304050607" and p.seal(bytes(range(8)), 1)[:2].hex() == "6101"


# ---- frames of a second implementation ---------------------------------------------------------------------------
def _theirs(key: str, data: bytes, byte_offset: int = 0) -> bytes:
    """autosar-e2e's frame of ``data`` (its counter already in place)."""
    raw, table = bytearray(data), TABLES[key]
    if key.startswith("P01"):
        mode = {"1A": e2e.p01.E2E_P01_DATAID_BOTH, "1B": e2e.p01.E2E_P01_DATAID_ALT,
                "1C": e2e.p01.E2E_P01_DATAID_NIBBLE}[table["variant"]]
        e2e.p01.e2e_p01_protect(raw, table["data_id"], data_id_mode=mode, offset=byte_offset, increment_counter=False)
    elif key.startswith("P11"):
        mode = {"11A": e2e.p11.E2E_P11_DATAID_BOTH, "11C": e2e.p11.E2E_P11_DATAID_NIBBLE}[table["variant"]]
        e2e.p11.e2e_p11_protect(raw, table["data_id"], data_id_mode=mode, offset=byte_offset, increment_counter=False)
    elif key == "P02":
        e2e.p02.e2e_p02_protect(raw, bytes(table["data_ids"]), increment_counter=False)
    else:
        e2e.p05.e2e_p05_protect(raw, table["data_id"], offset=byte_offset, increment_counter=False)
    return bytes(raw)


@pytest.mark.parametrize("key", TABLES)
def test_frames_equal_autosar_e2es_and_each_checks_the_others(key):
    rng = random.Random(key)
    p = _bind(TABLES[key], signals="")
    for _ in range(200):
        ours = p.seal(rng.randbytes(8), rng.randrange(p.counter_modulus))
        assert _theirs(key, ours) == ours
        assert p.cause(ours) is None


@pytest.mark.parametrize("key", ["P01-1A", "P01-1C", "P11-11C", "P05"])
def test_a_header_moved_into_the_frame_equals_autosar_e2es_offset(key):
    """autosar-e2e places the header at a byte offset (the fields' relative positions fixed): ours with every
    offset moved by the same whole bytes gives its frames."""
    k = 3
    moved = {"offset": 8 * k} if key == "P05" else {"crc_offset": 8 * k, "counter_offset": 8 * k + 8,
                                                      "data_id_nibble_offset": 8 * k + 12}
    p = _bind({**TABLES[key], **moved}, length=12, signals="")
    rng = random.Random(key)
    for _ in range(100):
        ours = p.seal(rng.randbytes(12), rng.randrange(p.counter_modulus))
        assert _theirs(key, ours, byte_offset=k) == ours


def test_profiles_2_and_5_equal_cantools_helpers():
    rng = random.Random(5)
    p2, p5 = _bind(TABLES["P02"], signals=""), _bind(TABLES["P05"], signals="")
    for _ in range(100):
        frame = p2.seal(rng.randbytes(8), rng.randrange(16))
        data_id = TABLES["P02"]["data_ids"][frame[1] & 0x0F]
        assert end_to_end.check_profile2_crc(frame, data_id) is True
        frame = p5.seal(rng.randbytes(8), rng.randrange(256))
        assert end_to_end.check_profile5_crc(frame, 0x1234) is True
        assert bytes(end_to_end.apply_profile5_crc(frame, 0x1234)) == frame


# ---- the tables ---------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("table, words", [
    ({"profile": "P03"}, "profile must be one of"),
    ({"data_id": 1}, "profile must be one of"),
    ({"profile": "P05", "data_id": 1, "counter_offset": 8}, "key 'counter_offset'"),
    ({"profile": "P05"}, "data_id is missing"),
    ({"profile": "P05", "data_id": 0x10000}, "data_id must be within"),
    ({"profile": "P05", "data_id": True}, "data_id must be a whole number"),
    ({"profile": "P02", "data_ids": [1] * 15}, "data_ids must be the 16"),
    ({"profile": "P01", "variant": "1D", "data_id": 1}, "variant must be one of 1A, 1B, 1C"),
    ({"profile": "P11", "variant": "11B", "data_id": 1}, "variant must be one of 11A, 11C"),
    ({"profile": "P01", "variant": "1A", "data_id_mode": "nibble", "data_id": 1}, "not variant 1A's"),
])
def test_a_bad_table_is_one_error_naming_the_message_and_the_key(table, words):
    with pytest.raises(ProtectionError, match=words) as caught:
        ProtectionSpec.from_table(table, "TCU_CMD")
    assert str(caught.value).startswith("TCU_CMD: ") and isinstance(caught.value, InputError)


@pytest.mark.parametrize("table, length, words", [
    ({"profile": "P01", "data_id": 1, "crc_offset": 4}, 8, "crc_offset 4 must be a multiple of 8"),
    ({"profile": "P01", "data_id": 1, "counter_offset": 6}, 8, "counter_offset 6 must be a multiple of 4"),
    ({"profile": "P01", "data_id": 1, "counter_offset": 64}, 8, "counter field .* does not fit"),
    ({"profile": "P01", "data_id": 1, "counter_offset": 4}, 8, "crc and counter fields overlap"),
    ({"profile": "P01", "variant": "1C", "data_id": 0x1234}, 8, "does not fit data ID mode nibble"),
    ({"profile": "P05", "data_id": 1, "offset": 48}, 8, "counter field .* does not fit"),
    ({"profile": "P05", "data_id": 1}, 2, "does not fit"),
    ({"profile": "P05", "data_id": 1, "data_length": 72}, 8, "data_length 72 must be whole bytes within"),
    ({"profile": "P02", "data_ids": [0] * 16, "max_delta_counter": 16}, 8, "max_delta_counter 16 must be within"),
])
def test_a_layout_that_does_not_fit_the_frame_is_refused(table, length, words):
    with pytest.raises(ProtectionError, match=words):
        _bind(table, length=length, signals="")


def test_a_signal_partly_in_a_protection_field_is_refused_and_one_wholly_in_it_is_not_a_value():
    with pytest.raises(ProtectionError, match="signal Value lies partly in the P05 counter field"):
        _bind({"profile": "P05", "data_id": 1}, signals=' SG_ Value : 20|16@1+ (1,0) [0|65535] "-" B')
    db = _db(signals=' SG_ Crc : 0|16@1+ (1,0) [0|65535] "-" B\n SG_ Sqc : 16|8@1+ (1,0) [0|255] "-" B\n'
                     ' SG_ Value : 24|16@1+ (1,0) [0|65535] "-" B')
    codec = Codec(db, {"MSG": ["Value"]}, protection={"MSG": {"profile": "P05", "data_id": 0x1234}})
    frame = codec.decode(0x100, codec.encode("MSG", {"Value": 300}, 7))
    assert frame.values == {"Value": 300.0} and frame.counter == 7
    with pytest.raises(ProtocolError, match="MSG.Sqc carries the message's P05 protection"):
        Codec(db, {"MSG": ["Sqc"]}, protection={"MSG": {"profile": "P05", "data_id": 0x1234}})


def test_a_motorola_signal_is_placed_by_its_bits():
    """A big-endian signal's bits as AUTOSAR counts them: start 7, 16 bits = bytes 0 and 1."""
    with pytest.raises(ProtectionError, match="partly in the P01 counter field"):
        _bind({"profile": "P01", "data_id": 1, "crc_offset": 16}, signals=' SG_ Value : 7|16@0+ (1,0) [0|1] "-" B')


def test_the_spec_gives_its_table_back():
    spec = ProtectionSpec.from_table({"profile": "P01", "variant": "1C", "data_id": 0x123}, "MSG")
    assert spec.as_table() == {"profile": "P01", "variant": "1C", "data_id": 0x123, "data_id_mode": "nibble"}
    assert ProtectionSpec.from_table(spec.as_table(), "MSG") == spec


# ---- the codec ---------------------------------------------------------------------------------------------------
def test_the_default_is_the_dsg_hil_scheme_on_the_generated_path():
    db = load_dbc()
    codec = Codec(db, {"TCU_CMD": ["P_CL_Cmd"]})
    assert isinstance(codec.protection("TCU_CMD"), Protection) and "TCU_CMD" in codec.sources
    explicit = Codec(db, {"TCU_CMD": ["P_CL_Cmd"]}, protection={"TCU_CMD": {"profile": "dsg-hil"}})
    assert explicit.encode("TCU_CMD", {"P_CL_Cmd": 0.5}, 3) == codec.encode("TCU_CMD", {"P_CL_Cmd": 0.5}, 3)


@pytest.mark.parametrize("key", TABLES)
def test_a_profiled_message_encodes_and_decodes_with_generated_functions(key):
    db = load_dbc()  # TCU_CMD with its Counter (bits 48-51) and CRC (byte 7): move the profile clear of them
    table = dict(TABLES[key])
    if key == "P05":
        table["offset"] = 48  # CRC bytes 6-7, and the counter ... beyond: does not fit
        with pytest.raises(ProtectionError, match="does not fit"):
            Codec(db, {"TCU_CMD": ["P_CL_Cmd"]}, protection={"TCU_CMD": table})
        return
    codec = Codec(_db(), {"MSG": ["Value"]}, protection={"MSG": table}) if key == "P02" else None
    if codec is None:
        table.update(crc_offset=56, counter_offset=48, data_id_nibble_offset=52)
        codec = Codec(db, {"TCU_CMD": ["P_CL_Cmd"]}, protection={"TCU_CMD": table})
    name = "MSG" if key == "P02" else "TCU_CMD"
    assert "SEAL(" in codec.sources[name]  # generated, the protection sealing (tests/protocol/test_generated_codec.py)
    data = codec.encode(name, {"P_CL_Cmd": 0.5, "Value": 1234}, 3)
    frame = codec.decode(codec.frame_id(name), data)
    assert frame.counter == 3 and "Counter" not in frame.values and "CRC" not in frame.values
    assert codec.protection(name).cause(data) is None and codec.protection(name).profile == table["profile"]


def test_a_message_unprotected_is_taken_every_frame_even_repeated():
    codec = Codec(_db(), {"MSG": ["Value"]}, protection={"MSG": {"profile": "none"}})
    rx, tx = RxMonitor(codec, ["MSG"]), TxScheduler(codec, ["MSG"])
    data = [tx.data("MSG", {"Value": 7}) for _ in range(5)]
    assert len(set(data)) == 1 and data[0] == bytes(4) + (7).to_bytes(2, "little") + bytes(2)  # nothing but the value
    assert [rx.take_data(0x100, d, 0.01 * i)[0] for i, d in enumerate(data)] == ["new"] * 5
    assert rx.rejected_total == 0 and rx.states["MSG"].duplicates == 0 and rx.valid("MSG", 0.05)


# ---- the receiver, per profile -----------------------------------------------------------------------------------
def _frames(codec, counters, t0=0.0, period=0.01):
    return [(t0 + k * period, codec.encode("MSG", {"Value": 100 + k}, c)) for k, c in enumerate(counters)]


@pytest.mark.parametrize("key", TABLES)
def test_the_receiver_counts_steps_repeats_losses_and_resynchronises(key):
    codec = Codec(_db(), {"MSG": ["Value"]}, protection={"MSG": TABLES[key]})
    p = codec.protection("MSG")
    m, d = p.counter_modulus, p.max_delta
    assert (m, d) == {"P02": (16, 7), "P05": (256, 127)}.get(key, (15, 7))
    rx = RxMonitor(codec, ["MSG"])
    counters = [m - 2, m - 1, m - 1, 1, 1 + d, (2 + 2 * d) % m]  # wrap; repeat; 1 lost; max step; one more: refused
    taken = [rx.take_data(0x100, data, t)[0] for t, data in _frames(codec, counters)]
    assert taken == ["new", "new", "rejected", "new", "new", "rejected"]
    state = rx.states["MSG"]
    assert rx.rejected["counter"] == 2 and state.lost == 1 + (d - 1) and state.counter_jumps == 2
    (t, late), = _frames(codec, [(2 + 2 * d) % m], t0=1.0)  # after the timeout any step but 0 is taken
    assert rx.take_data(0x100, late, t)[0] == "new"
    repeat = codec.encode("MSG", {"Value": 555}, (2 + 2 * d) % m)  # a repeated counter never is, even then
    assert rx.take_data(0x100, repeat, 2.0)[0] == "rejected" and rx.rejected["counter"] == 3


@pytest.mark.parametrize("key, other, cause", [
    ("P01-1A", {"data_id": 0x124}, "crc"), ("P01-1C", {"data_id": 0x223}, "data_id"),
    ("P01-1C", {"data_id": 0x124}, "crc"), ("P11-11A", {"data_id": 0x223}, "crc"),
    ("P11-11C", {"data_id": 0x323}, "data_id"), ("P02", {"data_ids": list(range(0x11, 0x21))}, "crc"),
    ("P05", {"data_id": 0x1235}, "crc")])
def test_a_frame_of_another_data_id_is_rejected(key, other, cause):
    """Masquerading: a sender with another data ID (the nibble sent by 1C/11C says which; else the CRC)."""
    mine = Codec(_db(), {"MSG": ["Value"]}, protection={"MSG": TABLES[key]})
    theirs = Codec(_db(), {"MSG": ["Value"]}, protection={"MSG": {**TABLES[key], **other}})
    rx = RxMonitor(mine, ["MSG"])
    assert rx.take_data(0x100, theirs.encode("MSG", {"Value": 1}, 0), 0.0)[0] == "rejected"
    assert rx.rejected == {cause: 1}
    assert rx.take_data(0x100, mine.encode("MSG", {"Value": 1}, 0), 0.01)[0] == "new"


@pytest.mark.parametrize("key", ["P01-1A", "P11-11C"])
def test_counter_15_is_never_sent_and_refused(key):
    codec = Codec(_db(), {"MSG": ["Value"]}, protection={"MSG": TABLES[key]})
    tx = TxScheduler(codec, ["MSG"])
    assert [codec.protection("MSG").counter(tx.data("MSG", {})) for _ in range(16)] == [*range(15), 0]
    p = codec.protection("MSG")
    raw = bytearray(codec.encode("MSG", {"Value": 1}, 0))
    raw[1] |= 0x0F
    forged = bytes(raw[:1]) + bytes(raw[1:])
    forged = bytes([p.crc(forged, 15)]) + forged[1:]  # a valid CRC over counter 15
    assert p.cause(forged) == "counter"
    rx = RxMonitor(codec, ["MSG"])
    assert rx.take_data(0x100, forged, 0.0)[0] == "rejected" and rx.rejected == {"counter": 1}


# ---- fault injection, per profile --------------------------------------------------------------------------------
def _faulted(codec, fault, counters=range(6)):
    injector = FaultInjector(codec.db, [parse_fault(fault)], protections=codec.protections())
    out = []
    for k, c in enumerate(counters):
        msg = can.Message(arbitration_id=0x100, data=codec.encode("MSG", {"Value": 100 + k}, c), is_extended_id=False)
        out += [bytes(m.data) for m in injector.apply(msg, 0.01 * k)]
    return out


@pytest.mark.parametrize("key", [*TABLES, "dsg-hil"])
def test_protection_faults_work_on_every_profile(key):
    if key == "dsg-hil":
        db = _db(signals=' SG_ Value : 16|16@1+ (1,0) [0|65535] "-" B\n SG_ Counter : 48|4@1+ (1,0) [0|15] "-" B\n'
                         ' SG_ CRC : 56|8@1+ (1,0) [0|255] "-" B')
        codec = Codec(db, {"MSG": ["Value"]})
    else:
        codec = Codec(_db(), {"MSG": ["Value"]}, protection={"MSG": TABLES[key]})
    rx = RxMonitor(codec, ["MSG"])
    for i, data in enumerate(_faulted(codec, "corrupt_crc:MSG@0.02-0.04")):
        rx.take_data(0x100, data, 0.01 * i)
    assert rx.rejected == {"crc": 2} and rx.states["MSG"].received == 4
    rx = RxMonitor(codec, ["MSG"])
    frames = _faulted(codec, "freeze_counter:MSG@0.02-")
    assert [codec.protection("MSG").counter(f) for f in frames] == [0, 1, 2, 2, 2, 2]
    assert [rx.take_data(0x100, f, 0.01 * i)[0] for i, f in enumerate(frames)] == ["new"] * 3 + ["rejected"] * 3
    assert rx.rejected == {"counter": 3}
    rx = RxMonitor(codec, ["MSG"])
    frames = _faulted(codec, "stuck:MSG.Value@0.02-,value=9")  # a signal fault: counter and CRC still valid
    assert [rx.receive(can.Message(arbitration_id=0x100, data=f, is_extended_id=False), 0.01 * i).values["Value"]
            for i, f in enumerate(frames)] == [100, 101, 9, 9, 9, 9]


def test_a_protection_fault_on_an_unprotected_message_fails_at_start_up():
    codec = Codec(_db(), {"MSG": ["Value"]}, protection={"MSG": {"profile": "none"}})
    with pytest.raises(FaultError, match="MSG has no CRC to fault \\(protection none\\)"):
        FaultInjector(codec.db, [parse_fault("corrupt_crc:MSG")], protections=codec.protections())
    with pytest.raises(FaultError, match="MSG has no counter to fault"):
        FaultInjector(codec.db, [parse_fault("freeze_counter:MSG")], protections=codec.protections())


def test_protection_for_uses_the_dsg_hil_scheme_by_default():
    message = load_dbc().get_message_by_name("TCU_CMD")
    assert protection_for(message) == Protection.of(message)
    assert protection_for(message, {"profile": "none"}).counter_modulus == 0


# ---- an ARXML's E2E data -----------------------------------------------------------------------------------------
ARXML = Path(__file__).parent / "data" / "e2e_profile5.arxml"


def test_an_arxml_messages_e2e_data_gives_its_protection():
    """cantools reads the ARXML's END-TO-END-PROTECTION (category PROFILE_05, data ID 0x1234): the codec protects
    the message by it without a table, and cantools' own Profile 5 check, given the message, accepts the frames."""
    db = cantools.database.load_file(str(ARXML), strict=True)
    message = db.get_message_by_name("COMMAND")
    assert ProtectionSpec.from_autosar(message) == ProtectionSpec.from_table(
        {"profile": "P05", "data_id": 0x1234, "data_length": 64}, "COMMAND")
    codec = Codec(db, {"COMMAND": ["Torque"]})
    assert codec.protection("COMMAND").profile == "P05"
    frames = [codec.encode("COMMAND", {"Torque": 300 + k}, k) for k in range(3)]
    assert all(end_to_end.check_profile5_crc(f, message) for f in frames)
    assert [codec.decode(0x200, f) for f in frames][2].values == {"Torque": 302.0}  # Crc, Counter: not values
    override = Codec(db, {"COMMAND": ["Torque"]}, protection={"COMMAND": {"profile": "P05", "data_id": 0x4321}})
    assert override.protection("COMMAND").cause(frames[0]) == "crc"  # a table wins over the ARXML


@pytest.mark.parametrize("category, profile", [("PROFILE_01", "P01"), ("Profile2", "P02"), ("p2", "P02"),
                                               ("PROFILE_05", "P05"), ("Profile11", "P11"), ("E2E_P05", "P05")])
def test_arxml_category_names_as_tools_write_them(category, profile):
    db = cantools.database.load_file(str(ARXML), strict=True)
    message = db.get_message_by_name("COMMAND")
    message.autosar.e2e.category = category
    message.autosar.e2e.data_ids = list(range(16)) if profile == "P02" else [7]
    assert ProtectionSpec.from_autosar(message).profile == profile


def test_an_arxml_profile_we_do_not_have_is_one_error():
    db = cantools.database.load_file(str(ARXML), strict=True)
    message = db.get_message_by_name("COMMAND")
    message.autosar.e2e.category = "PROFILE_04"
    with pytest.raises(ProtectionError, match="COMMAND \\(ARXML E2E\\): E2E category 'PROFILE_04' is not a supported"):
        ProtectionSpec.from_autosar(message)


# ---- the reference page ------------------------------------------------------------------------------------------
PAGE = Path(__file__).resolve().parents[2] / "docs" / "reference" / "e2e.md"


def _blocks(language: str) -> list[str]:
    if not PAGE.exists():
        pytest.skip("no docs/ beside the tests (installed package)")
    return re.findall(rf"^```{language}\n(.*?)^```", PAGE.read_text(encoding="utf-8"), re.S | re.M)


def test_the_pages_tables_are_specs_and_its_python_runs():
    (toml,) = _blocks("toml")
    tables = tomllib.loads(toml)
    specs = {name: ProtectionSpec.from_table(table, name) for name, table in tables.items()}
    assert [s.profile for s in specs.values()] == ["P05", "P01", "P02", "none"]
    (python,) = _blocks("python")
    exec(compile(python, str(PAGE), "exec"), {})  # noqa: S102 - the page's own example, its asserts included
