"""A DBC signal's value ranges: what its bits can carry and what the DBC allows. Shared by the codec's cantools
path (:mod:`.codec`) and the generated functions (:mod:`.generated`), so neither imports the other for them."""

from __future__ import annotations

from cantools.database.can import Signal

__all__ = ["raw_range", "signal_range"]


def raw_range(signal: Signal) -> tuple[float, float]:
    """The physical values the signal's bits can carry (scale and offset applied), low to high."""
    lo, hi = (-(1 << (signal.length - 1)), (1 << (signal.length - 1)) - 1) if signal.is_signed \
        else (0, (1 << signal.length) - 1)
    a, b = lo * signal.scale + signal.offset, hi * signal.scale + signal.offset
    return min(a, b), max(a, b)


def signal_range(signal: Signal) -> tuple[float, float]:
    """The signal's DBC range [minimum, maximum]; a bound the DBC leaves open (the common "no range" [0|0],
    which cantools reads as None) is the one its bits can carry."""
    lo, hi = raw_range(signal)
    return (lo if signal.minimum is None else signal.minimum, hi if signal.maximum is None else signal.maximum)
