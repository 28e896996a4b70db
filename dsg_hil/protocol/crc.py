"""The CRCs of the end-to-end protections.

* CRC-8 SAE J1850: width 8, poly 0x1D, init 0xFF, not reflected, final XOR 0xFF, check value 0x4B (the polynomial
  of AUTOSAR's Crc_CalculateCRC8). :func:`crc8_j1850` is our own table (the dsg-hil scheme's generated fast path,
  :mod:`.generated`, derives its tables from it); how the dsg-hil scheme applies it is in :mod:`.e2e`.
* The AUTOSAR E2E profiles' CRCs (:mod:`.profiles`) are crccheck's (a dependency of cantools, so of every install):
  CRC-8 SAE J1850 with init and final XOR 0x00 (:func:`crc8_p01`, Profiles 1 and 11: AUTOSAR's Crc_CalculateCRC8
  chained from 0xFF with IsFirstCall false, its result XOR 0xFF), CRC-8H2F (:func:`crc8_h2f`, Profile 2: poly 0x2F,
  init 0xFF, final XOR 0xFF, check 0xDF) and CRC-16/CCITT-FALSE (:func:`crc16_ccitt`, Profile 5: poly 0x1021, init
  0xFFFF, no final XOR, check 0x29B1).

Every frame of a profiled message is sealed and checked, so these run per frame. crccheck computes bit by bit in
Python (about 15 us for 10 bytes); the CRC-8s here run through a table of 256 entries taken once from crccheck's
own classes (:func:`_table8`: the register after each byte value), byte by byte, and CRC-16/CCITT-FALSE is the
standard library's ``binascii.crc_hqx`` (C: the CCITT polynomial 0x1021, not reflected, from the initial value
given, no final XOR), each under 1 us. The same CRCs: the tests compare each with crccheck's and autosar-e2e's.
"""

from __future__ import annotations

from binascii import crc_hqx

from crccheck.crc import Crc8Autosar, Crc8SaeJ1850

__all__ = ["crc16_ccitt", "crc8_h2f", "crc8_j1850", "crc8_p01"]


def _table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table.append(crc)
    return tuple(table)


_TABLE = _table()


def _table8(crc: type[Crc8SaeJ1850] | type[Crc8Autosar]) -> tuple[int, ...]:
    """The table of a CRC-8 crccheck defines, not reflected: entry b is the register after the byte b from 0 (its
    CRC of ``bytes((b,))`` from init 0, less the final XOR, which is the CRC of no data from init 0)."""
    final = int(crc.calc(b"", initvalue=0))
    return tuple(int(crc.calc(bytes((b,)), initvalue=0)) ^ final for b in range(256))


_P01 = _table8(Crc8SaeJ1850)  # poly 0x1D
_H2F = _table8(Crc8Autosar)  # poly 0x2F


def crc8_j1850(data: bytes) -> int:
    """CRC-8 SAE J1850 of ``data`` (check value of b"123456789" is 0x4B)."""
    crc = 0xFF
    for byte in data:
        crc = _TABLE[crc ^ byte]
    return crc ^ 0xFF


def crc8_p01(data: bytes) -> int:
    """CRC-8 SAE J1850's polynomial with init 0x00 and final XOR 0x00, as E2E Profiles 1 and 11 apply it (check
    value of b"123456789": 0x37, the catalogued CRC-8/GSM-A): crccheck's ``Crc8SaeJ1850.calc(data, initvalue=0)``
    XOR 0xFF."""
    crc, table = 0, _P01
    for byte in data:
        crc = table[crc ^ byte]
    return crc


def crc8_h2f(data: bytes) -> int:
    """CRC-8H2F (AUTOSAR Crc_CalculateCRC8H2F) of ``data`` (check value 0xDF): crccheck's ``Crc8Autosar.calc``."""
    crc, table = 0xFF, _H2F
    for byte in data:
        crc = table[crc ^ byte]
    return crc ^ 0xFF


def crc16_ccitt(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (AUTOSAR Crc_CalculateCRC16) of ``data`` (check value 0x29B1): crccheck's
    ``Crc16CcittFalse.calc``."""
    return crc_hqx(data, 0xFFFF)
