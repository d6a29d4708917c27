"""The tables of a GTFS zip as checked text, and the strict parsing of GTFS values, each error naming its field.

A feed is a zip of CSV tables (https://gtfs.org/documentation/schedule/reference/). :class:`FeedZip` opens it and
reads one table at a time, **streamed** from the zip member a megabyte at a time: :meth:`FeedZip.rows` gives a
table row by row (:class:`TableRows`, which can keep the rows whose ``trip_id`` is wanted and drop the others as
they are read), :meth:`FeedZip.table` a whole small table. A ``stop_times.txt`` of millions of rows (a city's
buses) thus costs the memory of the rows kept, not of the file. Everything a damaged or hostile file can do
becomes a :class:`~railsim.errors.ConfigError` naming the feed and the table or ``table.column``:

* **The archive**: not a zip, a truncated or damaged zip (a member's checksum is checked as it is read; members
  not read, like ``shapes.txt``, are not decompressed), a table missing, or one table twice (at the root and in a
  sub-folder). Tables in one sub-folder are fine (feeds are often zipped with their folder); directory entries and
  other files are ignored.
* **The text**, of every row read, kept or not: UTF-8 (a byte-order mark is dropped, as the reference allows), no
  NUL byte, CSV with a header; a row with more or fewer fields than the header, or a quote left open, is refused
  with its line number. Header names and values are stripped of surrounding spaces. An empty file counts as a
  table without rows (or as a missing table where one is required, :meth:`FeedZip.table` with ``present``).
* **Values** (:func:`gtfs_time`, :func:`non_negative_int`, :func:`gtfs_date`, :func:`coordinate`): a time is
  ``H:MM:SS`` with minutes and seconds below 60 and at most :data:`MAX_HOURS` hours (the reference allows times
  past 24:00 for a service day's trips after midnight; a week bounds a trip the simulation could run); a
  ``stop_sequence`` or ``headway_secs`` a non-negative integer; a date ``YYYYMMDD`` that exists; a stop's
  latitude/longitude finite and within WGS84 (empty: unknown, NaN).

Quoted values in messages go through :func:`railsim.inputs.excerpt` (bounded, escaped).
"""

from __future__ import annotations

import codecs
import csv
import io
import itertools
import math
import re
import zipfile
import zlib
from collections.abc import Container, Iterable, Iterator
from dataclasses import dataclass
from datetime import date as Date, datetime
from pathlib import Path
from typing import IO

from railsim.errors import ConfigError
from railsim.inputs import excerpt

MAX_HOURS = 168  # the latest GTFS time accepted: a week after the service day's noon minus 12 h
_TIME = re.compile(r"(\d{1,6}):([0-5]\d):([0-5]\d)")
_INT = re.compile(r"\d{1,9}")


@dataclass(frozen=True)
class Table:
    """A table's header (column names) and rows (one dict per row, every column present); ``lines[k]`` is the
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


class TableRows:
    """A table read row by row from its text (module docstring: what it refuses): :attr:`columns` at once, then
    ``(fields, line)`` per row, the fields as in the file (not stripped; :meth:`record` strips them), as many as
    the header's. Nothing is held but the row at hand, so a table of millions of rows costs what is kept of it."""

    def __init__(self, path: Path, name: str, lines: Iterable[str]) -> None:
        self.path, self.name = path, name
        self._reader = csv.reader(lines, strict=True)
        self.columns: tuple[str, ...] = ()
        try:
            for fields in self._reader:
                if fields and fields != [""]:
                    self.columns = tuple(f.strip().lstrip("\ufeff") for f in fields)
                    break
        except csv.Error as exc:
            raise ConfigError(path, name, f"expected CSV, got {exc} in line {self._reader.line_num}") from None

    def __iter__(self) -> Iterator[tuple[list[str], int]]:
        reader, n = self._reader, len(self.columns)
        try:
            for fields in reader:
                if len(fields) != n or n == 1:
                    if not fields or fields == [""]:
                        continue
                    if len(fields) != n:
                        raise ConfigError(
                            self.path,
                            self.name,
                            f"expected {n} fields as in the header, got {len(fields)} in line {reader.line_num}",
                        )
                yield fields, reader.line_num
        except csv.Error as exc:
            raise ConfigError(self.path, self.name, f"expected CSV, got {exc} in line {reader.line_num}") from None

    def index(self, column: str) -> int:
        """The position of ``column`` in a row (a ConfigError naming ``table.column`` if the header lacks it)."""
        if column not in self.columns:
            raise ConfigError(self.path, f"{self.name}.{column}", "expected this column, got a table without it")
        return self.columns.index(column)

    def record(self, fields: list[str]) -> dict[str, str]:
        """A row as ``{column: value}``, values stripped of surrounding spaces."""
        return dict(zip(self.columns, [f.strip() for f in fields]))

    def collect(self, column: str | None = None, values: Container[str] = ()) -> Table:
        """The rest of the table as a :class:`Table`: every row, or those whose ``column`` is one of ``values``
        (the others are read and checked as text, not kept)."""
        rows: list[dict[str, str]] = []
        lines: list[int] = []
        if column is None:
            for fields, line in self:
                rows.append(self.record(fields))
                lines.append(line)
        else:
            k = self.index(column)
            for fields, line in self:
                if fields[k].strip() in values:
                    rows.append(self.record(fields))
                    lines.append(line)
        return Table(self.name, self.columns, rows, lines)


