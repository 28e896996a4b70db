"""Fault injection: lives in :mod:`dsg_hil.protocol.faults` (ecu-stub uses it too); re-exported here."""

from ..protocol.faults import *  # noqa: F401,F403
from ..protocol.faults import __all__  # noqa: F401
