"""Fault injection, declarative: what goes wrong on which DBC message or signal, and when (see :mod:`.spec`).

Entry points: :func:`parse_fault` / :func:`fault_from_mapping` for the specifications, :class:`FaultyBus` to put
an injector between a node and its bus.
"""

from .injector import FaultInjector, FaultyBus, bridge_step, outside_range
from .spec import KINDS, FaultError, FaultSpec, check_against_dbc, fault_from_mapping, parse_fault

__all__ = ["KINDS", "FaultError", "FaultInjector", "FaultSpec", "FaultyBus", "bridge_step", "check_against_dbc",
           "fault_from_mapping", "outside_range", "parse_fault"]