_ZIP_ERRORS = (zipfile.BadZipFile, zlib.error, EOFError, OSError, NotImplementedError, RuntimeError)


class FeedZip:
    """An opened GTFS zip (module docstring: what it refuses)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        if not path.is_file():
            raise ConfigError(path, None, "expected an existing GTFS feed (.zip)")
        try:
            with zipfile.ZipFile(path) as zf:
                infos = [i for i in zf.infolist() if not i.is_dir()]
        except _ZIP_ERRORS as exc:
            raise ConfigError(
                path, None, f"expected a GTFS feed (a .zip of .txt tables), got a file that is not a zip ({exc})"
            ) from None
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
        """Table ``name`` whole (an empty table if the feed lacks it, or a ConfigError when ``present``); every
        column of ``required`` must be in its header."""
        if name not in self.members:
            if present:
                raise ConfigError(self.path, name, f"expected the GTFS table {name} in the feed, got none")
            return Table(name, (), [], [])
        rows = self.rows(name) if present else TableRows(self.path, name, self._lines(name))
        table = rows.collect()
        for col in required:
            if table.rows and col not in table.columns or present and col not in table.columns:
                raise ConfigError(self.path, f"{name}.{col}", "expected this column, got a table without it")
        return table

    def rows(self, name: str, required: tuple[str, ...] = ()) -> TableRows:
        """Table ``name`` row by row; the feed must have it, with a header naming every column of ``required``."""
        if name not in self.members:
            raise ConfigError(self.path, name, f"expected the GTFS table {name} in the feed, got none")
        rows = TableRows(self.path, name, self._lines(name))
        if not rows.columns:
            raise ConfigError(self.path, name, "expected a header line, got an empty table")
        for col in required:
            rows.index(col)
        return rows

    def _lines(self, name: str) -> Iterator[str]:
        """The lines of member ``name``, decoded and checked as they are read (:func:`text_lines`)."""
        return itertools.chain.from_iterable(self._chunks(name))

    def _chunks(self, name: str) -> Iterator[list[str]]:
        try:
            with zipfile.ZipFile(self.path) as zf, zf.open(self.members[name]) as raw:
                yield from text_lines(self.path, name, raw)
        except _ZIP_ERRORS as exc:
            raise ConfigError(self.path, name, f"expected a readable zip member, got an error ({exc})") from None


def text_lines(path: Path, name: str, raw: IO[bytes], chunk_bytes: int = 1 << 20) -> Iterator[list[str]]:
    """The text of ``raw`` as lists of lines (each with its line end, split as CSV reads them: ``\\n``, ``\\r\\n``
    or ``\\r``), read ``chunk_bytes`` at a time: UTF-8 (a byte-order mark dropped) without a NUL byte, else a
    ConfigError naming ``name`` and the line."""
    decoder = codecs.getincrementaldecoder("utf-8-sig")()
    before = 0  # line ends in the text decoded so far
    pending = ""  # the last line of the text so far when it may go on in the next chunk
    while True:
        data = raw.read(chunk_bytes)
        final = not data
        try:
            text = decoder.decode(data, final)
        except UnicodeDecodeError as exc:
            line = before + exc.object[: exc.start].count(b"\n") + 1
            raise ConfigError(path, name, f"expected UTF-8 text, got an invalid byte in line {line}") from None
        if "\x00" in text:
            line = before + text[: text.index("\x00")].count("\n") + 1
            raise ConfigError(path, name, f"expected text, got a NUL byte in line {line}")
        before += text.count("\n")
        text = pending + text
        if text:
            lines = io.StringIO(text, newline="").readlines()
            pending = "" if final or lines[-1].endswith("\n") else lines.pop()
            yield lines
        if final:
            return


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
