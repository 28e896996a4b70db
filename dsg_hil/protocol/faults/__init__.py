"""Fault injection, declarative: what goes wrong on which DBC message or signal, and when (see :mod:`.spec`).

Entry points: :func:`parse_fault` / :func:`fault_from_mapping` for the specifications, :class:`FaultyBus` to put
an injector between a node and its bus, :func:`with_faults` to do it for a node of this package. The names are
imported when first used (PEP 562): the command-line options need none of python-can and cantools.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...common.lazy import lazy_names

if TYPE_CHECKING:
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

_WHERE = {**dict.fromkeys(("FaultInjector", "FaultyBus", "bridge_step", "outside_range"), "injector"),
          **dict.fromkeys(("add_fault_arguments", "fault_counts", "faults_from_args", "with_faults"), "options"),
          **dict.fromkeys(("KINDS", "FaultError", "FaultSpec", "check_against_dbc", "check_faults",
                           "fault_from_mapping", "fault_side", "parse_fault"), "spec")}

__all__ = ["KINDS", "FaultError", "FaultInjector", "FaultSpec", "FaultyBus", "add_fault_arguments", "bridge_step",
           "check_against_dbc", "check_faults", "fault_counts", "fault_from_mapping", "fault_side",
           "faults_from_args", "outside_range", "parse_fault", "with_faults"]


__getattr__ = lazy_names(__name__, _WHERE, globals())
