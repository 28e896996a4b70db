"""Compiled physics: the plant's pure functions run as numba machine code, numba imported on first use.

:func:`compiled` marks a function of plain floats, float arrays and parameter records (:func:`record`) as
compiled. The function is the one implementation: it is compiled (``numba.njit(cache=True)``) the first time
anything calls it, from Python or from another compiled function, so ``import dsg_hil`` and commands that never
step the plant do not pay numba's import (~0.5 s). Called from Python, a parameter group (a frozen dataclass of
:mod:`dsg_hil.physics.params`) is passed as its record, so the unit tests call the compiled code with the
parameter objects they already have.

Compiled code is cached next to the module (``__pycache__``); where that directory is read-only numba falls
back to its user cache directory, and ``NUMBA_CACHE_DIR`` overrides both.
"""

from __future__ import annotations

import functools
from collections import namedtuple
from dataclasses import fields, is_dataclass
from typing import Any, Callable

from . import params as _params

_RECORDS: dict[type, type] = {}


def record(group: Any) -> tuple:
    """A parameter group's values as a named tuple of floats with the same field names (compiled code reads
    ``e.Kp_gov`` from it as Python reads it from the dataclass)."""
    cls = type(group)
    rec = _RECORDS.get(cls)
    if rec is None:
        name = f"{cls.__name__}Record"
        rec = namedtuple(name, [f.name for f in fields(group)], module=_params.__name__)  # type: ignore[misc]
        setattr(_params, name, rec)  # importable by name: numba's cache pickles the type by reference
        _RECORDS[cls] = rec
    return rec(*(float(getattr(group, f.name)) for f in fields(group)))


class Compiled:
    """A physics function, compiled on first call (see the module docstring)."""

    def __init__(self, py_func: Callable[..., Any]) -> None:
        functools.update_wrapper(self, py_func)
        self.py_func = py_func
        self._dispatcher: Any = None

    @property
    def dispatcher(self) -> Any:
        """numba's dispatcher of the function (numba imported here, the first time)."""
        if self._dispatcher is None:
            import numba

            self._dispatcher = numba.njit(cache=True)(self.py_func)
        return self._dispatcher

    @property
    def _numba_type_(self) -> Any:
        """How numba types this object when compiled code calls it: as its dispatcher."""
        from numba.core import types

        return types.Dispatcher(self.dispatcher)

    def specialize(self, *args: Any) -> Callable[..., Any]:
        """The compiled function for arguments of exactly these types, called without numba's per-call typing
        of the arguments (tens of microseconds for parameter records): for a hot loop whose argument types never
        change."""
        from numba import typeof

        return self.dispatcher.compile(tuple(typeof(a) for a in args))

    def __call__(self, *args: Any) -> Any:
        return self.dispatcher(*(record(a) if is_dataclass(a) else a for a in args))


def compiled(py_func: Callable[..., Any]) -> Compiled:
    """Decorator: the function runs compiled (see the module docstring)."""
    return Compiled(py_func)
