"""The codec generated per message from the DBC against the cantools path (``Codec(..., reference=True)``): the
same bytes for random, out-of-range, missing and non-finite values, and the same decoded values or the same
rejection (reason and text) for random, corrupted, resized and re-sealed frames; on the shipped DBC and on one
with what the shipped one lacks (Motorola byte order, integer scaling, value tables, a float signal). Each case
twice: with the generated functions, and with the messages' plans (``Codec(..., plans=True)``, :mod:`.plan`: what the
compiled build decodes and encodes expressions with), here run by the interpreter; and a third time with the messages
under AUTOSAR E2E profiles (:mod:`.profiles`), whose generated functions call the protection's seal and check."""

from __future__ import annotations

import math
import random

import cantools
import pytest

from dsg_hil.protocol import Codec, FrameError, load_dbc
from dsg_hil.protocol.codec import raw_range, signal_range
from dsg_hil.protocol.e2e import COUNTER, CRC

EXTRA_DBC = """VERSION ""
NS_ :
BS_:
BU_: A B
BO_ 300 MOTOROLA: 8 A
 SG_ Speed : 7|16@0- (0.1,-5) [-3000|3000] "rpm" B
 SG_ Gear : 19|4@0+ (1,0) [0|9] "-" B
 SG_ Step : 31|10@0+ (2,-100) [-100|1900] "-" B
 SG_ Mode : 33|2@1+ (1,0) [0|3] "-" B
 SG_ Counter : 48|4@1+ (1,0) [0|15] "-" B
 SG_ CRC : 56|8@1+ (1,0) [0|255] "-" B
BO_ 301 CRC_FIRST: 6 A
 SG_ CRC : 0|8@1+ (1,0) [0|255] "-" B
 SG_ Counter : 8|3@1+ (1,0) [0|7] "-" B
 SG_ Torque : 11|13@1- (0.5,0) [-1000|1000] "Nm" B
 SG_ Open : 24|16@1+ (1,0) [0|0] "-" B
BO_ 302 WITH_FLOAT: 8 A
 SG_ Ratio : 0|32@1- (1,0) [-10|10] "-" B
 SG_ Counter : 48|4@1+ (1,0) [0|15] "-" B
 SG_ CRC : 56|8@1+ (1,0) [0|255] "-" B
BA_DEF_ BO_ "GenMsgCycleTime" INT 0 10000;
BA_DEF_ SG_ "GenSigStartValue" FLOAT -1000000000 1000000000;
BA_DEF_DEF_ "GenMsgCycleTime" 0;
BA_DEF_DEF_ "GenSigStartValue" 0;
BA_ "GenMsgCycleTime" BO_ 300 10;
BA_ "GenMsgCycleTime" BO_ 301 10;
BA_ "GenMsgCycleTime" BO_ 302 10;
BA_ "GenSigStartValue" SG_ 300 Speed 70;
VAL_ 300 Mode 0 "OFF" 1 "ON" 2 "AUTO" ;
SIG_VALTYPE_ 302 Ratio : 1;
"""


def profiled(db) -> dict[str, dict]:
    """AUTOSAR E2E profiles on the messages: P01 (1A, 1B, 1C) and P11 (11A, 11C) in turn on the bits of a Counter at
    48 and a CRC at 56 (which then carry it), none on the others."""
    tables = [{"profile": "P01", "variant": "1A"}, {"profile": "P11", "variant": "11C"},
              {"profile": "P01", "variant": "1B"}, {"profile": "P01", "variant": "1C"}, {"profile": "P11"}]
    out: dict[str, dict] = {}
    for k, message in enumerate(db.messages):
        at = {s.name: s.start for s in message.signals}
        out[message.name] = {**tables[k % len(tables)], "data_id": 0x100 + k, "crc_offset": 56, "counter_offset": 48,
                             "data_id_nibble_offset": 52} if (at.get(COUNTER), at.get(CRC)) == (48, 56) else \
            {"profile": "none"}
    return out


def codecs(db, mode: str) -> tuple[Codec, Codec]:
    """The codec of ``mode`` ("generated", "plans", "profiles": generated under :func:`profiled`) and the cantools
    path's, under the same protections."""
    uses = {m.name: () for m in db.messages}
    protection = profiled(db) if mode == "profiles" else None
    return (Codec(db, uses, plans=mode == "plans", protection=protection),
            Codec(db, uses, reference=True, protection=protection))


def random_value(rng: random.Random, signal) -> float | int | bool | None:
    lo, hi = signal_range(signal)
    step = abs(signal.scale)
    pick = rng.random()
    if pick < 0.45:
        return rng.uniform(lo, hi)
    if pick < 0.6:  # ties of the rounding, and values on the grid
        return signal.offset + (rng.randrange(int((hi - lo) / step) + 1) + rng.choice((0.0, 0.5))) * step + lo * 0
    if pick < 0.75:
        return rng.choice((lo, hi, lo - step, hi + step, 0, -0.0, lo - 1e6, hi + 1e6))
    if pick < 0.85:
        return rng.choice((math.nan, math.inf, -math.inf, None))
    if pick < 0.95:
        return rng.randrange(int(lo) - 2, int(hi) + 3)
    return rng.choice((True, False))


