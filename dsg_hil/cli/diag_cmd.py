"""``dsg-hil diag``: an ECU's diagnostics over UDS (ISO 14229-1) on ISO-TP (ISO 15765-2), for ecu-stub or a
user's ECU: its DTCs with their status bits and freeze frames, its DIDs, and clearing its DTCs.

The tester is :mod:`dsg_hil.protocol.diag_client` (udsoncan over can-isotp, extra ``diag``), the values decoded by a
description file (:mod:`dsg_hil.protocol.diag`). Everything given is checked before the bus is opened: bad input
sends nothing (exit 2); an ECU that does not answer, or refuses (a negative response, shown by its NRC name), is
exit 1.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import textwrap
from collections.abc import Callable, Mapping, Sequence
from decimal import Decimal
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from ..common.errors import InputError, RunError
from ..common.files import check_output_path
from ..protocol.bus import add_bus_arguments
from . import command_help
from .common import positive_number, progress

if TYPE_CHECKING:
    from ..protocol.diag import DiagDescription
    from ..protocol.diag_client import DtcReport

__all__ = ["ACTIONS", "DEFAULT_MASK", "add_subparser", "did_table", "dtc_table", "resolve_dids"]

ACTIONS = ("dtc", "read", "clear")
DEFAULT_MASK = 0x2F  # testFailed, ...ThisOperationCycle, pending, confirmed, ...SinceLastClear: failed since a clear
_T = TypeVar("_T")
UDS_LOGGERS = ("UdsClient", "Connection", "isotp")  # udsoncan's client and connection, can-isotp's stack

EXAMPLES = """examples (ecu-stub joined to a plant's udp_multicast group: the options 'dsg-hil plant' prints):
  dsg-hil diag dtc -i udp_multicast -c 239.255.12.34 --bus-kwargs port=40000
  dsg-hil diag dtc --mask 0x08 --json dtcs.json -i socketcan -c vcan0
  dsg-hil diag read state plate_temperatures_pred 0xF189 -i socketcan -c vcan0
  dsg-hil diag read -i socketcan -c can0
  dsg-hil diag clear -i socketcan -c vcan0
  dsg-hil diag dtc --description my_ecu.toml --request-id 0x7E0 --response-id 0x7E8 -i socketcan -c can0
"""


def _hex_int(low: int, high: int, what: str) -> Callable[[str], int]:
    """An argparse type: an integer (decimal or 0x hex) within [low, high] (else a usage error, exit 2)."""
    def parse(text: str) -> int:
        try:
            value = int(text, 0)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r} (decimal or 0x hex)") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{what} must be 0x{low:X}-0x{high:X}, got {text}")
        return value
    return parse


def add_subparser(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "diag", help=command_help("diag"), formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EXAMPLES,
        description=textwrap.fill(
            "Talk UDS (ISO 14229-1) on ISO-TP to an ECU on a CAN bus: 'dtc' lists its trouble codes "
                    "whose status matches --mask, with their status bits and freeze frame (snapshot record 1); "
                    "'read' reads DIDs (by name or number; none: every DID of the description); 'clear' clears "
                    "its DTCs (ClearDiagnosticInformation). ecu-stub serves UDS while it runs (and after a "
                    "lock-step plant has gone, until its --idle-exit). A user's ECU: give its request/response "
                    "IDs and a description of its DIDs and DTCs (a TOML file of the shipped diag.toml's form). "
                    "Needs the extra 'diag' (pip install 'dsg-hil[diag]'). Exit 2 for bad input (nothing sent), "
                    "1 when the ECU does not answer or answers with a negative response (its NRC named).", 100))
    parser.add_argument("action", choices=ACTIONS, help="dtc: read DTCs; read: read DIDs; clear: clear DTCs")
    parser.add_argument("did", nargs="*", metavar="DID",
                        help="read: the DIDs, by name in the description or number (0xF189); none: all")
    add_bus_arguments(parser, fresh_udp=False)
    parser.add_argument("--description", metavar="FILE",
                        help="the ECU's DIDs and DTCs, a TOML file of the form of dsg_hil/data/diag.toml "
                             "(default: ecu-stub's, that file)")
    parser.add_argument("--dbc", metavar="FILE",
                        help="DBC whose network attributes DiagRequestId/DiagResponseId give the IDs when neither "
                             "the options nor the description do (default: the shipped dbc/dsg_hil.dbc)")
    parser.add_argument("--request-id", type=_hex_int(0, 0x7FF, "an 11-bit CAN ID"), metavar="ID",
                        help="the tester's requests' CAN ID (e.g. 0x7E0; default: the description's, else the DBC's)")
    parser.add_argument("--response-id", type=_hex_int(0, 0x7FF, "an 11-bit CAN ID"), metavar="ID",
                        help="the ECU's responses' CAN ID (e.g. 0x7E8; default: the description's, else the DBC's)")
    parser.add_argument("--mask", type=_hex_int(0, 0xFF, "a status mask"), default=DEFAULT_MASK, metavar="MASK",
                        help=f"dtc: the status mask (ISO 14229-1 D.2: bit 0 testFailed ... 3 confirmed ...; "
                             f"default 0x{DEFAULT_MASK:02X}, failed since the last clear; 0x08: confirmed; 0xFF: "
                             f"every DTC the ECU supports)")
    parser.add_argument("--snapshots", action=argparse.BooleanOptionalAction, default=True,
                        help="dtc: read each DTC's freeze frame (default: yes)")
    parser.add_argument("--group", type=_hex_int(0, 0xFFFFFF, "a DTC group"), default=0xFFFFFF, metavar="GROUP",
                        help="clear: the group of DTCs (default 0xFFFFFF: all)")
    parser.add_argument("--timeout", type=positive_number, default=2.0, metavar="S",
                        help="seconds to wait for each response (default 2)")
    parser.add_argument("--json", metavar="FILE", help="dtc, read: also write what was read as JSON")
    parser.add_argument("-v", "--verbose", action="store_true",
                        help="log the UDS and ISO-TP traffic (udsoncan's and can-isotp's loggers) on stderr")
    parser.set_defaults(func=_do_diag)


def resolve_dids(names: Sequence[str], description: DiagDescription, where: str) -> list[int]:
    """DID arguments (names in the description, or numbers) -> DIDs; none: every described DID. An InputError
    names the argument and the description ``where`` when it is not described (its values could not be decoded)."""
    if not names:
        return list(description.dids)
    by_name = {did.name: number for number, did in description.dids.items()}
    dids = []
    for name in names:
        try:
            number = int(name, 0)
        except ValueError:
            number = by_name.get(name, -1)
        if number not in description.dids:
            raise InputError(f"DID {name!r}: not in the description {where} (it has "
                             f"{', '.join(sorted(by_name))})")
        dids.append(number)
    return dids


def _ids(args: argparse.Namespace, description: DiagDescription) -> tuple[int, int]:
    """Request and response ID: the options', else the description's, else the DBC's."""
    request = args.request_id if args.request_id is not None else description.request_id
    response = args.response_id if args.response_id is not None else description.response_id
    if request is None or response is None or args.dbc is not None:
        from ..protocol import load_dbc  # noqa: PLC0415 - cantools at run time only
        from ..protocol.codec import DEFAULT_DBC  # noqa: PLC0415
        from ..protocol.diag import diag_ids  # noqa: PLC0415

        db = load_dbc(args.dbc)
        try:
            from_dbc = diag_ids(db)
        except InputError as exc:
            raise type(exc)(f"{args.dbc or DEFAULT_DBC}: {str(exc).removeprefix('DBC: ')}") from None
        request = from_dbc[0] if request is None else request
        response = from_dbc[1] if response is None else response
    if request == response:
        raise InputError(f"--request-id/--response-id: the request and response IDs are both 0x{request:03X}")
    return request, response


def _decimals(scale: float) -> int:
    """Decimals that show a value of resolution ``scale`` (0.25 -> 2, 0.1 -> 1, 1 -> 0)."""
    return max(0, -int(Decimal(repr(scale)).normalize().as_tuple().exponent))


def _field_formats(description: DiagDescription) -> dict[str, tuple[int, str]]:
    return {f.name: (_decimals(f.scale), f.unit) for did in description.dids.values() for f in did.fields}


def _value_lines(values: Mapping[str, Any] | str, formats: Mapping[str, tuple[int, str]], indent: str) -> list[str]:
    if isinstance(values, str):
        return [f"{indent}{values!r}"]
    width = max((len(name) for name in values), default=0)
    lines = []
    for name, value in values.items():
        decimals, unit = formats.get(name, (3, ""))
        unit = "" if unit == "-" else f" {unit}"
        lines.append(f"{indent}{name:<{width}}  {value:.{decimals}f}{unit}")
    return lines


def dtc_table(reports: Sequence[DtcReport], description: DiagDescription, mask: int) -> str:
    """The DTCs as text: code, name, status byte and bits; the freeze frame's fields below each, with units."""
    if not reports:
        return f"no DTC matches status mask 0x{mask:02X}"
    formats = _field_formats(description)
    width = max(len(r.name) for r in reports)
    lines = [f"{'DTC':<8}{'name':<{width}}  status  bits"]
    for r in reports:
        lines.append(f"{r.code:<8}{r.name:<{width}}  0x{r.status:02X}    {', '.join(r.bits) or '-'}")
        if r.freeze_frame is not None:
            lines.append("        freeze frame (snapshot record 1):")
            lines += _value_lines(r.freeze_frame, formats, " " * 10)
    return "\n".join(lines)


def did_table(dids: Sequence[int], values: Mapping[int, Any], refused: Mapping[int, str],
              description: DiagDescription) -> str:
    """DIDs as text, in the order read: number and name, then the value (text) or one line per field with its
    unit; a refused DID's negative response by its NRC name."""
    formats = _field_formats(description)
    lines = []
    for did in dids:
        head = f"0x{did:04X}  {description.dids[did].name}"
        if did in refused:
            lines.append(f"{head}  refused: {refused[did]}")
        elif isinstance(values[did], str):
            lines.append(f"{head}  {values[did]!r}")
        else:
            lines += [head, *_value_lines(values[did], formats, " " * 8)]
    return "\n".join(lines)


def _nrc(exc: Exception) -> str:
    """A negative response as its NRC name and code (``RequestOutOfRange (0x31)``)."""
    response = getattr(exc, "response", None)
    code = getattr(response, "code", None)
    if code is None:
        return str(exc)
    from udsoncan import Response  # noqa: PLC0415 - extra diag

    return f"{Response.Code.get_name(code)} (0x{code:02X})"


def _log_uds(verbose: bool) -> None:
    """The tester libraries' own log lines: all of them with ``verbose``, else none (an error is the one
    ``error:`` line of the command). Set on each call: several commands may run in one process."""
    if verbose:
        logging.basicConfig(level=logging.INFO, stream=sys.stderr, format="%(levelname)s %(name)s: %(message)s")
    for name in UDS_LOGGERS:
        logging.getLogger(name).setLevel(logging.NOTSET if verbose else logging.CRITICAL + 1)


def _require_diag_extra() -> None:
    try:
        import isotp  # noqa: F401, PLC0415 - extra diag
        import udsoncan  # noqa: F401, PLC0415
    except ImportError as exc:
        raise InputError(f"dsg-hil diag: needs the extra 'diag' (pip install 'dsg-hil[diag]'): {exc}") from None


def _do_diag(args: argparse.Namespace) -> int:
    from ..protocol.bus import bus_config, bus_name, open_bus  # noqa: PLC0415
    from ..protocol.diag import load_description  # noqa: PLC0415 - cantools at run time only

    _require_diag_extra()
    _log_uds(args.verbose)
    check_output_path("--json", args.json)
    if args.json is not None and args.action == "clear":
        raise InputError("--json: 'clear' reads nothing to write")
    if args.did and args.action != "read":
        raise InputError(f"DID {args.did[0]!r}: DIDs are for 'dsg-hil diag read', not '{args.action}'")
    description = load_description(args.description)
    where = args.description or "dsg_hil/data/diag.toml"  # the shipped one, by its place in the package
    dids = resolve_dids(args.did, description, where) if args.action == "read" else []
    request_id, response_id = _ids(args, description)
    config = bus_config(args)
    fd = bool(config.get("fd"))

    from ..protocol.diag_client import uds_client  # noqa: PLC0415

    bus = open_bus(config)
    try:
        ecu = f"ECU 0x{request_id:03X}/0x{response_id:03X} on {bus_name(config)}"
        progress(f"diag: {ecu}")
        with uds_client(bus, description, request_id, response_id, fd=fd, timeout=args.timeout) as client:
            if args.action == "dtc":
                result = _dtc(args, client, description, ecu)
            elif args.action == "read":
                result = _read(client, description, dids, ecu, args.timeout)
            else:
                _talk(ecu, "ClearDiagnosticInformation", lambda: client.clear_dtc(args.group), args.timeout)
                print(f"cleared DTC group 0x{args.group:06X}")
                return 0
    finally:
        bus.shutdown()
    data, refused = result
    if args.json is not None:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
        progress(f"wrote {args.json}")
    if refused:
        raise RunError(f"{ecu}: {refused}")
    return 0


def _talk(ecu: str, service: str, call: Callable[[], _T], timeout: float,
          refusals: list[str] | None = None) -> _T | None:
    """``call()`` (one request), its errors as one RunError naming the ECU and the service: no answer within the
    timeout, a negative response (by its NRC name; with ``refusals``: appended there instead, None returned), an
    answer that is not the one asked for."""
    from udsoncan.exceptions import (  # noqa: PLC0415 - extra diag
        InvalidResponseException,
        NegativeResponseException,
        TimeoutException,
        UnexpectedResponseException,
    )

    try:
        return call()
    except TimeoutException:
        raise RunError(f"{ecu}: no response to {service} within {timeout:g} s (--timeout): is the ECU on this "
                       "bus, at these IDs, powered?") from None
    except NegativeResponseException as exc:
        if refusals is None:
            raise RunError(f"{ecu}: {service} refused: negative response {_nrc(exc)}") from None
        refusals.append(_nrc(exc))
        return None
    except (InvalidResponseException, UnexpectedResponseException) as exc:
        hint = " (is the DID's size in the description the ECU's?)" if service.startswith("ReadData") else ""
        raise RunError(f"{ecu}: {service}: {str(exc).strip()}{hint}") from None


def _dtc(args: argparse.Namespace, client: Any, description: DiagDescription,
         ecu: str) -> tuple[dict[str, Any], str]:
    from ..protocol.diag_client import read_dtcs  # noqa: PLC0415

    reports = _talk(ecu, "ReadDTCInformation", lambda: read_dtcs(client, description, args.mask, args.snapshots),
                    args.timeout) or []
    print(dtc_table(reports, description, args.mask))
    return {"mask": f"0x{args.mask:02X}", "dtcs": [r.as_json() for r in reports]}, ""


def _read(client: Any, description: DiagDescription, dids: Sequence[int], ecu: str,
          timeout: float) -> tuple[dict[str, Any], str]:
    """Each DID in its own request: one refused is shown with its NRC, the others still read."""
    from ..protocol.diag_client import read_dids  # noqa: PLC0415

    values: dict[int, Any] = {}
    refused: dict[int, str] = {}
    for did in dids:
        refusals: list[str] = []
        read = _talk(ecu, f"ReadDataByIdentifier 0x{did:04X}",
                     lambda did=did: read_dids(client, description, [did]), timeout,  # type: ignore[misc]
                     refusals)
        if read is None:
            refused[did] = refusals[0]
        else:
            values[did] = read[description.dids[did].name]
    print(did_table(dids, values, refused, description))
    data = {"dids": {description.dids[d].name: v for d, v in values.items()},
            "refused": {description.dids[d].name: text for d, text in refused.items()}}
    summary = "; ".join(f"0x{d:04X} {description.dids[d].name} refused: {text}" for d, text in refused.items())
    return data, summary
