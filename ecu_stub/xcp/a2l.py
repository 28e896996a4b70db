"""The A2L file (ASAM MCD-2 MC, ASAP2 1.71) of ecu-stub's XCP slave, written from the code (:mod:`.memory`,
:mod:`.slave`): each calibration scalar a CHARACTERISTIC (a FLOAT64_IEEE value with its unit and the calibration's
limits; read-only ones marked READ_ONLY), each internal variable a MEASUREMENT (the state and the active clutch
with their names: a COMPU_VTAB of the TCU's own numbers), one DAQ event channel for the control period, and the
XCP on CAN IF_DATA with the IDs the slave serves (``ecu-stub --a2l FILE``)."""

from __future__ import annotations

import re

from .memory import CAL_BASE, MEAS_BASE, MEAS_SIZE, MEASUREMENTS, cal_values
from .slave import DEFAULT_IDS, EVENT_CYCLE, EVENT_NAME, EVENT_UNIT_1MS, MAX_CTO, MAX_DAQ, MAX_DTO, MAX_ENTRY_SIZE

__all__ = ["a2l_text", "symbol"]

BITRATE = 500_000  # the DBC's


def symbol(name: str) -> str:
    """An A2L identifier of ``name``: ``strategy.T_safe_c`` -> ``strategy_T_safe_c``."""
    return re.sub(r"[^A-Za-z0-9_]", "_", name)


def _unit_method(unit: str) -> str:
    return "CM_" + (symbol(unit.replace("/", "_per_").replace("^", "")) if unit else "none")


