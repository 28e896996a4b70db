"""The source of a definition as a syntax tree, where the module runs compiled too: mypyc's extension modules give
:mod:`inspect` no source lines, and the installed package keeps each module's ``.py`` beside its extension."""

from __future__ import annotations

import ast
import sys
from pathlib import Path
from typing import Any

__all__ = ["definition"]


def definition(obj: Any) -> ast.FunctionDef | ast.ClassDef:
    """The ``def`` or ``class`` of a function, method or class, found by its qualified name in its module's
    source file."""
    owner = getattr(obj, "__objclass__", None)  # a compiled method: its class knows the module
    module = sys.modules[getattr(obj, "__module__", None) or owner.__module__]
    path = Path(module.__file__ or "")
    tree: ast.Module | ast.FunctionDef | ast.ClassDef = ast.parse(
        path.with_name(module.__name__.rpartition(".")[2] + ".py").read_text(encoding="utf-8"))
    for name in obj.__qualname__.split("."):
        tree = next(node for node in tree.body if isinstance(node, (ast.FunctionDef, ast.ClassDef))
                    and node.name == name)
    assert not isinstance(tree, ast.Module)
    return tree
