"""A recorded bus log (candump -L, .asc, .blf, .mf4 with asammdf ... through python-can's LogReader) decoded with
the DBC: the one reader of ``dsg-hil report`` (:mod:`dsg_hil.paper.report.log`) and ``python -m ecu_stub.identify``.

Whatever python-can's readers raise on a missing or garbled file becomes one
:class:`~dsg_hil.common.errors.LogError` naming the file (exit 2).
"""

from __future__ import annotations

import logging
from collections.abc import Iterator, Mapping, MutableMapping
from pathlib import Path
from typing import TextIO, cast

import can
from cantools.database.can import Database

from ..common.errors import LogError
from .bus import require_mf4
from .codec import Codec, DecodedFrame, FrameError

__all__ = ["decoded_frames", "log_codec"]

log = logging.getLogger(__name__)


def log_codec(db: Database, protection: Mapping[str, Mapping[str, object]] | None = None) -> Codec:
    """A codec of every cyclic DBC message protected by a counter and a CRC, all its signals but those two; and of
    each message of ``protection`` (a binding's: by message, its profile's table), all its signals but the ones
    that carry the protection. CAN FD frames decode as classic ones (the codec knows their lengths)."""
    from .profiles import protection_for, protection_signals  # noqa: PLC0415

    uses = {m.name: [s.name for s in m.signals if s.name not in ("Counter", "CRC")] for m in db.messages
            if {"Counter", "CRC"} <= {s.name for s in m.signals} and m.cycle_time}
    for name, table in (protection or {}).items():
        message = db.get_message_by_name(name)
        carriers = protection_signals(message, protection_for(message, table))
        uses[name] = [s.name for s in message.signals if s.name not in carriers]
    return Codec(db, uses, protection=protection)


def decoded_frames(path: str | Path, codec: Codec,
                   counts: MutableMapping[str, int] | None = None) -> Iterator[tuple[float, DecodedFrame | None]]:
    """``(timestamp, frame)`` of every data frame of the log in file order, ``frame`` None where ``codec`` does not
    decode it (an ID it does not know, or a frame failing its checks). ``counts`` (if given) tallies ``decoded``,
    ``rejected`` and ``unknown`` frames.

    A candump log (``.log``) whose last line is cut short (what a logger killed mid-write leaves) is read up to
    that line, with a warning naming the file and line; another line it cannot read is a :class:`LogError`
    naming the file and line."""
    if not Path(path).is_file():
        raise LogError(f"{path}: cannot read the log (log file not found)")
    tally = counts if counts is not None else {}
    for key in ("decoded", "rejected", "unknown"):
        tally.setdefault(key, 0)
    if str(path).lower().endswith(".mf4"):
        require_mf4(str(path))
    lines = _Lines(Path(path)) if str(path).lower().endswith(".log") else None
    try:
        with (can.LogReader(str(path)) if lines is None
              else can.CanutilsLogReader(cast("TextIO", lines))) as reader:  # (it iterates lines and closes)
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
        if lines is None:
            raise LogError(f"{path}: cannot read the log ({type(exc).__name__}: {exc})") from exc
        if not lines.cut:
            raise LogError(f"{path}:{lines.number}: cannot read the log line {lines.last!r} "
                           f"({type(exc).__name__}: {exc})") from exc
        log.warning("%s:%d: the last line is cut short (%r: a logger stopped mid-write?): read up to it", path,
                    lines.number, lines.last)


class _Lines:
    """The lines of a text file for python-can's candump reader, counted: ``number`` and ``last`` of the line
    read last, ``cut`` whether it is the file's last and has no line end."""

    def __init__(self, path: Path) -> None:
        try:
            self._file = path.open(encoding="utf-8", errors="replace", newline="")
        except OSError as exc:
            raise LogError(f"{path}: cannot read the log ({exc.strerror})") from exc
        self.number, self.last, self.cut = 0, "", False

    def __iter__(self) -> Iterator[str]:
        for line in self._file:
            self.number, self.last = self.number + 1, line.rstrip("\r\n")
            self.cut = not line.endswith("\n")
            yield line

    def close(self) -> None:
        self._file.close()
