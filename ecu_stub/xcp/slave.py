"""ecu-stub's XCP slave (ASAM MCD-1 XCP 1.x) on CAN: a master's command packets (CRO) on one ID, responses, error
packets and DAQ packets (DTO) on the other, classic 8-byte frames, Intel byte order, byte granularity.

Commands: CONNECT, DISCONNECT, GET_STATUS, SYNCH, GET_COMM_MODE_INFO, GET_ID (1: the A2L's name; 0: a text),
SET_MTA, UPLOAD, SHORT_UPLOAD, DOWNLOAD (up to 6 bytes a packet: a calibration value comes in two, and is taken
with the second, :mod:`.memory`; no block modes), and dynamic DAQ: GET_DAQ_PROCESSOR_INFO,
GET_DAQ_RESOLUTION_INFO, GET_DAQ_EVENT_INFO, FREE_DAQ, ALLOC_DAQ, ALLOC_ODT, ALLOC_ODT_ENTRY, SET_DAQ_PTR, WRITE_DAQ,
SET_DAQ_LIST_MODE, GET_DAQ_LIST_MODE, START_STOP_DAQ_LIST, START_STOP_SYNCH. One event channel, the control period
(:meth:`XcpSlave.period`); absolute ODT numbers as PIDs, no timestamps, prescalers. No seed and key: nothing is
protected.

Every request is answered (once connected; before, only CONNECT is), with an error packet where the standard gives
one: ERR_CMD_UNKNOWN, ERR_CMD_SYNTAX (too short), ERR_OUT_OF_RANGE (an address outside the memory map, a length or
number beyond the limits, a calibration value outside its limits), ERR_WRITE_PROTECTED (measurements, read-only
calibration values), ERR_SEQUENCE, ERR_DAQ_CONFIG, ERR_MEMORY_OVERFLOW, ERR_MODE_NOT_VALID, ERR_DAQ_ACTIVE. Memory:
:mod:`ecu_stub.xcp.memory`.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass, field

from .memory import TcuMemory

__all__ = ["DEFAULT_IDS", "EVENT_NAME", "XcpSlave"]

DEFAULT_IDS = (0x7D0, 0x7D1)  # CRO (master -> slave), DTO (slave -> master)
MAX_CTO = MAX_DTO = 8
MAX_DAQ = 16  # DAQ lists
MAX_ODTS = 0xBF  # ODTs in all (absolute ODT numbers are PIDs 0x00-0xBE)
MAX_ENTRIES = 255  # ODT entries in all
MAX_ENTRY_SIZE = MAX_DTO - 1
EVENT_NAME = "control period"
EVENT_CYCLE, EVENT_UNIT_1MS = 10, 6

RES, ERR = 0xFF, 0xFE
ERR_CMD_SYNCH, ERR_DAQ_ACTIVE, ERR_CMD_UNKNOWN, ERR_CMD_SYNTAX = 0x00, 0x11, 0x20, 0x21
ERR_OUT_OF_RANGE, ERR_WRITE_PROTECTED, ERR_MODE_NOT_VALID, ERR_SEQUENCE = 0x22, 0x23, 0x27, 0x29
ERR_DAQ_CONFIG, ERR_MEMORY_OVERFLOW = 0x2A, 0x2B

CONNECT, DISCONNECT, GET_STATUS, SYNCH, GET_COMM_MODE_INFO, GET_ID = 0xFF, 0xFE, 0xFD, 0xFC, 0xFB, 0xFA
SET_MTA, UPLOAD, SHORT_UPLOAD, DOWNLOAD = 0xF6, 0xF5, 0xF4, 0xF0
SET_DAQ_PTR, WRITE_DAQ, SET_DAQ_LIST_MODE, GET_DAQ_LIST_MODE, START_STOP_DAQ_LIST = 0xE2, 0xE1, 0xE0, 0xDF, 0xDE
START_STOP_SYNCH, GET_DAQ_PROCESSOR_INFO, GET_DAQ_RESOLUTION_INFO, GET_DAQ_EVENT_INFO = 0xDD, 0xDA, 0xD9, 0xD7
FREE_DAQ, ALLOC_DAQ, ALLOC_ODT, ALLOC_ODT_ENTRY = 0xD6, 0xD5, 0xD4, 0xD3
LENGTH = {  # the shortest packet of each command
    CONNECT: 2, DISCONNECT: 1, GET_STATUS: 1, SYNCH: 1, GET_COMM_MODE_INFO: 1, GET_ID: 2, SET_MTA: 8, UPLOAD: 2,
    SHORT_UPLOAD: 8, DOWNLOAD: 2, SET_DAQ_PTR: 6, WRITE_DAQ: 8, SET_DAQ_LIST_MODE: 8,
    GET_DAQ_LIST_MODE: 4, START_STOP_DAQ_LIST: 4, START_STOP_SYNCH: 2, GET_DAQ_PROCESSOR_INFO: 1,
    GET_DAQ_RESOLUTION_INFO: 1, GET_DAQ_EVENT_INFO: 4, FREE_DAQ: 1, ALLOC_DAQ: 4, ALLOC_ODT: 5, ALLOC_ODT_ENTRY: 6,
}
MODE_SELECTED, MODE_DIRECTION, MODE_TIMESTAMP, MODE_PID_OFF, MODE_RUNNING = 0x01, 0x02, 0x10, 0x20, 0x40


@dataclass
class DaqList:
    """One dynamic DAQ list: its ODTs (each a list of entries (address, size)), mode, prescaler, priority."""

    odts: list[list[tuple[int, int]]] = field(default_factory=list)
    entries: list[int] = field(default_factory=list)  # entries allocated per ODT
    event: int = 0
    prescaler: int = 1
    priority: int = 0
    selected: bool = False
    running: bool = False
    cycles: int = 0  # control periods since started (the prescaler's count)
    first_pid: int = 0


class XcpSlave:
    """The slave on CRO ID ``request_id`` (frames the TCU takes) and DTO ID ``response_id``; ``send(frame_id,
    data)`` puts a frame on the bus; ``identity``: GET_ID type 1's answer (the A2L file's name without extension).
    :meth:`take` a CRO frame's data; :meth:`period` after each control period (measurements refreshed, DAQ sent)."""

    def __init__(self, memory: TcuMemory, request_id: int, response_id: int, send: Callable[[int, bytes], None],
                 identity: str = "ecu_stub") -> None:
        self.memory, self.request_id, self.response_id, self._send = memory, request_id, response_id, send
        self.identity = identity
        self.connected = False
        self.mta = 0
        self._blob: bytes | None = None  # GET_ID's or an event's name: what UPLOAD reads while set (from MTA 0)
        self.daq: list[DaqList] = []
        self._allocated = 0  # 0 free, 1 DAQ lists, 2 ODTs, 3 entries (the allocation's order)
        self._ptr: tuple[int, int, int] | None = None
        self.errors = 0  # error packets sent
        self.dto_sent = 0

    # -- the bus side
    def take(self, data: bytes) -> None:
        """A CRO frame: its answer, if any, is sent."""
        answer = self.handle(data)
        if answer is not None:
            if answer[0] == ERR:
                self.errors += 1
            self._send(self.response_id, answer)

    def period(self, now: float) -> None:
        """After a control period at TCU time ``now`` [s]: the measurements refreshed, each running DAQ list's ODTs
        sent whose prescaler is due."""
        self.memory.refresh(now)
        for daq in self.daq:
            if not daq.running:
                continue
            daq.cycles += 1
            if daq.cycles % daq.prescaler:
                continue
            read = self.memory.read
            for j, odt in enumerate(daq.odts):
                if odt:
                    self._send(self.response_id, bytes((daq.first_pid + j,)) + b"".join(
                        read(address, size) or bytes(size) for address, size in odt))
                    self.dto_sent += 1

    @property
    def daq_running(self) -> bool:
        return any(d.running for d in self.daq)

    # -- the commands
    def handle(self, data: bytes) -> bytes | None:
        """The answer to a command packet (RES or ERR), or None (none is due: not connected, a block's packet)."""
        if not data:
            return None
        pid = data[0]
        if not self.connected and pid != CONNECT:
            return None  # a disconnected slave answers CONNECT only
        if pid not in LENGTH:
            return _err(ERR_CMD_UNKNOWN)
        if len(data) < LENGTH[pid]:
            return _err(ERR_CMD_SYNTAX)
        return self._commands[pid](self, data)

    def _connect(self, data: bytes) -> bytes:
        self.connected = True
        # RESOURCE: CAL/PAG and DAQ; COMM_MODE_BASIC: Intel, byte granularity, OPTIONAL (GET_COMM_MODE_INFO)
        return bytes((RES, 0x05, 0x80, MAX_CTO)) + struct.pack("<H", MAX_DTO) + bytes((0x01, 0x01))

    def _disconnect(self, data: bytes) -> bytes:
        self._stop_all()
        self.connected, self._blob = False, None
        return bytes((RES,))

    def _get_status(self, data: bytes) -> bytes:
        return bytes((RES, MODE_RUNNING if self.daq_running else 0, 0, 0, 0, 0))

    def _synch(self, data: bytes) -> bytes:
        return _err(ERR_CMD_SYNCH)

    def _comm_mode_info(self, data: bytes) -> bytes:
        # COMM_MODE_OPTIONAL: no block mode, not interleaved; MAX_BS, MIN_ST, QUEUE_SIZE 0; driver version 1.0
        return bytes((RES, 0, 0, 0, 0, 0, 0, 0x10))

    def _get_id(self, data: bytes) -> bytes:
        if data[1] not in (0, 1):
            return _err(ERR_OUT_OF_RANGE)
        text = self.identity if data[1] == 1 else f"{self.identity}: dsg-hil TCU, XCP on CAN"
        self._upload_from(text.encode("ascii", "replace"))
        return bytes((RES, 0, 0, 0)) + struct.pack("<I", len(self._blob or b""))

    def _upload_from(self, blob: bytes) -> None:
        self._blob, self.mta = blob, 0

    def _set_mta(self, data: bytes) -> bytes:
        if data[3] != 0:
            return _err(ERR_OUT_OF_RANGE)
        self._blob, self.mta = None, struct.unpack_from("<I", data, 4)[0]
        return bytes((RES,))

    def _read(self, n: int) -> bytes | None:
        if not 1 <= n <= MAX_CTO - 1:
            return None
        if self._blob is not None:
            chunk = self._blob[self.mta:self.mta + n]
            if len(chunk) < n:
                return None
        elif (found := self.memory.read(self.mta, n)) is None:
            return None
        else:
            chunk = found
        self.mta += n
        return bytes((RES,)) + chunk

    def _upload(self, data: bytes) -> bytes:
        return self._read(data[1]) or _err(ERR_OUT_OF_RANGE)

    def _short_upload(self, data: bytes) -> bytes:
        if data[3] != 0:
            return _err(ERR_OUT_OF_RANGE)
        blob, mta = self._blob, self.mta
        self._blob, self.mta = None, struct.unpack_from("<I", data, 4)[0]
        answer = self._read(data[1])
        if answer is None:
            self._blob, self.mta = blob, mta
            return _err(ERR_OUT_OF_RANGE)
        return answer

    def _download(self, data: bytes) -> bytes:
        n = data[1]
        if not 1 <= n <= MAX_CTO - 2 or self._blob is not None:
            return _err(ERR_OUT_OF_RANGE)
        if len(data) < 2 + n:
            return _err(ERR_CMD_SYNTAX)
        return self._write(self.mta, bytes(data[2:2 + n]))

    def _write(self, address: int, payload: bytes) -> bytes:
        code = self.memory.write(address, payload)
        if code:
            return _err(code)
        self.mta = address + len(payload)
        return bytes((RES,))

    # -- DAQ
    def _processor_info(self, data: bytes) -> bytes:
        # DAQ_PROPERTIES: dynamic, prescaler; MAX_DAQ, MAX_EVENT_CHANNEL 1, MIN_DAQ 0; DAQ_KEY_BYTE: absolute ODT
        # numbers, address extension free, default optimisation
        return bytes((RES, 0x03)) + struct.pack("<HH", MAX_DAQ, 1) + bytes((0, 0x00))

    def _resolution_info(self, data: bytes) -> bytes:
        return bytes((RES, 1, MAX_ENTRY_SIZE, 1, 0, 0, 0, 0))  # no timestamps

    def _event_info(self, data: bytes) -> bytes:
        if struct.unpack_from("<H", data, 2)[0] != 0:
            return _err(ERR_OUT_OF_RANGE)
        name = EVENT_NAME.encode("ascii")
        self._upload_from(name)
        return bytes((RES, 0x04, 0xFF, len(name), EVENT_CYCLE, EVENT_UNIT_1MS, 0))

    def _free_daq(self, data: bytes) -> bytes:
        self.daq, self._allocated, self._ptr = [], 0, None
        return bytes((RES,))

    def _alloc_daq(self, data: bytes) -> bytes:
        count = struct.unpack_from("<H", data, 2)[0]
        if self._allocated != 0 or self.daq_running:
            return _err(ERR_SEQUENCE)
        if count > MAX_DAQ:
            return _err(ERR_MEMORY_OVERFLOW)
        self.daq, self._allocated = [DaqList() for _ in range(count)], 1
        return bytes((RES,))

    def _alloc_odt(self, data: bytes) -> bytes:
        number, count = struct.unpack_from("<H", data, 2)[0], data[4]
        if self._allocated not in (1, 2):
            return _err(ERR_SEQUENCE)
        if number >= len(self.daq):
            return _err(ERR_OUT_OF_RANGE)
        if sum(len(d.odts) for d in self.daq) + count > MAX_ODTS:
            return _err(ERR_MEMORY_OVERFLOW)
        daq = self.daq[number]
        daq.odts += [[] for _ in range(count)]
        daq.entries += [0] * count
        self._allocated = 2
        first = 0
        for d in self.daq:
            d.first_pid, first = first, first + len(d.odts)
        return bytes((RES,))

    def _alloc_odt_entry(self, data: bytes) -> bytes:
        number, odt, count = struct.unpack_from("<H", data, 2)[0], data[4], data[5]
        if self._allocated not in (2, 3):
            return _err(ERR_SEQUENCE)
        if number >= len(self.daq) or odt >= len(self.daq[number].odts) or count > MAX_ENTRY_SIZE:
            return _err(ERR_OUT_OF_RANGE)
        if sum(sum(d.entries) for d in self.daq) + count > MAX_ENTRIES:
            return _err(ERR_MEMORY_OVERFLOW)
        self.daq[number].entries[odt] = count
        self._allocated = 3
        return bytes((RES,))

    def _set_daq_ptr(self, data: bytes) -> bytes:
        number, odt, entry = struct.unpack_from("<H", data, 2)[0], data[4], data[5]
        if number >= len(self.daq) or odt >= len(self.daq[number].odts) or entry >= self.daq[number].entries[odt]:
            return _err(ERR_OUT_OF_RANGE)
        if self.daq[number].running:
            return _err(ERR_DAQ_ACTIVE)
        self._ptr = (number, odt, entry)
        return bytes((RES,))

    def _write_daq(self, data: bytes) -> bytes:
        if self._ptr is None:
            return _err(ERR_SEQUENCE)
        number, odt, entry = self._ptr
        daq = self.daq[number]
        bit, size, ext, address = data[1], data[2], data[3], struct.unpack_from("<I", data, 4)[0]
        if daq.running:
            return _err(ERR_DAQ_ACTIVE)
        if entry >= daq.entries[odt] or bit != 0xFF or ext != 0 or not 1 <= size <= MAX_ENTRY_SIZE:
            return _err(ERR_OUT_OF_RANGE)
        if code := self.memory.check(address, size):
            return _err(code)
        entries = daq.odts[odt]
        del entries[entry:]
        if sum(s for _, s in entries) + size > MAX_DTO - 1:
            return _err(ERR_DAQ_CONFIG)
        entries.append((address, size))
        self._ptr = (number, odt, entry + 1)
        return bytes((RES,))

    def _set_daq_list_mode(self, data: bytes) -> bytes:
        mode, number, event = data[1], *struct.unpack_from("<HH", data, 2)
        prescaler, priority = data[6], data[7]
        if number >= len(self.daq) or event != 0 or prescaler < 1:
            return _err(ERR_OUT_OF_RANGE)
        if mode & (MODE_DIRECTION | MODE_TIMESTAMP | MODE_PID_OFF):
            return _err(ERR_MODE_NOT_VALID)  # no STIM, no timestamps, PIDs always
        daq = self.daq[number]
        if daq.running:
            return _err(ERR_DAQ_ACTIVE)
        daq.event, daq.prescaler, daq.priority = event, prescaler, priority
        return bytes((RES,))

    def _get_daq_list_mode(self, data: bytes) -> bytes:
        number = struct.unpack_from("<H", data, 2)[0]
        if number >= len(self.daq):
            return _err(ERR_OUT_OF_RANGE)
        d = self.daq[number]
        mode = (MODE_SELECTED if d.selected else 0) | (MODE_RUNNING if d.running else 0)
        return bytes((RES, mode, 0, 0)) + struct.pack("<H", d.event) + bytes((d.prescaler, d.priority))

    def _start_stop_daq_list(self, data: bytes) -> bytes:
        mode, number = data[1], struct.unpack_from("<H", data, 2)[0]
        if number >= len(self.daq) or mode > 2:
            return _err(ERR_OUT_OF_RANGE)
        daq = self.daq[number]
        if mode != 0 and (not daq.odts or any(len(o) != n for o, n in zip(daq.odts, daq.entries))):
            return _err(ERR_DAQ_CONFIG)  # not configured whole
        if mode == 0:
            daq.running = daq.selected = False
        elif mode == 1:
            daq.running, daq.cycles = True, 0
        else:
            daq.selected = True
        return bytes((RES, daq.first_pid))

    def _start_stop_synch(self, data: bytes) -> bytes:
        mode = data[1]
        if mode > 2:
            return _err(ERR_OUT_OF_RANGE)
        if mode == 0:
            self._stop_all()
        for daq in self.daq:
            if daq.selected:
                if mode == 1:
                    daq.running, daq.cycles = True, 0
                elif mode == 2:
                    daq.running = False
                daq.selected = False
        return bytes((RES,))

    def _stop_all(self) -> None:
        for daq in self.daq:
            daq.running = daq.selected = False

    _commands: dict[int, Callable[[XcpSlave, bytes], bytes | None]] = {
        CONNECT: _connect, DISCONNECT: _disconnect, GET_STATUS: _get_status, SYNCH: _synch,
        GET_COMM_MODE_INFO: _comm_mode_info, GET_ID: _get_id, SET_MTA: _set_mta, UPLOAD: _upload,
        SHORT_UPLOAD: _short_upload, DOWNLOAD: _download,
        GET_DAQ_PROCESSOR_INFO: _processor_info, GET_DAQ_RESOLUTION_INFO: _resolution_info,
        GET_DAQ_EVENT_INFO: _event_info, FREE_DAQ: _free_daq, ALLOC_DAQ: _alloc_daq, ALLOC_ODT: _alloc_odt,
        ALLOC_ODT_ENTRY: _alloc_odt_entry, SET_DAQ_PTR: _set_daq_ptr, WRITE_DAQ: _write_daq,
        SET_DAQ_LIST_MODE: _set_daq_list_mode, GET_DAQ_LIST_MODE: _get_daq_list_mode,
        START_STOP_DAQ_LIST: _start_stop_daq_list, START_STOP_SYNCH: _start_stop_synch,
    }


def _err(code: int) -> bytes:
    return bytes((ERR, code))
