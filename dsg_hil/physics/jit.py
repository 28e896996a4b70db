"""Compiled physics: the plant's pure functions run as numba machine code, numba imported on first use.

:func:`compiled` marks a function of plain floats, float arrays and parameter records (:func:`record`) as
compiled. The function is the one implementation: it is compiled (``numba.njit(cache=True)``) the first time
anything calls it, from Python or from another compiled function (a :class:`dsg_hil.physics.plant.Plant` when it is
built), so ``import dsg_hil`` and commands that build no plant do not pay numba's import (~0.5 s). Called from
Python, a parameter group (a frozen dataclass of :mod:`dsg_hil.physics.params`) is passed as its record, so the
unit tests call the compiled code with the parameter objects they already have.

Compiled code is cached in the user's cache directory (``$XDG_CACHE_HOME/dsg-hil/numba``, by default
``~/.cache/dsg-hil/numba``), one sub-directory per source tree, never inside the installed package: numba's files
there are not in pip's record of the install, so ``pip uninstall`` would leave them behind as a ``dsg_hil``
namespace directory that hides a later editable install. ``NUMBA_CACHE_DIR`` overrides it; where it cannot be
written numba falls back to ``__pycache__`` or its own user cache.
"""

from __future__ import annotations

import functools
import os
import weakref
from collections import namedtuple
from collections.abc import Callable
from dataclasses import fields, is_dataclass
from typing import Any

import numpy as np

from ..common.files import user_cache_dir
from . import params as _params

__all__ = ["Compiled", "cache_dir", "compiled", "constants", "record"]


def cache_dir() -> str:
    """Where numba caches the compiled plant: ``NUMBA_CACHE_DIR`` if set, else ``dsg-hil/numba`` in the user's
    cache directory (``$XDG_CACHE_HOME``, by default ``~/.cache``)."""
    given = os.environ.get("NUMBA_CACHE_DIR")
    if given:
        return given
    return str(user_cache_dir("numba"))

_RECORDS: dict[type, type] = {}
_OF_GROUP: dict[int, tuple] = {}  # id(group) -> record, while the group lives


def _record_class(cls: type) -> type:
    name = f"{cls.__name__}Record"
    rec = namedtuple(name, [f.name for f in fields(cls)], module=_params.__name__)  # type: ignore[misc]
    setattr(_params, name, rec)  # importable by name: numba's cache pickles the type by reference
    return rec


# Every flat parameter group has its record class from the start: numba's cache index lists every signature a
# function was ever compiled for, and unpickling it needs all their record types, used in this process or not.
for _cls in list(vars(_params).values()):
    if isinstance(_cls, type) and is_dataclass(_cls) and all(f.type in ("float", float) for f in fields(_cls)):
        _RECORDS[_cls] = _record_class(_cls)


def record(group: Any) -> tuple:
    """A parameter group's values as a named tuple of floats with the same field names (compiled code reads
    ``e.Kp_gov`` from it as Python reads it from the dataclass). Made once per group object."""
    known = _OF_GROUP.get(id(group))
    if known is not None:
        return known
    rec = _RECORDS[type(group)]
    values = rec(*(float(getattr(group, f.name)) for f in fields(group)))
    _OF_GROUP[id(group)] = values
    weakref.finalize(group, _OF_GROUP.pop, id(group), None)
    return values


def constants(arrays: dict[str, np.ndarray | float], *groups: Any) -> np.ndarray:
    """Named float arrays and every field of the parameter groups as one numpy record: a structured array of one
    element. Compiled code reads ``k = K[0]`` once and then ``k.Phi`` (a sub-array) or ``k.r_w`` and passes ``k``
    wherever a group's record is expected (its fields are found by name), so a hot loop's step-invariant data
    costs one argument to pass instead of an array or record each. Names must be unique across everything."""
    names: list[str] = [*arrays, *(f.name for g in groups for f in fields(g))]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ValueError(f"constants: repeated names {', '.join(repeated)}")
    dtype = np.dtype([(name, np.float64, np.shape(a)) for name, a in arrays.items()]
                     + [(f.name, np.float64) for g in groups for f in fields(g)])
    K = np.zeros(1, dtype=dtype)
    for name, a in arrays.items():
        K[0][name] = a
    for g in groups:
        for f in fields(g):
            K[0][f.name] = float(getattr(g, f.name))
    return K


class Compiled:
    """A physics function, compiled on first call (see the module docstring)."""

    def __init__(self, py_func: Callable[..., Any]) -> None:
        functools.update_wrapper(self, py_func)
        self.py_func = py_func
        self._dispatcher: Any = None
        self._by_types: dict[tuple[type, ...], tuple[Callable[..., Any], frozenset[int]]] = {}  # see __call__

    @property
    def dispatcher(self) -> Any:
        """numba's dispatcher of the function (numba imported here, the first time)."""
        if self._dispatcher is None:
            import numba

            config: Any = numba.config  # its settings are set from the environment at import: untyped
            if not config.CACHE_DIR:  # read when the cache is set up, i.e. by njit(cache=True) just below
                config.CACHE_DIR = cache_dir()
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
        key = tuple(map(type, args))  # floats, ints and records: their Python type fixes the numba type
        entry = self._by_types.get(key)
        if entry is None:
            entry = self._by_types[key] = self._prepare(args)
        fn, groups = entry
        if groups:
            args = tuple(record(a) if i in groups else a for i, a in enumerate(args))
        return fn(*args)

    def _prepare(self, args: tuple) -> tuple[Callable[..., Any], frozenset[int]]:
        """How to call with arguments of these Python types: which are parameter groups (passed as records), and
        the compiled function for them (numba's own dispatch where there are arrays: it types arrays fast)."""
        groups = frozenset(i for i, a in enumerate(args) if is_dataclass(a))
        args = tuple(record(a) if i in groups else a for i, a in enumerate(args))
        if any(isinstance(a, np.ndarray) for a in args):
            return self.dispatcher, groups
        return self.specialize(*args), groups


def compiled(py_func: Callable[..., Any]) -> Compiled:
    """Decorator: the function runs compiled (see the module docstring)."""
    return Compiled(py_func)
