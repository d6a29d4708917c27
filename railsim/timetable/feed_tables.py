"""The tables of a GTFS zip as checked text, and the strict parsing of GTFS values, each error naming its field.

A feed is a zip of CSV tables (https://gtfs.org/documentation/schedule/reference/). :class:`FeedZip` opens it and
reads one table at a time; everything a damaged or hostile file can do becomes a
:class:`~railsim.errors.ConfigError` naming the feed and the table or ``table.column``:

* **The archive**: not a zip, a truncated or damaged zip (its members' checksums are checked), a table missing,
  or one table twice (at the root and in a sub-folder). Tables in one sub-folder are fine (feeds are often
  zipped with their folder); directory entries and other files are ignored.
* **The text**: UTF-8 (a byte-order mark is dropped, as the reference allows), no NUL byte, CSV with a header;
  a row with more or fewer fields than the header, or a quote left open, is refused with its line number.
  Header names and values are stripped of surrounding spaces. An empty file counts as a table without rows
  (or as a missing table where one is required, :meth:`FeedZip.table` with ``required``).
* **Values** (:func:`gtfs_time`, :func:`non_negative_int`, :func:`gtfs_date`, :func:`coordinate`): a time is
  ``H:MM:SS`` with minutes and seconds below 60 and at most :data:`MAX_HOURS` hours (the reference allows times
  past 24:00 for a service day's trips after midnight; a week bounds a trip the simulation could run); a
  ``stop_sequence`` or ``headway_secs`` a non-negative integer; a date ``YYYYMMDD`` that exists; a stop's
  latitude/longitude finite and within WGS84 (empty: unknown, NaN).

Quoted values in messages go through :func:`railsim.inputs.excerpt` (bounded, escaped).
"""

from __future__ import annotations

import csv
import io
import math
import re
import zipfile
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import date as Date, datetime
from pathlib import Path

from railsim.errors import ConfigError
from railsim.inputs import excerpt

MAX_HOURS = 168  # the latest GTFS time accepted: a week after the service day's noon minus 12 h
_TIME = re.compile(r"(\d{1,6}):([0-5]\d):([0-5]\d)")
_INT = re.compile(r"\d{1,9}")


@dataclass(frozen=True)
class Table:
    """A table's header (column names) and rows (one dict per row, every column present); ``line`` gives the
    file's line number of row ``k`` (for messages)."""

    name: str
    columns: tuple[str, ...]
    rows: list[dict[str, str]]
    lines: list[int]

    def rows_of_trips(self, trips: set[str]) -> Iterator[tuple[dict[str, str], str]]:
        """The rows whose ``trip_id`` is in ``trips``, each with where it stands (trip and line, for messages)."""
        for row, line in zip(self.rows, self.lines):
            if row["trip_id"] in trips:
                yield row, f"trip {excerpt(row['trip_id'])}, line {line}"


