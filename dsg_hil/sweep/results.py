"""A sweep's results, written as runs finish so that nothing is lost and ``--resume`` repeats nothing::

    OUT/runs/<run_id>.json       each run at once (atomic rename): its table row, summary, error
    OUT/runs/<run_id>.log.gz     its log, for a violating or failed run (every run with --keep-logs)
    OUT/table/part-NNNNN.parquet the rows, one part file per batch (pyarrow); read the directory as one table
    OUT/sweep.json               what the sweep is (its space's digest, sampler, n; a search): what --resume checks

A run counts as done once its JSON is there; rows whose JSON is written but not yet in a part (a sweep killed
between the two) are put into a part when the store is opened again.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from ..common.errors import InputError

__all__ = ["MANIFEST", "ResultStore", "read_manifest", "read_table", "write_manifest"]

MANIFEST = "sweep.json"


def _write_atomic(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def read_manifest(out: str | Path) -> dict[str, Any] | None:
    """What ``OUT/sweep.json`` says the sweep in ``out`` is (None if there is none: no sweep, or an older one)."""
    path = Path(out) / MANIFEST
    if not path.exists():
        return None
    try:
        return dict(json.loads(path.read_text(encoding="utf-8")))
    except (OSError, ValueError) as exc:
        raise InputError(f"--out {out}: {MANIFEST} is unreadable ({exc})") from exc


def write_manifest(out: str | Path, manifest: Mapping[str, Any]) -> None:
    path = Path(out) / MANIFEST
    path.parent.mkdir(parents=True, exist_ok=True)
    _write_atomic(path, json.dumps(dict(manifest), indent=1).encode())


class ResultStore:
    """The results directory of one sweep. ``resume``: keep what is there (else it must hold no results)."""

    def __init__(self, out: str | Path, resume: bool = False, batch_s: float = 5.0) -> None:
        self.out = Path(out)
        self.runs, self.table = self.out / "runs", self.out / "table"
        if not resume and any(self.runs.glob("*.json")):
            raise InputError(f"--out {self.out}: holds a sweep's results already (give --resume, or another --out)")
        self.runs.mkdir(parents=True, exist_ok=True)
        self.table.mkdir(parents=True, exist_ok=True)
        self.batch_s = batch_s
        self._pending: list[dict[str, Any]] = []
        self._last_flush = time.monotonic()
        in_table = set(self._table_ids())
        self.done: dict[str, dict[str, Any]] = {}
        for path in sorted(self.runs.glob("*.json")):
            record = json.loads(path.read_text(encoding="utf-8"))
            self.done[record["run_id"]] = record["row"]
            if record["run_id"] not in in_table:
                self._pending.append(record["row"])
        self.flush()

    def _table_ids(self) -> list[str]:
        parts = sorted(self.table.glob("part-*.parquet"))
        if not parts:
            return []
        import pyarrow.parquet as pq  # noqa: PLC0415

        return [i for part in parts for i in pq.read_table(part, columns=["run_id"]).column("run_id").to_pylist()]

    def add(self, result: Mapping[str, Any]) -> None:
        """A finished run: its JSON (and log) at once, its row into the next part."""
        run_id = result["run_id"]
        if result.get("log") is not None:
            _write_atomic(self.runs / f"{run_id}.log.gz", result["log"])
        record = {"run_id": run_id, "row": result["row"], "summary": result.get("summary"),
                  "traceback": result.get("traceback"), "task": result.get("task")}
        _write_atomic(self.runs / f"{run_id}.json", json.dumps(record, indent=1, default=str).encode())
        self.done[run_id] = dict(result["row"])
        self._pending.append(dict(result["row"]))
        if time.monotonic() - self._last_flush >= self.batch_s:
            self.flush()

    def flush(self) -> None:
        """Write the rows not yet in a part as a new part file."""
        if not self._pending:
            return
        import pyarrow as pa  # noqa: PLC0415
        import pyarrow.parquet as pq  # noqa: PLC0415

        number = len(list(self.table.glob("part-*.parquet")))
        path = self.table / f"part-{number:05d}.parquet"
        tmp = path.with_name(f".{path.name}.tmp")
        parts = sorted(self.table.glob("part-*.parquet"))
        first = pq.read_schema(parts[0]) if parts else None  # pyarrow.parquet.read_table(OUT/table) reads its
        rows = _uniform(self._pending, () if first is None else first.names)  # columns: every part has them
        # a column with no value in this batch gets a type all the same (the first part's, else text for
        # TEXT_COLUMNS, else a number), so that the parts read as one dataset (pyarrow cannot cast into null)
        inferred = pa.Table.from_pylist(rows).schema
        schema = pa.schema([_typed(c, first, pa) if pa.types.is_null(inferred.field(c).type) else inferred.field(c)
                            for c in rows[0]])
        pq.write_table(pa.Table.from_pylist(rows, schema=schema), tmp)
        os.replace(tmp, path)
        self._pending, self._last_flush = [], time.monotonic()

    def rows(self) -> list[dict[str, Any]]:
        """Every run's row, in run order."""
        return sorted(self.done.values(), key=lambda r: (r.get("index", 0), r["run_id"]))

    def record(self, run_id: str) -> dict[str, Any]:
        return dict(json.loads((self.runs / f"{run_id}.json").read_text(encoding="utf-8")))


_TEXT_COLUMNS = frozenset({"error"})  # the row's columns that hold text where they have a value (else numbers)


def _typed(column: str, first: Any, pa: Any) -> Any:
    """The field of a column without a value in a batch: the first part's, else text or a number."""
    if first is not None and column in first.names:
        return first.field(column)
    return pa.field(column, pa.string() if column in _TEXT_COLUMNS else pa.float64())


def _uniform(rows: Iterable[Mapping[str, Any]], first: Iterable[str] = ()) -> list[dict[str, Any]]:
    """Rows with the same columns (``first``'s, then the rows'; None where a row lacks one), each column of one
    type (numbers as float)."""
    rows = list(rows)
    columns = list(dict.fromkeys([*first, *(k for r in rows for k in r)]))
    numeric = {c for c in columns if all(isinstance(r.get(c), (int, float)) and not isinstance(r.get(c), bool)
                                         for r in rows if r.get(c) is not None)}
    return [{c: (float(r[c]) if c in numeric and r.get(c) is not None else r.get(c)) for c in columns}
            for r in rows]


def read_table(out: str | Path) -> Any:
    """The sweep's table (a ``pyarrow.Table``) from the parts in ``OUT/table`` (columns a part lacks are null)."""
    import pyarrow as pa  # noqa: PLC0415
    import pyarrow.parquet as pq  # noqa: PLC0415

    parts = [pq.read_table(p) for p in sorted((Path(out) / "table").glob("part-*.parquet"))]
    return pa.concat_tables(parts, promote_options="permissive") if parts else pa.table({})
