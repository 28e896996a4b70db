"""The entries of dsg-hil's parameter file and ecu-stub's calibration: every number is an inline table
``{ value = ..., unit = "...", source = "...", <reason> = "..." }`` that says its unit and where it comes from.

:func:`quantity` checks one entry's form (the unit, a known source and its non-empty reason); :func:`finite`
checks a number and its range. Both raise the caller's :class:`~dsg_hil.common.errors.InputError` subclass,
naming the key.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from .errors import InputError

__all__ = ["finite", "quantity"]


def quantity(key: str, raw: Any, unit: str, sources: Mapping[str, str],
             error: type[InputError]) -> tuple[Any, str, str]:
    """``(value, source, reason)`` of the entry ``raw`` of ``key``: its unit must be ``unit``, its source one of
    ``sources`` (source: the field that gives the reason, e.g. ``{"paper": "ref", "assumed": "why"}``)."""
    reasons = sorted(set(sources.values()))
    if not isinstance(raw, dict) or "value" not in raw:
        raise error(f"{key}: expected {{ value = ..., unit = ..., source = ..., {' | '.join(reasons)} = ... }}, "
                    f"got {raw!r}")
    extra = set(raw) - {"value", "unit", "source", *reasons}
    if extra:
        raise error(f"{key}.{sorted(extra)[0]}: unknown field")
    if raw.get("unit") != unit:
        raise error(f"{key}: unit must be {unit!r}, got {raw.get('unit')!r}")
    source = raw.get("source")
    if not isinstance(source, str) or source not in sources:
        raise error(f"{key}: source must be one of {', '.join(sources)}, got {source!r}")
    reason = raw.get(sources[source])
    if not isinstance(reason, str) or not reason.strip():
        raise error(f"{key}: source {source!r} needs a non-empty {sources[source]!r} (where the value comes from)")
    return raw["value"], source, reason


def finite(key: str, value: Any, error: type[InputError], lo: float | None = None, hi: float | None = None,
           lo_open: bool = False) -> float:
    """``value`` as a float: a finite number (not a bool) within [lo, hi] (lo excluded if ``lo_open``)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise error(f"{key}: value must be a finite number, got {value!r}")
    if lo is not None and (value < lo or (lo_open and value == lo)):
        raise error(f"{key}: {value} is out of range (must be {'>' if lo_open else '>='} {lo})")
    if hi is not None and value > hi:
        raise error(f"{key}: {value} is out of range (must be <= {hi})")
    return float(value)
