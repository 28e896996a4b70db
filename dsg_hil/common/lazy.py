"""Names of a package imported from its modules when first used (PEP 562), so that importing the package, e.g.
for a command's ``--help``, does not load cantools and python-can."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_names"]


def lazy_names(package: str, where: Mapping[str, str], namespace: dict[str, Any]) -> Callable[[str], Any]:
    """A module ``__getattr__`` for ``package``: ``name`` from its module ``where[name]`` (relative), kept in
    ``namespace`` (the package's globals) once imported."""
    def __getattr__(name: str) -> Any:  # noqa: N807 - the module hook of PEP 562
        if name not in where:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f".{where[name]}", package), name)
        namespace[name] = value
        return value
    return __getattr__
