"""Fault injection, declarative: what goes wrong on which DBC message or signal, and when (see :mod:`.spec`).

Entry points: :func:`parse_fault` / :func:`fault_from_mapping` for the specifications, :class:`FaultyBus` to put
an injector between a node and its bus, :func:`with_faults` to do it for a node of this package.
"""

from .injector import FaultInjector, FaultyBus, bridge_step, outside_range
from .options import add_fault_arguments, fault_counts, faults_from_args, with_faults
from .spec import (
                   KINDS,
                   FaultError,
                   FaultSpec,
                   check_against_dbc,
                   check_faults,
                   fault_from_mapping,
                   fault_side,
                   parse_fault,
)

__all__ = ["KINDS", "FaultError", "FaultInjector", "FaultSpec", "FaultyBus", "add_fault_arguments", "bridge_step",
           "check_against_dbc", "check_faults", "fault_counts", "fault_from_mapping", "fault_side",
           "faults_from_args", "outside_range", "parse_fault", "with_faults"]