class FeedZip:
    """An opened GTFS zip (module docstring: what it refuses)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        if not path.is_file():
            raise ConfigError(path, None, "expected an existing GTFS feed (.zip)")
        try:
            with zipfile.ZipFile(path) as zf:
                infos = [i for i in zf.infolist() if not i.is_dir()]
                damaged = zf.testzip()
        except (zipfile.BadZipFile, zlib.error, EOFError, OSError, NotImplementedError, RuntimeError) as exc:
            raise ConfigError(
                path, None, f"expected a GTFS feed (a .zip of .txt tables), got a file that is not a zip ({exc})"
            ) from None
        if damaged is not None:
            raise ConfigError(path, Path(damaged).name, "expected an intact zip member, got a damaged one (CRC)")
        self.members: dict[str, str] = {}
        for info in infos:
            base = Path(info.filename).name
            if base in self.members:
                raise ConfigError(
                    path, base, f"expected one {base} in the feed, got {self.members[base]!r} and {info.filename!r}"
                )
            self.members[base] = info.filename

    def has(self, name: str) -> bool:
        return name in self.members

    def table(self, name: str, required: tuple[str, ...] = (), *, present: bool = False) -> Table:
        """Table ``name`` (an empty table if the feed lacks it, or a ConfigError when ``present``); every column of
        ``required`` must be in its header."""
        if name not in self.members:
            if present:
                raise ConfigError(self.path, name, f"expected the GTFS table {name} in the feed, got none")
            return Table(name, (), [], [])
        try:
            with zipfile.ZipFile(self.path) as zf:
                data = zf.read(self.members[name])
        except (zipfile.BadZipFile, zlib.error, EOFError, OSError, NotImplementedError, RuntimeError) as exc:
            raise ConfigError(self.path, name, f"expected a readable zip member, got an error ({exc})") from None
        table = parse_csv(self.path, name, data)
        if present and not table.columns:
            raise ConfigError(self.path, name, "expected a header line, got an empty table")
        for col in required:
            if table.rows and col not in table.columns or present and col not in table.columns:
                raise ConfigError(self.path, f"{name}.{col}", "expected this column, got a table without it")
        return table


def parse_csv(path: Path, name: str, data: bytes) -> Table:
    """A table's bytes as a :class:`Table` (module docstring: what it refuses)."""
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise ConfigError(path, name, f"expected UTF-8 text, got an invalid byte in line {line}") from None
    if "\x00" in text:
        line = text[: text.index("\x00")].count("\n") + 1
        raise ConfigError(path, name, f"expected text, got a NUL byte in line {line}")
    reader = csv.reader(io.StringIO(text, newline=""), strict=True)
    columns: tuple[str, ...] = ()
    rows: list[dict[str, str]] = []
    lines: list[int] = []
    try:
        for fields in reader:
            if not fields or fields == [""]:
                continue
            cells = [f.strip() for f in fields]
            if not columns:
                columns = tuple(c.lstrip("\ufeff") for c in cells)
                continue
            if len(cells) != len(columns):
                raise ConfigError(
                    path,
                    name,
                    f"expected {len(columns)} fields as in the header, got {len(cells)} in line {reader.line_num}",
                )
            rows.append(dict(zip(columns, cells)))
            lines.append(reader.line_num)
    except csv.Error as exc:
        raise ConfigError(path, name, f"expected CSV, got {exc} in line {reader.line_num}") from None
    return Table(name, columns, rows, lines)


def gtfs_time(path: Path, where: str, value: str, context: str) -> float:
    """A GTFS time ``H:MM:SS`` [s after the service day's noon minus 12 h]; NaN for an empty value."""
    if value == "":
        return math.nan
    m = _TIME.fullmatch(value)
    if m is None or int(m.group(1)) > MAX_HOURS:
        raise ConfigError(
            path,
            where,
            f"expected a time H:MM:SS (minutes and seconds below 60, at most {MAX_HOURS} h), got {excerpt(value)} "
            f"({context})",
        )
    return float(3600 * int(m.group(1)) + 60 * int(m.group(2)) + int(m.group(3)))


def non_negative_int(path: Path, where: str, value: str, context: str) -> int:
    if _INT.fullmatch(value) is None:
        raise ConfigError(path, where, f"expected a whole number >= 0, got {excerpt(value)} ({context})")
    return int(value)


def gtfs_date(path: Path, where: str, value: str, context: str) -> Date:
    try:
        if re.fullmatch(r"\d{8}", value) is None:
            raise ValueError(value)
        return datetime.strptime(value, "%Y%m%d").date()
    except ValueError:
        raise ConfigError(path, where, f"expected a date YYYYMMDD, got {excerpt(value)} ({context})") from None


def coordinate(path: Path, where: str, value: str, limit_deg: float, context: str) -> float:
    """A latitude (``limit_deg`` 90) or longitude (180) in degrees; NaN for an empty value (unknown)."""
    if value == "":
        return math.nan
    try:
        deg = float(value)
    except ValueError:
        deg = math.nan
    if not (math.isfinite(deg) and abs(deg) <= limit_deg):
        raise ConfigError(
            path, where, f"expected degrees within +-{limit_deg:g} (WGS84) or nothing, got {excerpt(value)} ({context})"
        )
    return deg
