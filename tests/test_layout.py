"""The layout shows the data flow, one direction: each part imports only the parts upstream of it (the table
below), the top level holds only ``__init__``, ``__main__`` and subpackages, and the paths of 0.1 still import,
as the very modules that moved (with a DeprecationWarning)."""

from __future__ import annotations

import ast
import importlib
import sys
import warnings
from pathlib import Path

import pytest

import dsg_hil
import ecu_stub
from dsg_hil.common.moved import MOVED

PACKAGE = Path(dsg_hil.__file__).resolve().parent
ECU_STUB = Path(ecu_stub.__file__).resolve().parent

# part: the parts it may import (besides itself). Upstream first: the data flow is
# scenario -> physics/plant -> runner -> bus -> TCU -> results -> paper report.
ALLOWED: dict[str, set[str]] = {
    "common": set(),
    "protocol": {"common"},
    "physics": {"common"},
    "results": {"common", "physics"},
    "sim": {"common", "protocol", "physics", "results", "ecu_stub"},  # ecu_stub: the default in-process TCU
    "paper": {"common", "protocol", "physics", "results", "sim"},
    "testing": {"common", "protocol", "physics", "results", "sim", "ecu_stub", "fmi"},  # fmi: an .fmu controller
    "fmi": {"common", "protocol", "physics", "results", "sim", "ecu_stub"},  # FMI both ways, built on the run API
    "cli": {"common", "protocol", "physics", "results", "sim", "paper", "e2e", "ecu_stub", "sweep", "fmi"},
    "sweep": {"common", "protocol", "physics", "results", "sim", "ecu_stub", "testing"},  # testing: controllers
    "e2e": {"common", "protocol", "physics", "results", "sim", "ecu_stub"},
    "ecu_stub": {"common", "protocol"},  # the TCU knows the plant only through the DBC
    "__init__": {"common", "protocol", "physics", "results", "sim", "testing"},  # the lazy public API
    "__main__": {"cli"},
}
LOOP = ("common", "protocol", "physics", "results", "sim")  # nothing of the loop imports the paper's reproduction


def part_of(module: str) -> str:
    """``dsg_hil.sim.runner`` -> ``sim``; ``ecu_stub.runner`` -> ``ecu_stub``; ``dsg_hil`` -> ``__init__``."""
    parts = module.split(".")
    if parts[0] == "ecu_stub":
        return "ecu_stub"
    return parts[1] if len(parts) > 1 else "__init__"


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(path: Path, root: Path) -> set[str]:
    """Every dsg_hil / ecu_stub module ``path`` imports, anywhere in it (functions, TYPE_CHECKING blocks too)."""
    name = module_name(path, root)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                target = ".".join([*base, node.module] if node.module else base)
            else:
                target = node.module or ""
            found.add(target)
            found.update(f"{target}.{alias.name}" for alias in node.names)  # 'from . import x': x may be a module
    return {m for m in found if m.split(".")[0] in ("dsg_hil", "ecu_stub") and _is_module(m)}


def _is_module(name: str) -> bool:
    root = PACKAGE.parent if name.startswith("dsg_hil") else ECU_STUB.parent
    path = root.joinpath(*name.split("."))
    return path.with_suffix(".py").exists() or (path / "__init__.py").exists()


def sources() -> list[tuple[Path, Path]]:
    return [(p, root) for root in (PACKAGE, ECU_STUB) for p in sorted(root.rglob("*.py"))]


@pytest.mark.slow
def test_every_part_imports_only_what_the_table_allows():
    bad = []
    for path, root in sources():
        source = module_name(path, root)
        mine = part_of(source)
        assert mine in ALLOWED, f"{path}: part {mine!r} is not in the table"
        for target in imports(path, root):
            theirs = part_of(target)
            if theirs != mine and theirs not in ALLOWED[mine] and target != "dsg_hil":
                bad.append(f"{source} imports {target} ({mine} -> {theirs})")
    assert not bad, "\n".join(bad)


def test_nothing_in_the_loop_imports_the_paper():
    assert not any("paper" in ALLOWED[part] for part in LOOP)


def test_the_table_can_fail():
    """The checker sees a forbidden import (so the test above could fail)."""
    runner = PACKAGE / "sim" / "runner.py"
    assert "dsg_hil.results.summary" in imports(runner, PACKAGE)
    assert "results" not in ALLOWED["protocol"]


