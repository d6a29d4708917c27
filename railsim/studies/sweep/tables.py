"""The sweep folder's results: one JSON row per finished case, and the tables derived from them.

Each finished case is persisted atomically as ``DIR/rows/<case_id>.json`` (:func:`read_rows` reads them back);
``cases.parquet`` and ``cases.csv`` are rebuilt from those rows for the cases of the current definition, in
expansion order (:func:`write_tables`), so they never hold a duplicate or a half-written row. Column order:
``case_id, status, error, seed``, the label columns, the override columns, ``wall_s``, then the metrics sorted.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from railsim.record import output
from railsim.studies.sweep.spec import SweepSpec

log = logging.getLogger(__name__)

# Columns that measure wall-clock time: they differ between runs of the same case; every other column may not.
WALL_CLOCK_COLUMNS = ("wall_s", "engine_wall_s")


def _rows_dir(out_dir: Path) -> Path:
    return Path(out_dir) / "rows"


def write_row(out_dir: Path, case_id: str, row: Mapping[str, Any]) -> None:
    """Persist one finished case's row as ``out_dir/rows/<case_id>.json`` (temp file + rename: never half-written)."""
    output.write_json(_rows_dir(out_dir) / f"{case_id}.json", row)


def read_rows(out_dir: Path) -> dict[str, dict[str, Any]]:
    """The persisted rows of a sweep folder, by case id.

    railsim's own writes are atomic, so a half-written row cannot come from it; a row file that is empty or not a
    JSON object anyway (a disk that failed, an edit by hand) is not a finished case: it is left out with a warning,
    and the case runs again (its new row replaces the file)."""
    rows: dict[str, dict[str, Any]] = {}
    folder = _rows_dir(out_dir)
    if folder.is_dir():
        for path in sorted(folder.glob("*.json")):
            try:
                row = json.loads(path.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                row = None
            if not isinstance(row, dict):
                log.warning("%s: not a readable row; case %s runs again", path, path.stem)
                continue
            rows[path.stem] = row
    return rows


def _table_rows(spec: SweepSpec, rows: Mapping[str, dict[str, Any]]) -> tuple[list[dict[str, Any]], list[str]]:
    table: list[dict[str, Any]] = []
    metric_cols: set[str] = set()
    for case in spec.cases:
        row = rows.get(case.case_id)
        if row is None:
            continue
        row = dict(row)
        row.update(case.labels)  # labels come from the current definition (they are not hashed)
        for col in spec.label_columns:
            row.setdefault(col, None)
        table.append(row)
        metric_cols.update(row)
    head = ["case_id", "status", "error", "seed", *spec.label_columns, *spec.override_columns, "wall_s"]
    columns = head + sorted(metric_cols - set(head))
    return table, columns


def _uniform_types(rows: list[dict[str, Any]], columns: Sequence[str]) -> list[dict[str, Any]]:
    """Parquet needs one type per column: a column mixing text and numbers becomes text."""
    out = [dict(r) for r in rows]
    for col in columns:
        kinds = {
            (
                "num"
                if isinstance(r.get(col), (int, float)) and not isinstance(r.get(col), bool)
                else type(r.get(col)).__name__
            )
            for r in out
            if r.get(col) is not None
        }
        if len(kinds) > 1:
            for r in out:
                if r.get(col) is not None:
                    r[col] = str(r[col])
    return out


def write_tables(spec: SweepSpec, out_dir: Path) -> int:
    """Rebuild ``cases.parquet`` and ``cases.csv`` from ``rows/`` (current cases, expansion order); row count."""
    rows, columns = _table_rows(spec, read_rows(out_dir))
    rows = _uniform_types(rows, columns)
    output.write_csv(Path(out_dir) / "cases.csv", rows, columns)
    output.write_parquet(Path(out_dir) / "cases.parquet", rows, columns)
    return len(rows)


def load_table(out_dir: str | Path) -> Any:
    """The cases table of a sweep folder as a pandas DataFrame."""
    import pandas as pd

    return pd.read_parquet(Path(out_dir) / "cases.parquet")
