"""Export a run's (or a sweep's) tables as CSV, Parquet or JSON, each readable by pandas in one line.

A *run folder* (written by ``railsim run``) holds its tables as CSV and/or Parquet, whichever the scenario's
``outputs.formats`` asked for. This module reads them back, whatever the format (:func:`read_table`; Parquet is
preferred when both exist because it keeps every float bit and every dtype), adds the **section table**
(one row per trip and section between two consecutive served stations, from
:func:`railsim.analysis.sections.section_table`) and writes all of them in one chosen format (:func:`export`):

==========  ===============================  ==================================================================
table       one row per                      source
==========  ===============================  ==================================================================
trips       trip                             ``trips.csv|parquet`` (:data:`railsim.record.recorder.TRIP_COLUMNS`)
stops       trip × served stop               ``stops.csv|parquet``
formations  virtually coupled formation      ``formations.csv|parquet``
events      logged event (exact time)        ``events.csv|parquet``
sections    trip × section                   :func:`railsim.analysis.sections.section_table` (computed)
trace       train × trace sample             ``trace.csv|parquet``, only with ``include_trace`` (it is large)
cases       sweep case                       a *sweep folder*'s ``cases.parquet|csv`` (instead of the above)
==========  ===============================  ==================================================================

Reading an export back is one line of pandas (:data:`READERS` holds the exact calls)::

    pd.read_csv("out/export/trips.csv")
    pd.read_parquet("out/export/trips.parquet")
    pd.read_json("out/export/trips.json", orient="records")

JSON is a list of records (one object per row, keys in column order, ``null`` for missing values), written with
Python's shortest round-trip float text. pandas' JSON reader infers dtypes: a float column whose values are all
whole numbers comes back as integers, and it parses floats with its fast reader unless ``precise_float=True``
is passed (the last bit may differ without it). Parquet round-trips exactly; CSV too, except that CSV cannot tell
empty text from a missing value (``pd.read_csv`` reads both as NaN, as it does for the run's own CSV files).

A missing or unreadable folder or table raises :class:`railsim.errors.ConfigError` naming the path (the CLI
prints one line and exits 2).
"""

from __future__ import annotations

import io
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from railsim.errors import ConfigError
from railsim.record import output, recorder as record

if TYPE_CHECKING:
    import pandas as pd

FORMATS = ("csv", "parquet", "json")
RUN_TABLES = ("trips", "stops", "formations", "events")  # recorded by railsim.record.recorder, always exported
READERS = {
    "csv": 'pd.read_csv("{path}")',
    "parquet": 'pd.read_parquet("{path}")',
    "json": 'pd.read_json("{path}", orient="records")',
}
# columns a run's table must have (the recorder writes all of them; a table without them is not ours)
REQUIRED_COLUMNS = {
    "trips": record.TRIP_COLUMNS,
    "stops": record.STOP_COLUMNS,
    "formations": record.FORMATION_COLUMNS,
    "events": record.EVENT_COLUMNS,
    "trace": record.TRACE_COLUMNS,
}
CASE_TABLE = "cases"


# ---------------------------------------------------------------------------------------------------- folders
def is_sweep_folder(folder: Path | str) -> bool:
    """True if ``folder`` holds a sweep's case table (``cases.parquet`` or ``cases.csv``)."""
    folder = Path(folder)
    return any((folder / f"{CASE_TABLE}.{ext}").is_file() for ext in ("parquet", "csv"))


def is_run_folder(folder: Path | str) -> bool:
    """True if ``folder`` holds a run's trip table (``trips.parquet`` or ``trips.csv``)."""
    folder = Path(folder)
    return any((folder / f"trips.{ext}").is_file() for ext in ("parquet", "csv"))


def check_folder(folder: Path | str) -> str:
    """``"run"`` or ``"sweep"`` for a results folder; ConfigError naming the path otherwise."""
    folder = Path(folder)
    if not folder.is_dir():
        raise ConfigError(folder, None, "no such results folder")
    if is_sweep_folder(folder):
        return "sweep"
    if is_run_folder(folder):
        return "run"
    raise ConfigError(
        folder,
        None,
        "not a railsim run folder (no trips.csv or trips.parquet) nor a sweep folder (no cases.csv or cases.parquet)",
    )


