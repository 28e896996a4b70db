"""Build of dsg-hil. The metadata is in ``pyproject.toml``; this file only adds the modules a control period runs
through, compiled by mypyc (mypy's compiler of type-annotated Python to C extension modules: the same source, the
closed loop 2.4 times as fast, the same frames bit for bit, ``tests/test_packaging.py``), to a regular install
(``pip install .``, a wheel). An editable install (``pip install -e .``) stays pure Python, so that an edit takes
effect at once; so does any install with ``DSG_HIL_PURE_PYTHON=1``. Where the extensions cannot be built (no C
compiler, no Python headers, mypy refusing the source) the install is the pure-Python package, all of it (the
compiled modules share one library: some compiled and some not would not import), and its build output says so;
the compiled modules are the ones ``dsg_hil/common/build.py`` names (:data:`COMPILED`).
"""

from __future__ import annotations

import ast
import os
import sys

from setuptools import setup
from setuptools.command.build_ext import build_ext

HERE = os.path.dirname(os.path.abspath(__file__))


def _build_constant(name: str):
    """``name`` (``COMPILED``, ``GROUP``) of ``dsg_hil/common/build.py``, read as it stands (not imported: the
    build's environment need not have the package's dependencies), so the installed package knows them too."""
    with open(os.path.join(HERE, "dsg_hil", "common", "build.py"), encoding="utf-8") as f:
        tree = ast.parse(f.read())
    (value,) = [node.value for node in tree.body if isinstance(node, ast.Assign)
                and any(isinstance(t, ast.Name) and t.id == name for t in node.targets)]
    return ast.literal_eval(value)


COMPILED, GROUP = list(_build_constant("COMPILED")), _build_constant("GROUP")
PURE_ENV = "DSG_HIL_PURE_PYTHON"
BUILDS = {"bdist_wheel", "build", "build_ext", "install"}  # setup.py commands that build modules (not
# egg_info, dist_info, sdist, nor editable_wheel: pip's editable install)


def ext_modules() -> list:
    """The compiled modules, or none: an editable install, ``DSG_HIL_PURE_PYTHON`` set, no mypyc, or mypyc failing."""
    commands = set(sys.argv[1:])
    if os.environ.get(PURE_ENV, "") not in ("", "0") or "editable_wheel" in commands or not commands & BUILDS:
        return []
    try:
        from mypyc.build import mypycify  # noqa: PLC0415 - only when building
        # third-party packages typed as Any whether the build's environment has them or not (--no-site-packages):
        # the same build on a fresh machine (before its dependencies are installed) as on a set-up one
        exts = mypycify(["--no-site-packages", "--ignore-missing-imports", "--config-file=", *COMPILED],
                        group_name=GROUP, opt_level="3")
    except (SystemExit, Exception) as exc:  # noqa: BLE001 - any failure: the pure-Python package
        _say_pure(exc)
        return []
    return exts


def _say_pure(exc: BaseException) -> None:
    print(f"dsg-hil: building pure Python, not compiled ({type(exc).__name__}: {exc})", file=sys.stderr)


class AllOrNone(build_ext):
    """``build_ext`` that, where any extension fails to build, removes those it built and leaves the package pure
    Python: a module's extension imports the shared library of all of them, and the compiled modules call each
    other's compiled code (setuptools' ``optional`` extensions fail one by one)."""

    def run(self) -> None:
        try:
            super().run()
        except Exception as exc:  # noqa: BLE001 - CompileError, LinkError, DistutilsError, ...: no extension at all
            for ext in self.extensions:
                for path in (self.get_ext_fullpath(ext.name), os.path.join(self.build_lib, self.get_ext_filename(
                        ext.name))):
                    if os.path.exists(path):
                        os.remove(path)
            self.extensions = []
            _say_pure(exc)


setup(ext_modules=ext_modules(), cmdclass={"build_ext": AllOrNone})
