"""ecu-stub as an XCP slave on CAN (ASAM MCD-1 XCP): the master measures the controller's internals by DAQ once per
control period and changes calibration values at run time; the A2L file that describes it is generated from the
code (:mod:`.a2l`). Pure Python, off the compiled control path but for one call per control period
(:meth:`XcpSlave.period`)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from .memory import TcuMemory, tcu_memory
from .slave import DEFAULT_IDS, XcpSlave

__all__ = ["DEFAULT_IDS", "TcuMemory", "XcpSlave", "tcu_memory", "xcp_slave"]


def xcp_slave(request_id: int = DEFAULT_IDS[0], response_id: int = DEFAULT_IDS[1],
              identity: str = "ecu_stub") -> Callable[[Any, Callable[[int, bytes], None]], XcpSlave]:
    """What :class:`ecu_stub.runner.TcuRunner` takes as ``xcp``: builds the slave on its runner's controller."""
    def make(runner: Any, send: Callable[[int, bytes], None]) -> XcpSlave:
        return XcpSlave(tcu_memory(runner), request_id, response_id, send, identity)
    return make
