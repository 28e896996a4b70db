"""ecu-stub's diagnostics: UDS (ISO 14229-1) on ISO-TP (ISO 15765-2), DTCs with the standard status bits, debounce
and freeze frames; the DIDs and DTCs are the description's (:mod:`dsg_hil.protocol.diag`, ``dsg_hil/data/diag.toml``).
Pure Python, off the compiled control path but for one call per control period (:meth:`DiagServer.period`)."""

from .dtc import DtcMemory
from .isotp import IsoTpServer
from .server import DiagServer
from .uds import UdsServer

__all__ = ["DiagServer", "DtcMemory", "IsoTpServer", "UdsServer"]
