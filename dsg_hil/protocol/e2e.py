"""End-to-end protection of every frame of this contract: a rolling counter and a CRC, placed where the DBC's
``Counter`` and ``CRC`` signals say.

The scheme is dsg-hil's own (it is *not* AUTOSAR E2E profile 1, which places counter and CRC differently and
covers a data ID instead of the CAN ID):

* CRC: CRC-8 SAE J1850 (width 8, poly 0x1D, init 0xFF, no reflection, final XOR 0xFF; check value of the
  ASCII bytes "123456789": 0x4B) over the CAN ID as two bytes, little endian (low byte first), followed by every
  data byte except the CRC's own, in byte order. The ``CRC`` signal must be 8 bits, unsigned and byte aligned.
* Counter: the ``Counter`` signal (unsigned, up to 8 bits; 4 bits here), +1 per frame of that message, wrapping
  at 2^length; 0 in the first frame after start-up or after the lockstep presence probe.
* Receiver: a frame whose CRC does not match is rejected ("crc"); a counter step of 0 is a repeat and rejected
  ("counter") always, even after a timeout, so a sender whose counter froze never gets through; the first frame,
  and the first after the message timed out (3 cycle times without a valid frame), is otherwise accepted whatever
  its counter (resynchronisation); while the message is valid a step of 1 is normal, a step of 2 to ``MAX_DELTA``
  is accepted with step - 1 frames counted lost, and a larger step (a frame from the past) is rejected
  ("counter"). A byte-identical repeat of the last frame taken is a duplicate (a retransmission): counted, ignored.

:class:`Protection` is one implementation of :class:`.profiles.FrameProtection`, the interface the codec, the
receive checks and the fault injector use; the AUTOSAR E2E profiles and "none" are the others (:mod:`.profiles`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from cantools.database.can import Message

from .crc import crc8_j1850
from ..common.errors import InputError

__all__ = ["COUNTER", "CRC", "MAX_DELTA", "Protection", "ProtectionError"]

COUNTER, CRC = "Counter", "CRC"
MAX_DELTA = 7  # largest counter step accepted (half the 4-bit range): 6 frames lost in a row


class ProtectionError(InputError):
    """A message's protection cannot be had: its DBC Counter or CRC signal cannot carry this contract's scheme, or a
    profile's table (:class:`.profiles.ProtectionSpec`) is malformed or does not fit the frame. The message names
    the message and the key."""


@dataclass(frozen=True)
class Protection:
    """Where one message carries its counter and CRC, read from its DBC signals (the "dsg-hil" profile)."""

    frame_id: int
    length: int  # frame length, bytes
    crc_byte: int  # index of the CRC byte
    counter_modulus: int
    counter_offset: int = field(default=-1, compare=False)  # the counter's least significant bit (little endian)
    profile: str = field(default="dsg-hil", init=False, compare=False)
    max_delta: int = field(default=MAX_DELTA, init=False, compare=False)

    @property
    def layout(self) -> tuple[tuple[str, int, int], ...]:
        """(field, bit offset, bits) of the CRC and the counter (bit n: bit n % 8 of byte n // 8)."""
        return (("crc", 8 * self.crc_byte, 8), ("counter", self.counter_offset, self.counter_modulus.bit_length() - 1))

    @classmethod
    def of(cls, message: Message) -> Protection:
        try:
            crc, counter = message.get_signal_by_name(CRC), message.get_signal_by_name(COUNTER)
        except KeyError as exc:
            raise ProtectionError(f"{message.name} has no {exc.args[0]} signal") from None
        if crc.length != 8 or crc.is_signed or crc.start % 8 or crc.byte_order != "little_endian":
            raise ProtectionError(f"{message.name}.CRC must be 8 unsigned bits on a byte boundary (little endian), "
                                  f"got {crc.length} bits at bit {crc.start}")
        if counter.is_signed or not 1 <= counter.length <= 8:
            raise ProtectionError(f"{message.name}.Counter must be 1-8 unsigned bits, got {counter.length}")
        lsb = counter.start if counter.byte_order == "little_endian" else counter.start - counter.length + 1
        if counter.byte_order != "little_endian" and lsb // 8 != counter.start // 8:
            raise ProtectionError(f"{message.name}.Counter: a big-endian counter must lie within one byte")
        if lsb < crc.start + 8 and crc.start < lsb + counter.length:
            raise ProtectionError(f"{message.name}: Counter and CRC overlap")
        return cls(message.frame_id, message.length, crc.start // 8, 1 << counter.length, lsb)

    def crc(self, data: bytes | bytearray) -> int:
        """The CRC of a frame's data (the CRC byte itself is not covered)."""
        covered = bytes(data[:self.crc_byte]) + bytes(data[self.crc_byte + 1:])
        return crc8_j1850(bytes((self.frame_id & 0xFF, (self.frame_id >> 8) & 0xFF)) + covered)

    def seal(self, data: bytes | bytearray, counter: int | None = None) -> bytes:
        """``data`` with its CRC byte filled in (and first its counter ``counter``, if given)."""
        raw = bytearray(data)
        if counter is not None:
            bits, mask = self.counter_offset, self.counter_modulus - 1
            whole = int.from_bytes(raw, "little") & ~(mask << bits) | (counter % self.counter_modulus) << bits
            raw = bytearray(whole.to_bytes(len(raw), "little"))
        raw[self.crc_byte] = self.crc(raw)
        return bytes(raw)

    def check(self, data: bytes) -> bool:
        return len(data) > self.crc_byte and data[self.crc_byte] == self.crc(data)

    def cause(self, data: bytes) -> str | None:
        """Why ``data`` fails the protection ("crc"), or None."""
        return None if self.check(data) else "crc"

    def counter(self, data: bytes) -> int:
        """The frame's counter."""
        return (int.from_bytes(data, "little") >> self.counter_offset) & (self.counter_modulus - 1)

    def step(self, previous: int, counter: int) -> int:
        """Counter step from ``previous`` to ``counter`` (0 .. modulus-1)."""
        return (counter - previous) % self.counter_modulus
