"""A recorded bus log (candump -L, .asc, .blf, ... through python-can's LogReader) decoded with the DBC: the one
reader of ``dsg-hil report`` (:mod:`dsg_hil.paper.report.log`) and ``python -m ecu_stub.identify``.

Whatever python-can's readers raise on a missing or garbled file becomes one
:class:`~dsg_hil.common.errors.LogError` naming the file (exit 2).
"""

from __future__ import annotations

from collections.abc import Iterator, MutableMapping
from pathlib import Path

import can
from cantools.database.can import Database

from ..common.errors import LogError
from .codec import Codec, DecodedFrame, FrameError

__all__ = ["decoded_frames", "log_codec"]


def log_codec(db: Database) -> Codec:
    """A codec of every cyclic DBC message protected by a counter and a CRC, all its signals but those two."""
    return Codec(db, {m.name: [s.name for s in m.signals if s.name not in ("Counter", "CRC")] for m in db.messages
                      if {"Counter", "CRC"} <= {s.name for s in m.signals} and m.cycle_time})


def decoded_frames(path: str | Path, codec: Codec,
                   counts: MutableMapping[str, int] | None = None) -> Iterator[tuple[float, DecodedFrame | None]]:
    """``(timestamp, frame)`` of every data frame of the log in file order, ``frame`` None where ``codec`` does not
    decode it (an ID it does not know, or a frame failing its checks). ``counts`` (if given) tallies ``decoded``,
    ``rejected`` and ``unknown`` frames."""
    if not Path(path).is_file():
        raise LogError(f"{path}: cannot read the log (log file not found)")
    tally = counts if counts is not None else {}
    for key in ("decoded", "rejected", "unknown"):
        tally.setdefault(key, 0)
    try:
        with can.LogReader(str(path)) as reader:
            for msg in reader:
                if msg.is_error_frame or msg.is_remote_frame:
                    continue
                try:
                    frame: DecodedFrame | None = codec.decode(msg.arbitration_id, bytes(msg.data))
                except FrameError as exc:
                    tally["unknown" if exc.reason == "unknown" else "rejected"] += 1
                    frame = None
                else:
                    tally["decoded"] += 1
                yield msg.timestamp, frame
    except LogError:
        raise
    except Exception as exc:  # noqa: BLE001 - each of python-can's readers raises its own types on garbage
        raise LogError(f"{path}: cannot read the log ({type(exc).__name__}: {exc})") from exc