def same_decode(generated: Codec, reference: Codec, frame_id: int, data: bytes) -> str:
    """Decode with both; assert the same result; return the rejection reason (or "ok")."""
    results: list[tuple[object, ...]] = []
    for codec in (generated, reference):
        try:
            frame = codec.decode(frame_id, data)
            results.append(("ok", frame.name, repr(frame.values), frame.counter))
        except FrameError as exc:
            results.append((exc.reason, str(exc)))
    assert results[0] == results[1], (hex(frame_id), data.hex())
    return str(results[0][0])


@pytest.fixture(params=["generated", "plans", "profiles"])
def mode(request) -> str:
    return request.param


@pytest.fixture(scope="module", params=["shipped", "extra"])
def db(request):
    return load_dbc() if request.param == "shipped" else cantools.database.load_string(EXTRA_DBC, "dbc",
                                                                                      strict=True)


def test_every_message_it_can_is_generated_and_the_rest_stays_on_cantools(db, mode):
    generated, _ = codecs(db, mode)
    expected = {m.name for m in db.messages} - {"WITH_FLOAT"}
    assert set(generated.sources) == expected


def test_encode_is_byte_identical_to_cantools(db, mode):
    generated, reference = codecs(db, mode)
    rng = random.Random(9)
    n = 0
    for message in db.messages:
        signals = [s for s in message.signals if s.name not in (COUNTER, CRC)]
        for _ in range(600):
            values = {}
            for signal in signals:
                value = random_value(rng, signal)
                if value is not None or rng.random() < 0.5:
                    values[signal.name] = value
            counter = rng.randrange(-3, 300)
            assert generated.encode(message.name, values, counter) == reference.encode(message.name, values, counter), \
                (message.name, values, counter)
            n += 1
    assert n >= 1800


def test_an_expression_encoder_gives_the_bytes_of_the_dict_one(db, mode):
    """``Codec.expression_encoder``: values as expressions of its arguments (here ``x[name]``), the signals it does
    not name at their defaults; the same bytes as ``encode`` of the dict, fused where the message is generated, and
    on the cantools path."""
    generated, reference = codecs(db, mode)
    rng = random.Random(21)
    n = 0
    for message in db.messages:
        signals = [s.name for s in message.signals if s.name not in (COUNTER, CRC)]
        named = signals[::2]  # the rest: defaults
        expressions = {s: f"x[{s!r}]" for s in named}
        encoders = [codec.expression_encoder(message.name, ("x",), expressions) for codec in (generated, reference)]
        as_floats = generated.expression_encoder(message.name, ("x",), {s: f"float({e})" for s, e in
                                                                         expressions.items()}, floats=True)
        for _ in range(200):
            values = {}
            while len(values) < len(named):
                value = random_value(rng, message.get_signal_by_name(named[len(values)]))
                if value is not None:
                    values[named[len(values)]] = value
            counter = rng.randrange(-3, 300)
            expected = reference.encode(message.name, values, counter)
            assert [encode(values, counter) for encode in encoders] == [expected, expected], (message.name, values)
            assert as_floats(values, counter) == expected  # floats=True: expressions that give floats, taken as such
            n += 1
    assert n >= 600
    with pytest.raises(ValueError, match="no signal Counter"):
        generated.expression_encoder(db.messages[0].name, ("x",), {COUNTER: "1"})
    with pytest.raises(ValueError, match="argument 'v' is a name the encoder uses"):
        generated.expression_encoder(db.messages[0].name, ("v",), {})


def test_decode_gives_the_same_values_or_the_same_rejection(db, mode):
    generated, reference = codecs(db, mode)
    rng = random.Random(10)
    reasons: dict[str, int] = {}
    for message in db.messages:
        protection = generated.protection(message.name)
        for _ in range(700):
            data = bytearray(rng.randbytes(message.length))
            kind = rng.random()
            if kind < 0.5:  # a random frame with a valid CRC: in range or not
                data = bytearray(protection.seal(data))
            elif kind < 0.8:  # a good frame with bits flipped, or re-sealed after the flip
                values = {s.name: rng.uniform(*signal_range(s)) for s in message.signals}
                data = bytearray(generated.encode(message.name, values, rng.randrange(16)))
                data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
                if rng.random() < 0.5:
                    data = bytearray(protection.seal(data))
            elif kind < 0.9:  # a wrong length
                data = bytearray(rng.randbytes(rng.choice((0, 1, message.length - 1, message.length + 1, 64))))
            reason = same_decode(generated, reference, message.frame_id, bytes(data))
            reasons[reason] = reasons.get(reason, 0) + 1
    same_decode(generated, reference, 0x7FF, bytes(8))
    assert {"ok", "crc", "dlc"} <= set(reasons)
    if any(raw_range(s) != signal_range(s) for m in db.messages for s in m.signals):
        assert reasons.get("range", 0) > 50


def test_generated_decode_takes_bytearray_as_received(db, mode):
    generated, reference = codecs(db, mode)
    message = db.messages[0]
    data = generated.encode(message.name, {}, 5)
    assert generated.decode(message.frame_id, bytearray(data)) == reference.decode(message.frame_id, data)
