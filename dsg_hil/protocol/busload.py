"""Bus load implied by the DBC's cycle times (classic CAN, worst-case bit stuffing)."""

from __future__ import annotations

from cantools.database.can import Database

__all__ = ["bus_load", "frame_bits"]


def frame_bits(dlc: int, extended: bool = False) -> int:
    """Worst-case length of a classic CAN data frame [bits], stuff bits and 3-bit interframe space included."""
    header = 39 if extended else 19  # SOF, arbitration and control fields
    stuffed = header + 8 * dlc + 15  # ... data and CRC: the bits subject to stuffing
    return stuffed + (1 + 2 + 7 + 3) + (stuffed - 1) // 4  # CRC delimiter, ACK, EOF, IFS; worst-case stuffing


def bus_load(db: Database, bitrate: float = 500_000.0) -> tuple[float, list[tuple[str, int, float, float]]]:
    """Total load (0-1) and per message (name, cycle time ms, frames/s, load)."""
    rows = []
    for m in db.messages:
        if not m.cycle_time:
            continue
        rate = 1000.0 / m.cycle_time
        load = rate * frame_bits(m.length, m.is_extended_frame) / bitrate
        rows.append((m.name, m.cycle_time, rate, load))
    return sum(r[3] for r in rows), rows
