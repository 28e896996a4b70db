"""Which code made a sweep's runs: a digest of the plant's and the bundled TCU's sources and data.

A sweep is judged as one body of evidence, so its runs must come from one plant and one controller. Two ways they
did not, silently, before: a ``--resume`` after the code changed (an interrupted 5,000-run sweep finished by a fixed
TCU), and a cluster whose workers run another install than the client. Each run's row now carries the digest of
the code its worker ran (``code``) and ``OUT/sweep.json`` the client's; :func:`code_counts` and the page say when
they differ. The digest covers every ``.py``, ``.toml`` and ``.dbc`` file of the ``dsg_hil`` and ``ecu_stub``
packages (by relative path and content): a comment changes it too, so equal digests prove the same code, and
different ones say only that it may behave differently. A controller by import path or command line is not
covered (its own version is the user's to record)."""

from __future__ import annotations

import functools
import hashlib
import importlib.util
from collections import Counter
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

__all__ = ["CODE_PACKAGES", "code_counts", "code_digest", "code_note", "digest_of"]

CODE_PACKAGES = ("dsg_hil", "ecu_stub")
_SUFFIXES = frozenset({".py", ".toml", ".dbc"})


@functools.cache
def code_digest() -> str:
    """12 hex digits of SHA-1 over the files of :data:`CODE_PACKAGES` (module docstring), once per process."""
    roots = []
    for name in CODE_PACKAGES:
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.origin is not None:
            roots.append(Path(spec.origin).parent)
    return digest_of(roots)


def digest_of(roots: Iterable[Path]) -> str:
    """12 hex digits of SHA-1 over the ``.py``, ``.toml`` and ``.dbc`` files under each package directory in
    ``roots`` (``__pycache__`` left out), each by its path from the package's parent and its bytes, in sorted order."""
    h = hashlib.sha1()
    for root in roots:
        files = sorted(p for p in root.rglob("*") if p.suffix in _SUFFIXES and "__pycache__" not in p.parts)
        for path in files:
            h.update(path.relative_to(root.parent).as_posix().encode())
            h.update(b"\0")
            h.update(path.read_bytes())
            h.update(b"\0")
    return h.hexdigest()[:12]


def code_counts(rows: Iterable[Mapping[str, Any]]) -> Counter[str]:
    """Runs by the code digest their worker ran (rows of an older sweep without one count as "unknown")."""
    return Counter(str(row.get("code") or "unknown") for row in rows)


def code_note(rows: Iterable[Mapping[str, Any]], here: str) -> str | None:
    """One line if the runs were not all made by the code ``here`` (the client's digest), else None."""
    counts = code_counts(rows)
    if not counts or set(counts) == {here}:
        return None
    parts = ", ".join(f"{n} by {digest}" for digest, n in counts.most_common())
    return (f"the runs come from other code than this install ({here}): {parts} (column 'code'; a --resume after "
            f"the code changed, or workers with another install): judge them apart")
