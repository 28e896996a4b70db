"""The TCU's memory as an XCP master sees it (:func:`tcu_memory`): what the A2L file describes
(:mod:`ecu_stub.xcp.a2l`) and the slave reads and writes (:mod:`ecu_stub.xcp.slave`).

* Calibration, from :data:`CAL_BASE` (0x10000): every scalar of the calibration file (sections strategy, speed,
  launch, vehicle, clutch.CL, clutch.CH; the friction map is not in it), one little-endian IEEE double each, 8 bytes
  apart in the file's order. A write is taken once all 8 bytes of a value have come (on CAN a DOWNLOAD carries 6:
  two of them), checked against the calibration's limits (the file's, :func:`ecu_stub.calibration.c`) and its cross
  checks, and handed to the controller (:meth:`ecu_stub.controller.CreepController.recalibrate`): the next control
  period runs with it. Values the runner's plausibility checks take at start-up too (:data:`READ_ONLY`) are read
  only: changed in the controller alone, the two would disagree.
* Measurements, from :data:`MEAS_BASE` (0x20000): the controller's internals after each control period
  (:meth:`TcuMemory.refresh`), little-endian; written by nobody but the TCU. ``State`` and ``ActiveClutch`` are the
  TCU's own numbers (the shipped DBC's value tables, as its UDS DIDs give them and the A2L names them), on any
  matrix: a binding's ``values`` renumber its frames, not its memory.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

from ..calibration import SECTIONS, CalibrationError, TcuCalibration
from ..controller import CreepController
from ..tcu_io import CLUTCH_VALUES, STATE_VALUES

__all__ = ["CAL_BASE", "MEAS_BASE", "MEASUREMENTS", "READ_ONLY", "CalValue", "Measured", "TcuMemory", "cal_values",
           "tcu_memory"]

CAL_BASE = 0x10000
MEAS_BASE = 0x20000
# read by the runner's checks when it is built (ecu_stub.runner: speed vote, sensor checks) as well as by the
# controller: a run-time change would reach one of them only
READ_ONLY = frozenset({"strategy.hydraulic_lag_s", "vehicle.input_ratio", "vehicle.brake_decel_mps2",
                       "clutch.CL.speed_ratio_m", "clutch.CH.speed_ratio_m", "clutch.CL.cooling_w_k",
                       "clutch.CH.cooling_w_k", "clutch.CL.K_plate_oil_w_k", "clutch.CH.K_plate_oil_w_k"})


@dataclass(frozen=True)
class CalValue:
    """One calibration scalar: ``name`` (``section.key``, as in the calibration file), its address, unit and
    limits."""

    name: str
    section: str  # the attribute of TcuCalibration (CL, CH for clutch.CL, clutch.CH)
    key: str
    address: int
    unit: str
    lo: float
    hi: float
    read_only: bool


@dataclass(frozen=True)
class Measured:
    """One measurement: ``name``, A2L data type, address, unit, physical range and what it is; ``names``: by number,
    the name of each value (a state's), none for a quantity."""

    name: str
    datatype: str  # FLOAT32_IEEE, ULONG, UBYTE
    address: int
    unit: str
    lo: float
    hi: float
    description: str
    names: tuple[tuple[int, str], ...] = ()


def cal_values() -> tuple[CalValue, ...]:
    """The calibration scalars in the file's order, with their addresses."""
    found: list[CalValue] = []
    for section, cls in SECTIONS.items():
        if section == "friction":
            continue
        for f in fields(cls):
            name = f"{section}.{f.name}"
            found.append(CalValue(name, section.removeprefix("clutch."), f.name, CAL_BASE + 8 * len(found),
                                  f.metadata["unit"], f.metadata["lo"], f.metadata["hi"], name in READ_ONLY))
    return tuple(found)


_TYPES = {"ULONG": ("I", 4), "FLOAT32_IEEE": ("f", 4), "UBYTE": ("B", 1)}
# (name, A2L type, unit, lo, hi, description): the 4-byte values first, then the bytes
_MEASURED = (
    ("t_ms", "ULONG", "ms", 0, 4294967295, "TCU time of the control period (lock-step: the tick's time)"),
    ("T_CL_Pred", "FLOAT32_IEEE", "degC", -40, 1000, "plate temperature of CL predicted by the TCU (TCU_STATUS)"),
    ("T_CH_Pred", "FLOAT32_IEEE", "degC", -40, 1000, "plate temperature of CH predicted by the TCU (TCU_STATUS)"),
    ("Bound_CL", "FLOAT32_IEEE", "degC", -40, 2000, "thermal monitor's bound of the CL plate until a release"),
    ("Bound_CH", "FLOAT32_IEEE", "degC", -40, 2000, "thermal monitor's bound of the CH plate until a release"),
    ("Margin_CL", "FLOAT32_IEEE", "K", -2000, 500, "T_safe minus the monitor's bound of CL"),
    ("Margin_CH", "FLOAT32_IEEE", "K", -2000, 500, "T_safe minus the monitor's bound of CH"),
    ("Integrator", "FLOAT32_IEEE", "N", -1e6, 1e9, "speed controller's integral (wheel force)"),
    ("F_cmd", "FLOAT32_IEEE", "N", -1e6, 1e9, "wheel force the speed controller demands"),
    ("v_ref", "FLOAT32_IEEE", "m/s", -10, 10, "speed reference (the desired speed along its ramp)"),
    ("P_CL_Cmd", "FLOAT32_IEEE", "MPa", 0, 2, "pressure command of CL (TCU_CMD)"),
    ("P_CH_Cmd", "FLOAT32_IEEE", "MPa", 0, 2, "pressure command of CH (TCU_CMD)"),
    ("Q_CL", "FLOAT32_IEEE", "W", 0, 1e7, "friction power of CL as the TCU estimates it"),
    ("Q_CH", "FLOAT32_IEEE", "W", 0, 1e7, "friction power of CH as the TCU estimates it"),
    ("State", "UBYTE", "", 0, 255, "controller state (the shipped DBC's TCU_STATUS.State value)"),
    ("ActiveClutch", "UBYTE", "", 0, 255, "clutch carrying the vehicle (the shipped DBC's TCU_STATUS.ActiveClutch "
                                           "value)"),
    ("BrakeRequest", "UBYTE", "", 0, 1, "full brake requested (TCU_STATUS.BrakeRequest)"),
)

# the measurements that are a state's number, by name: the TCU's own numbers (its UDS DIDs'), on any matrix
_NAMES = {"State": STATE_VALUES, "ActiveClutch": CLUTCH_VALUES}


def _measurements() -> tuple[Measured, ...]:
    found, address = [], MEAS_BASE
    for name, datatype, unit, lo, hi, description in _MEASURED:
        names = tuple(sorted((n, s) for s, n in _NAMES[name].items())) if name in _NAMES else ()
        found.append(Measured(name, datatype, address, unit, float(lo), float(hi), description, names))
        address += _TYPES[datatype][1]
    return tuple(found)


MEASUREMENTS = _measurements()
_LAYOUT = struct.Struct("<" + "".join(_TYPES[m.datatype][0] for m in MEASUREMENTS))
MEAS_SIZE = _LAYOUT.size


class TcuMemory:
    """The memory map of a :class:`~ecu_stub.controller.CreepController` that ``controller()`` gives (the runner's:
    a lock-step start replaces it, keeping its calibration). ``states``/``clutches``: the numbers of State and
    ActiveClutch by name (the measurements' :attr:`Measured.names`, the TCU's own: :func:`tcu_memory`).
    :meth:`read` and :meth:`write` answer None / 0 or an XCP error code (:mod:`ecu_stub.xcp.slave`)."""

    def __init__(self, controller: Callable[[], CreepController], states: dict[str, int],
                 clutches: dict[str, int]) -> None:
        self.controller, self.states, self.clutches = controller, states, clutches
        self.values = cal_values()
        self.cal_image = bytearray(8 * len(self.values))
        self._pending = bytearray(len(self.cal_image))  # bytes written, not yet taken
        self._written = [0] * len(self.values)  # per value: bit i set once byte i has been written
        self.meas_image = bytearray(MEAS_SIZE)
        self.changes = 0  # calibration values taken since start
        self._load(controller().cal)

    def _load(self, cal: TcuCalibration) -> None:
        for i, v in enumerate(self.values):
            struct.pack_into("<d", self.cal_image, 8 * i, float(getattr(getattr(cal, v.section), v.key)))
        self._pending[:] = self.cal_image
        self._written = [0] * len(self.values)

    # -- the control period
    def refresh(self, now: float) -> None:
        """The measurements after the control period at TCU time ``now`` [s]."""
        ctl = self.controller()
        T = ctl.T_pred or {"CL": 0.0, "CH": 0.0}
        T_safe, bound, heat, P = ctl.cal.strategy.T_safe_c, ctl.bound, ctl.heat, ctl.P_cmd
        _LAYOUT.pack_into(self.meas_image, 0, max(0, round(now * 1000.0)) & 0xFFFFFFFF,
                          T["CL"], T["CH"], bound["CL"], bound["CH"], T_safe - bound["CL"], T_safe - bound["CH"],
                          ctl.pid.integral, ctl.F_cmd, ctl.v_ref, P["CL"], P["CH"], heat["CL"], heat["CH"],
                          self.states.get(ctl.state, 0xFF) & 0xFF, self.clutches.get(ctl.active, 0xFF) & 0xFF,
                          int(ctl.brake_request))

    # -- the master's side
    def _region(self, address: int, n: int) -> tuple[bytearray, int] | None:
        """The image holding [address, address + n) and the offset in it, or None (not mapped)."""
        for base, image in ((CAL_BASE, self.cal_image), (MEAS_BASE, self.meas_image)):
            if base <= address and address + n <= base + len(image):
                return image, address - base
        return None

    def read(self, address: int, n: int) -> bytes | None:
        """``n`` bytes from ``address``, or None where any is outside the map."""
        found = self._region(address, n)
        if found is None:
            return None
        image, offset = found
        return bytes(image[offset:offset + n])

    def check(self, address: int, n: int) -> int:
        """0 if ``n`` bytes at ``address`` may be read (an ODT entry), else the XCP error code."""
        return 0 if n > 0 and self._region(address, n) is not None else ERR_OUT_OF_RANGE

    def write(self, address: int, data: bytes) -> int:
        """Write ``data`` at ``address``: 0, or the XCP error code (nothing changed then). Calibration values whose
        8 bytes have all come are checked and taken together; one outside its limits refuses the whole write."""
        n = len(data)
        if not n:
            return 0
        if not (CAL_BASE <= address and address + n <= CAL_BASE + len(self.cal_image)):
            return ERR_WRITE_PROTECTED if self._region(address, n) is not None else ERR_OUT_OF_RANGE
        offset = address - CAL_BASE
        touched = range(offset // 8, (offset + n - 1) // 8 + 1)
        if any(self.values[i].read_only for i in touched):
            return ERR_WRITE_PROTECTED
        pending, written = bytearray(self._pending), list(self._written)
        pending[offset:offset + n] = data
        for k in range(offset, offset + n):
            written[k // 8] |= 1 << (k % 8)
        complete = [i for i in touched if written[i] == 0xFF]
        cal = self.controller().cal
        try:
            for i in complete:
                cal = with_value(cal, self.values[i], struct.unpack_from("<d", pending, 8 * i)[0])
        except CalibrationError:
            for i in complete:  # the refused values: as they are
                pending[8 * i:8 * i + 8] = self.cal_image[8 * i:8 * i + 8]
                written[i] = 0
            self._pending, self._written = pending, written
            return ERR_OUT_OF_RANGE
        for i in complete:
            written[i] = 0
            self.cal_image[8 * i:8 * i + 8] = pending[8 * i:8 * i + 8]
        self._pending, self._written = pending, written
        if complete:
            self.controller().recalibrate(cal)
            self.changes += len(complete)
        return 0


ERR_OUT_OF_RANGE = 0x22
ERR_WRITE_PROTECTED = 0x23


def with_value(cal: TcuCalibration, value: CalValue, x: float) -> TcuCalibration:
    """``cal`` with one scalar changed, checked as the calibration file's values are (its limits, finite; the stop
    ramp within the handover); raises :class:`CalibrationError` naming it."""
    if not math.isfinite(x) or (value.lo is not None and x < value.lo) or (value.hi is not None and x > value.hi):
        raise CalibrationError(f"{value.name}: {x!r} is outside [{value.lo:g}, {value.hi:g}] {value.unit}")
    section = getattr(cal, value.section)
    changed: dict[str, Any] = {f.name: getattr(section, f.name) for f in fields(section)}
    changed[value.key] = float(x)
    parts: dict[str, Any] = {f.name: getattr(cal, f.name) for f in fields(cal)}
    parts[value.section] = type(section)(**changed)
    new = TcuCalibration(**parts)
    if new.strategy.stop_release_s > new.strategy.handover_time_s:
        raise CalibrationError("strategy.stop_release_s: must not exceed strategy.handover_time_s")
    return new


def tcu_memory(runner: Any) -> TcuMemory:
    """The memory map of ``runner``'s controller (an :class:`ecu_stub.runner.TcuRunner` whose controller is a
    :class:`~ecu_stub.controller.CreepController`; else :class:`CalibrationError`)."""
    if not isinstance(runner.controller, CreepController):
        raise CalibrationError(f"XCP: the TCU's controller is a {type(runner.controller).__name__}, not ecu-stub's "
                               f"CreepController: no memory map for it")
    # the TCU's own numbers, which the A2L names (not the runner's: those of the matrix's value tables, where its
    # binding gives values)
    return TcuMemory(lambda: runner.controller, dict(STATE_VALUES), dict(CLUTCH_VALUES))