# ---------------------------------------------------------------------------------------------------- reading
def read_table(folder: Path | str, name: str) -> pd.DataFrame:
    """Table ``name`` of a run or sweep folder as a DataFrame (:func:`railsim.analysis.sections.read_table`: Parquet
    preferred over CSV), checked for the columns the recorder writes.

    Raises ConfigError naming the file if it is missing, unreadable, or lacks one of those columns.
    """
    from railsim.analysis import sections

    frame = sections.read_table(folder, name)
    missing = [c for c in REQUIRED_COLUMNS.get(name, ()) if c not in frame.columns]
    if missing:
        path = next(p for p in (Path(folder) / f"{name}.parquet", Path(folder) / f"{name}.csv") if p.is_file())
        raise ConfigError(path, missing[0], f"missing column (every {name} table written by railsim run has it)")
    return frame


def run_tables(run_dir: Path | str, include_trace: bool = False) -> dict[str, pd.DataFrame]:
    """The exportable tables of a run folder: trips, stops, formations, events, sections (and trace)."""
    run_dir = Path(run_dir)
    if check_folder(run_dir) != "run":
        raise ConfigError(run_dir, None, "a sweep folder, not a run folder")
    from railsim.analysis import sections

    tables = {name: read_table(run_dir, name) for name in RUN_TABLES}
    tables["sections"] = sections.section_table(run_dir)
    if include_trace:
        tables["trace"] = read_table(run_dir, "trace")
    return tables


def folder_tables(folder: Path | str, include_trace: bool = False) -> dict[str, pd.DataFrame]:
    """A sweep folder's ``{"cases": ...}`` or a run folder's :func:`run_tables`."""
    if check_folder(folder) == "sweep":
        return {CASE_TABLE: read_table(folder, CASE_TABLE)}
    return run_tables(folder, include_trace)


# ---------------------------------------------------------------------------------------------------- writing
def _json_value(value: Any) -> Any:
    if hasattr(value, "item"):  # numpy scalar
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def table_bytes(frame: pd.DataFrame, fmt: str) -> bytes:
    """``frame`` encoded as a CSV, Parquet or JSON-records file (no index)."""
    import pandas as pd

    if fmt == "csv":
        return frame.to_csv(index=False, lineterminator="\n").encode("utf-8")
    if fmt == "parquet":
        buf = io.BytesIO()
        frame.to_parquet(buf, index=False)
        return buf.getvalue()
    if fmt == "json":
        columns = [str(c) for c in frame.columns]
        records = [
            {
                c: (None if v is None or (not isinstance(v, str) and pd.isna(v)) else _json_value(v))
                for c, v in zip(columns, row)
            }
            for row in frame.itertuples(index=False, name=None)
        ]
        return (json.dumps(records, ensure_ascii=False, indent=None) + "\n").encode("utf-8")
    raise ConfigError(None, "format", f"expected one of {', '.join(FORMATS)}, got {fmt!r}")


def export(
    folder: Path | str, fmt: str = "csv", out_dir: Path | str | None = None, include_trace: bool = False
) -> list[Path]:
    """Write the tables of a run or sweep folder as ``<out_dir>/<table>.<fmt>``; returns the paths written.

    ``out_dir`` defaults to ``<folder>/export``. Files are replaced atomically.
    """
    if fmt not in FORMATS:
        raise ConfigError(None, "format", f"expected one of {', '.join(FORMATS)}, got {fmt!r}")
    folder = Path(folder)
    tables = folder_tables(folder, include_trace)
    dest = Path(out_dir) if out_dir is not None else folder / "export"
    written = []
    for name, frame in tables.items():
        path = dest / f"{name}.{fmt}"
        output.write_bytes(path, table_bytes(frame, fmt))
        written.append(path)
    return written