def test_the_top_level_holds_only_init_main_and_subpackages():
    modules = sorted(p.name for p in PACKAGE.glob("*.py"))
    assert modules == ["__init__.py", "__main__.py"]
    for directory in PACKAGE.iterdir():
        if directory.is_dir() and directory.name not in ("data", "__pycache__"):
            assert (directory / "__init__.py").exists(), directory


@pytest.mark.parametrize("old", sorted(MOVED))
def test_an_old_import_path_is_the_moved_module(old):
    sys.modules.pop(old, None)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        module = importlib.import_module(old)
    assert module is importlib.import_module(MOVED[old])
    assert any(issubclass(w.category, DeprecationWarning) and MOVED[old] in str(w.message) for w in caught)


def test_the_public_api_is_lazy_and_complete():
    for name in dsg_hil.__all__:
        assert getattr(dsg_hil, name) is not None, name


# ---- no import cycle ---------------------------------------------------------------------------------------------
# The graph: a module -> every dsg_hil / ecu_stub module it imports, anywhere in it (imports() above: functions and
# TYPE_CHECKING blocks too), plus, for a package whose __init__ re-exports names lazily (common.lazy.lazy_names),
# an edge to each submodule its table names: ``from dsg_hil.protocol import Codec`` runs protocol/codec.py, so a
# module that imports its package's lazy names sits downstream of them. Not an edge: the parent package that
# Python imports before a submodule (every module would otherwise be in a cycle with its package's __init__), and
# the 0.1 paths of common/moved.py (nothing in the package imports them).


def lazy_submodules(path: Path, root: Path) -> set[str]:
    """The submodules named by the lazy_names table of the package ``path`` (an ``__init__.py``), if it has one."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    tables = [node.args[1].id for node in ast.walk(tree) if isinstance(node, ast.Call)
              and getattr(node.func, "id", None) == "lazy_names" and isinstance(node.args[1], ast.Name)]
    package = module_name(path, root)
    return {f"{package}.{where}" for table in tables
            for where in getattr(importlib.import_module(package), table).values()}


def import_graph() -> dict[str, set[str]]:
    graph = {}
    for path, root in sources():
        name = module_name(path, root)
        lazy = lazy_submodules(path, root) if path.name == "__init__.py" else set()
        graph[name] = (imports(path, root) | lazy) - {name}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """A cycle of ``graph`` as its path (first node repeated at the end), or None: depth first, iteratively."""
    done: set[str] = set()
    for start in sorted(graph):
        if start in done:
            continue
        path, todo = [start], [iter(sorted(graph[start]))]
        while path:
            nxt = next(todo[-1], None)
            if nxt is None:  # every import of path[-1] explored: no cycle through it
                done.add(path.pop())
                todo.pop()
            elif nxt in path:
                return path[path.index(nxt):] + [nxt]
            elif nxt not in done:
                path.append(nxt)
                todo.append(iter(sorted(graph.get(nxt, ()))))
    return None


def test_the_cycle_finder_finds_a_cycle_and_only_a_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"d": {"b", "e"}, "b": {"c"}, "c": {"b"}, "e": set()}) == ["b", "c", "b"]
    assert find_cycle({"a": {"a"}}) == ["a", "a"]
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set(), "d": {"a", "x"}}) is None  # a diamond is no cycle


def test_the_graph_holds_every_kind_of_import():
    graph = import_graph()
    assert "dsg_hil.protocol.codec" in graph["dsg_hil.protocol"]  # a lazy re-export of the package
    assert "dsg_hil.results.creep_rows" in graph["dsg_hil.results.summary"]
    assert "ecu_stub.controller" in graph["ecu_stub.runner"]
    assert len(graph) == len(sources())


def test_no_import_cycle():
    cycle = find_cycle(import_graph())
    assert cycle is None, " -> ".join(cycle or ())


def test_every_module_declares_its_public_api():
    """``__all__`` in every module but the packages' and the test suites': each name in it defined there."""
    missing, unknown = [], []
    for path, root in sources():
        if path.name in ("__init__.py", "__main__.py", "conftest.py") or path.name.startswith("test_"):
            continue
        name = module_name(path, root)
        module = importlib.import_module(name)
        if not hasattr(module, "__all__"):
            missing.append(name)
        else:
            unknown += [f"{name}.{n}" for n in module.__all__ if not hasattr(module, n)]
    assert not missing, f"no __all__: {missing}"
    assert not unknown, f"in __all__ but not defined: {unknown}"