def a2l_text(request_id: int = DEFAULT_IDS[0], response_id: int = DEFAULT_IDS[1], version: str = "",
             name: str = "ecu_stub") -> str:
    """The A2L of the slave on CRO ID ``request_id`` and DTO ID ``response_id``; ``version``: the software's."""
    values = cal_values()
    units = sorted({v.unit for v in values} | {m.unit for m in MEASUREMENTS})
    out = [
        "ASAP2_VERSION 1 71",
        f'/begin PROJECT {name} "dsg-hil ecu-stub: the TCU of a DSG creeping in traffic"',
        f'  /begin HEADER "written by ecu-stub --a2l" VERSION "{version}" /end HEADER',
        '  /begin MODULE TCU "transmission control unit: creep strategy, plate temperature prediction, thermal '
        'monitor"',
        '    /begin MOD_COMMON "" BYTE_ORDER MSB_LAST ALIGNMENT_BYTE 1 ALIGNMENT_WORD 1 ALIGNMENT_LONG 1 '
        'ALIGNMENT_FLOAT32_IEEE 1 ALIGNMENT_FLOAT64_IEEE 1 /end MOD_COMMON',
        '    /begin MOD_PAR "ecu-stub memory map"',
        f'      /begin MEMORY_SEGMENT calibration "calibration values" DATA RAM INTERN 0x{CAL_BASE:X} '
        f'0x{8 * len(values):X} -1 -1 -1 -1 -1 /end MEMORY_SEGMENT',
        f'      /begin MEMORY_SEGMENT measurement "internal variables" VARIABLES RAM INTERN 0x{MEAS_BASE:X} '
        f'0x{MEAS_SIZE:X} -1 -1 -1 -1 -1 /end MEMORY_SEGMENT',
        "    /end MOD_PAR",
        "    /begin IF_DATA XCP",
        f"      /begin PROTOCOL_LAYER 0x0100 1000 1000 0 0 0 0 0 {MAX_CTO} {MAX_DTO} BYTE_ORDER_MSB_LAST "
        "ADDRESS_GRANULARITY_BYTE",
        "        OPTIONAL_CMD GET_COMM_MODE_INFO OPTIONAL_CMD GET_ID OPTIONAL_CMD SET_MTA OPTIONAL_CMD UPLOAD",
        "        OPTIONAL_CMD SHORT_UPLOAD OPTIONAL_CMD DOWNLOAD OPTIONAL_CMD GET_DAQ_PROCESSOR_INFO",
        "        OPTIONAL_CMD GET_DAQ_RESOLUTION_INFO OPTIONAL_CMD GET_DAQ_EVENT_INFO OPTIONAL_CMD GET_DAQ_LIST_MODE",
        "        OPTIONAL_CMD FREE_DAQ OPTIONAL_CMD ALLOC_DAQ OPTIONAL_CMD ALLOC_ODT OPTIONAL_CMD ALLOC_ODT_ENTRY",
        "        OPTIONAL_CMD SET_DAQ_PTR OPTIONAL_CMD WRITE_DAQ OPTIONAL_CMD SET_DAQ_LIST_MODE",
        "        OPTIONAL_CMD START_STOP_DAQ_LIST OPTIONAL_CMD START_STOP_SYNCH",
        "      /end PROTOCOL_LAYER",
        f"      /begin DAQ DYNAMIC {MAX_DAQ} 1 0 OPTIMISATION_TYPE_DEFAULT ADDRESS_EXTENSION_FREE "
        f"IDENTIFICATION_FIELD_TYPE_ABSOLUTE GRANULARITY_ODT_ENTRY_SIZE_DAQ_BYTE {MAX_ENTRY_SIZE} "
        "NO_OVERLOAD_INDICATION PRESCALER_SUPPORTED",
        f'        /begin EVENT "{EVENT_NAME}" "period" 0 DAQ 255 {EVENT_CYCLE} {EVENT_UNIT_1MS} 0 /end EVENT',
        "      /end DAQ",
        f"      /begin XCP_ON_CAN 0x0100 CAN_ID_MASTER 0x{request_id:X} CAN_ID_SLAVE 0x{response_id:X} "
        f"BAUDRATE {BITRATE} /end XCP_ON_CAN",
        "    /end IF_DATA",
        "    /begin RECORD_LAYOUT Scalar_FLOAT64 FNC_VALUES 1 FLOAT64_IEEE COLUMN_DIR DIRECT /end RECORD_LAYOUT",
    ]
    for unit in units:
        out.append(f'    /begin COMPU_METHOD {_unit_method(unit)} "{unit or "no unit"}" IDENTICAL "%.6g" "{unit}" '
                   f'/end COMPU_METHOD')
    for m in MEASUREMENTS:
        if m.names:
            pairs = " ".join(f'{number} "{name}"' for number, name in m.names)
            out.append(f'    /begin COMPU_METHOD CM_{m.name} "{m.name} by name" TAB_VERB "%.0f" "" COMPU_TAB_REF '
                       f'VT_{m.name} /end COMPU_METHOD')
            out.append(f'    /begin COMPU_VTAB VT_{m.name} "{m.name}\'s names" TAB_VERB {len(m.names)} {pairs} '
                       f'DEFAULT_VALUE "none" /end COMPU_VTAB')
    for v in values:
        read_only = " READ_ONLY" if v.read_only else ""
        out.append(f'    /begin CHARACTERISTIC {symbol(v.name)} "{v.name} [{v.unit}]" VALUE 0x{v.address:X} '
                   f'Scalar_FLOAT64 0 {_unit_method(v.unit)} {v.lo!r} {v.hi!r}{read_only} /end CHARACTERISTIC')
    for m in MEASUREMENTS:
        method = f"CM_{m.name}" if m.names else _unit_method(m.unit)
        out.append(f'    /begin MEASUREMENT {m.name} "{m.description}" {m.datatype} {method} 0 0 '
                   f'{m.lo!r} {m.hi!r} ECU_ADDRESS 0x{m.address:X} /end MEASUREMENT')
    group = " ".join(m.name for m in MEASUREMENTS)
    cals = " ".join(symbol(v.name) for v in values)
    out += [
        f'    /begin GROUP internals "the TCU\'s internal variables" ROOT /begin REF_MEASUREMENT {group} '
        f'/end REF_MEASUREMENT /end GROUP',
        f'    /begin GROUP calibration "the calibration file\'s scalars" ROOT /begin REF_CHARACTERISTIC {cals} '
        f'/end REF_CHARACTERISTIC /end GROUP',
        "  /end MODULE",
        "/end PROJECT",
    ]
    return "\n".join(out) + "\n"
