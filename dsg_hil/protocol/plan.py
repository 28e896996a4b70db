"""Per-message encoding and decoding from a plan: the numbers :mod:`.generated` writes into its source (bit
positions, scale, offset, range, the Counter and the CRC's tables), held as typed data and run by one typed loop per
frame, with the same operations in the same order as that source, so the same frames and the same values and errors
bit for bit (``tests/protocol/test_generated_codec.py`` compares both with cantools on random and corrupted frames;
``tests/test_packaging.py`` runs that compiled, and compares the frames of whole runs).

Run by the interpreter a loop over a plan is slower than the generated source; compiled by mypyc (the regular
install's build, ``setup.py``) it is 2-3 times faster, and the codec takes it there (:data:`COMPILED`): the decoders,
and the encoders of signal values given as Python expressions (:meth:`Codec.expression_encoder`), whose generated
part is then only the expressions.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from importlib.machinery import EXTENSION_SUFFIXES
from typing import Any

__all__ = ["COMPILED", "IDENTITY", "LINEAR_INTEGER", "SCALED", "SCALED_OFFSET", "MessagePlan", "SignalPlan"]

COMPILED = __file__.endswith(tuple(EXTENSION_SUFFIXES))  # this module built by mypyc: the codec runs its plans
IDENTITY, LINEAR_INTEGER, SCALED, SCALED_OFFSET = 0, 1, 2, 3  # SignalPlan.kind: cantools' conversion (to raw)
_INF = math.inf


class SignalPlan:
    """One signal: where its bits are, how a value becomes them and back, its range [``lo``, ``hi``] (floats: the
    plan holds no bound a float cannot, :func:`.generated.plan`). ``kind`` (encoding): a value's raw integer as
    :func:`.generated._to_raw` computes it; ``int_values`` (decoding): raw x scale + offset in integers (an identity
    or integer conversion), else in floats (+ ``offset`` only where ``offset_added``); ``checked``: a decoded value
    more than 1e-9 outside the range is an error."""

    def __init__(self, name: str, big: bool, shift: int, length: int, signed: bool, kind: int, scale: float,
                 offset: float, int_values: bool, offset_added: bool, lo: float, hi: float, default: float,
                 checked: bool) -> None:
        self.name, self.big, self.shift, self.signed = name, big, shift, signed
        self.mask, self.sign_bit, self.span = (1 << length) - 1, 1 << (length - 1), 1 << length
        self.kind, self.scale, self.offset, self.offset_added = kind, scale, offset, offset_added
        self.int_values = int_values
        self.int_scale, self.int_offset = (int(scale), int(offset)) if int_values else (1, 0)
        self.lo, self.hi, self.default, self.checked = lo, hi, default, checked
        self.lo_tol, self.hi_tol, self.range_text = lo - 1e-9, hi + 1e-9, f"[{lo:g}, {hi:g}]"


class MessagePlan:
    """One message: its value signals (Counter and CRC apart) in DBC order, the Counter, the CRC (a constant and the
    tables of :func:`.generated._crc_terms`: ``crc_terms`` as (table, shift, mask)) and the CRC signal when its
    DBC range is checked on decoding. ``order``: the signals as decoding takes them, in DBC order, by index into
    ``values`` (-1 the Counter, -2 the CRC)."""

    def __init__(self, name: str, length: int, values: list[SignalPlan], counter: SignalPlan, modulus: int,
                 crc_shift: int, crc_constant: int, crc_terms: list[tuple[bytes, int, int]], crc: SignalPlan | None,
                 frame_error: Callable[[str, str], Exception], decoded_frame: type, order: list[int]) -> None:
        self.name, self.length, self.values, self.counter, self.modulus = name, length, values, counter, modulus
        self.crc_shift, self.crc_constant, self.crc = crc_shift, crc_constant, crc
        self.crc_tables = [table for table, _, _ in crc_terms]
        self.crc_shifts = [shift for _, shift, _ in crc_terms]
        self.crc_masks = [mask for _, _, mask in crc_terms]
        self.frame_error, self.decoded_frame = frame_error, decoded_frame
        self.roles = order
        self.decoded: list[SignalPlan] = []
        for index in order:
            s = counter if index == -1 else crc if index == -2 else values[index]
            assert s is not None
            self.decoded.append(s)
        self.data_mask = (1 << 8 * length) - 1 - (255 << crc_shift)  # the frame's bits but the CRC's
        self.big = counter.big or any(s.big for s in values) or (crc is not None and crc.big)

    def _crc(self, F: int) -> int:
        """The CRC of the frame's bits ``F`` (its CRC byte not looked at)."""
        crc = self.crc_constant
        tables, shifts, masks = self.crc_tables, self.crc_shifts, self.crc_masks
        for i in range(len(tables)):
            crc ^= tables[i][(F >> shifts[i]) & masks[i]]
        return crc

    def encode_values(self, values: tuple[float, ...], counter: int) -> bytes:
        """The frame of ``values`` (floats, one per value signal in DBC order: a generated fused encoder's
        ``v = expression``, a missing signal given its default), the Counter ``counter``, the CRC sealed."""
        signals = self.values
        if len(values) != len(signals):
            raise ValueError(f"{self.name}: {len(values)} values for {len(signals)} signals")
        F = 0
        G = 0
        for i in range(len(signals)):
            s = signals[i]
            v: float = values[i]
            if not s.lo <= v <= s.hi:
                v = s.default if v != v or v == _INF or v == -_INF else s.lo if v < s.lo else s.hi
            r = _to_raw(s, v)
            if s.big:
                G |= (r & s.mask) << s.shift
            else:
                F |= (r & s.mask) << s.shift
        c = self.counter
        if c.big:
            G |= ((counter % self.modulus) & c.mask) << c.shift
        else:
            F |= ((counter % self.modulus) & c.mask) << c.shift
        if self.big:
            F |= int.from_bytes(G.to_bytes(self.length, "big"), "little")
        return (F | self._crc(F) << self.crc_shift).to_bytes(self.length, "little")

    def decode(self, data: bytes | bytearray) -> Any:
        """The frame's DecodedFrame (name, values by signal, Counter), or ``frame_error`` raised: a wrong DLC, CRC, or
        a value outside its DBC range, with the generated decoder's reasons and texts."""
        n = len(data)
        if n != self.length:
            raise self.frame_error("dlc", f"{self.name}: DLC {n}, expected {self.length}")
        whole = int.from_bytes(data, "little")
        F = whole & self.data_mask  # (a small integer: the CRC's byte is often the top one)
        if (whole >> self.crc_shift) & 255 != self._crc(F):
            raise self.frame_error("crc", f"{self.name}: CRC mismatch")
        G = int.from_bytes(data, "big") if self.big else 0
        out: dict[str, float] = {}
        counter = 0
        roles, decoded = self.roles, self.decoded
        for i in range(len(roles)):
            s, role = decoded[i], roles[i]
            r = ((G if s.big else whole if role == -2 else F) >> s.shift) & s.mask
            if s.signed and r & s.sign_bit:
                r -= s.span
            if s.int_values:
                n = r * s.int_scale + s.int_offset
                if s.checked and not (s.lo_tol <= n <= s.hi_tol):
                    raise self.frame_error("range", f"{self.name}.{s.name} = {n} outside {s.range_text}")
                if role == -1:
                    counter = n
                elif role >= 0:
                    out[s.name] = float(n)
            else:
                v = r * s.scale + s.offset if s.offset_added else r * s.scale
                if s.checked and not (s.lo_tol <= v <= s.hi_tol):
                    raise self.frame_error("range", f"{self.name}.{s.name} = {v} outside {s.range_text}")
                if role >= 0:
                    out[s.name] = v
        return tuple.__new__(self.decoded_frame, (self.name, out, counter))


def _to_raw(s: SignalPlan, v: float) -> int:
    """The raw integer of the finite value ``v`` (:func:`.generated._to_raw`: cantools' ``numeric_scaled_to_raw``)."""
    kind = s.kind
    if kind == IDENTITY:
        return _round(v)
    if kind == LINEAR_INTEGER:
        d = v - s.offset if s.offset else v
        q, m = divmod(d, s.scale)
        return _round(q) if m == 0 else _round(d / s.scale)
    if kind == SCALED:
        return _round(v / s.scale)
    return _round((v - s.offset) / s.scale)


def _round(x: float) -> int:
    """``round(x)`` of a finite float, as Python's (the nearest integer, a tie to the even one), from its floor and
    the remainder x - floor(x), which is exact (Sterbenz) but for -0.5 < x < 0, where any rounding of it leaves
    it above 0.5 or at a tie, both giving 0 as they should; compiled: no call of the builtin."""
    f = math.floor(x)
    d = x - f
    if d > 0.5 or (d == 0.5 and f & 1):
        return f + 1
    return f
