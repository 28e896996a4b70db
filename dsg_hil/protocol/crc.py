"""CRC-8 SAE J1850: width 8, poly 0x1D, init 0xFF, not reflected, final XOR 0xFF, check value 0x4B (the polynomial
of AUTOSAR's Crc_CalculateCRC8; how this contract applies it is in :mod:`.e2e`)."""

from __future__ import annotations

__all__ = ["crc8_j1850"]


def _table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table.append(crc)
    return tuple(table)


_TABLE = _table()


def crc8_j1850(data: bytes) -> int:
    """CRC-8 SAE J1850 of ``data`` (check value of b"123456789" is 0x4B)."""
    crc = 0xFF
    for byte in data:
        crc = _TABLE[crc ^ byte]
    return crc ^ 0xFF
