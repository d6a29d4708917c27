"""A seeded mutator over the committed GTFS feed, and the fuzz harness around ``railsim timetable import``.

No feed may break the import. :func:`mutant` turns ``tests/data/gtfs/sao_paulo_rail_cut.zip`` into hostile feeds,
deterministically from a seed: mutant ``k`` is the same bytes on every machine (the zip is written stored, not
deflated, with fixed timestamps, so no zlib version enters). Each mutant applies one to three **table** mutations
and sometimes one **archive** mutation:

* **table** — on the parsed CSV rows (:data:`TABLE_OPS`): a required column removed or renamed, a table removed,
  emptied or left with its header only, a byte-order mark, CRLF line ends, a duplicated id, one trip's calls out
  of sequence or duplicated, a hostile time (``25:61:00``, ``-1:00:00``, ``99999:00:00``, empty, ``nan``...), an
  arrival after its departure, a non-numeric ``stop_sequence``, a hostile ``headway_secs`` (0, negative, huge,
  fractional), ``start_time`` after ``end_time``, a hostile ``stop_lat``/``stop_lon`` (NaN, inf, out of range,
  empty), a call of a missing stop or trip, a bad calendar date (``20261340``) or a calendar spanning millennia,
  a non-numeric ``route_type``, one ``block_id`` over trips that overlap in time, a ragged row, invalid UTF-8,
  a NUL byte;
* **archive** — a truncated zip, a directory entry, the feed zipped inside a zip, the tables in a sub-folder (and
  twice: root and sub-folder), an empty zip, an empty file, a text file.

Two harnesses classify a mutant's outcome as **ok**, **refused** (cleanly) or a **defect**:

* :func:`read_in_process` calls the reading layer, :func:`railsim.timetable.gtfs.read_trips`, on one date and
  window. Ok: it returns trips whose times are finite, not negative, and in order (arrival <= departure, never
  earlier than the call before), with stop positions NaN (absent) or valid WGS84. Refused: a ``ConfigError``
  naming the feed file and a field (the archive itself, for a file that is not a zip). Anything else (another exception, a hang) is a defect. No process is
  started, so the unit tier runs it (``tests/unit/test_fuzz_gtfs.py``).
* :func:`import_in_process` runs ``railsim timetable import FEED --world DIR ...`` through
  :func:`tests.fuzz.cli_in_process` on a world made by ``railsim network import`` (the São Paulo centre extract,
  which matches the feed's stations). Ok: exit 0 and the written scenario passes ``railsim validate`` with its
  world check. Refused: exit 2 and one ``railsim: error: FEED: FIELD: ...`` line. A traceback, exit 4, a hang, or a
  written scenario that fails validation is a defect. The world import runs netconvert, so this harness belongs
  to ``tests/sumo``.

``python -m tests.fuzz_gtfs --mutants N`` prints the campaign figures as JSON (``--reader`` for the reading layer
alone, ``--world DIR`` to reuse an imported world).
"""

from __future__ import annotations

import csv
import io
import json
import math
import random
import signal
import sys
import tempfile
import time
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import date
from pathlib import Path

from tests.fuzz import Hang, _on_alarm, campaign_parser, cli_in_process

ROOT = Path(__file__).resolve().parents[1]
BASE_FEED = ROOT / "tests" / "data" / "gtfs" / "sao_paulo_rail_cut.zip"
SAO_PAULO_OSM = ROOT / "tests" / "data" / "osm" / "sao_paulo_centre_rail.osm.gz"
DAY = date(2019, 10, 1)  # a Tuesday the feed runs
FROM_S = 7 * 3600.0
TO_S = 7 * 3600.0 + 300.0  # a five-minute window: a few dozen trips, a fast import
TIMEOUT_S = 30.0  # per mutant; a healthy import of the window takes about a second
ZIP_TIME = (2019, 10, 1, 0, 0, 0)

Tables = dict[str, list[list[str]] | bytes]  # a table as CSV rows (header first), or raw bytes once made hostile

REQUIRED_COLUMNS = {
    "routes.txt": ("route_id", "route_type"),
    "trips.txt": ("route_id", "service_id", "trip_id"),
    "stop_times.txt": ("trip_id", "arrival_time", "departure_time", "stop_id", "stop_sequence"),
    "stops.txt": ("stop_id", "stop_name", "stop_lat", "stop_lon"),
    "frequencies.txt": ("trip_id", "start_time", "end_time", "headway_secs"),
    "calendar.txt": ("service_id", "tuesday", "start_date", "end_date"),
}
HOSTILE_TIMES = ("25:61:00", "-1:00:00", "99999:00:00", "", "nan", "inf", "7:00", "07:00:00:00", "ab:cd:ef", "1e308")
HOSTILE_SEQUENCES = ("x", "1.5", "-3", "", "nan", "1e309", "99999999999999999999999")
HOSTILE_HEADWAYS = ("0", "-60", "1e12", "99999999999", "", "nan", "1", "0.001", "x", "inf")
HOSTILE_COORDS = ("nan", "inf", "-inf", "91", "-181", "1e308", "", "x")
HOSTILE_DATES = ("20261340", "", "x", "00000000", "2019-10-01", "00010101", "99991231")
HOSTILE_ROUTE_TYPES = ("x", "", "1.5", "-1", "1e400", "99999999999999999999999", "nan")


@dataclass(frozen=True)
class Mutant:
    """One mutated feed: what was done to it, its bytes."""

    index: int
    ops: tuple[str, ...]
    data: bytes


# ---- the mutator -----------------------------------------------------------------------------------------------


def base_tables(feed: Path = BASE_FEED) -> dict[str, list[list[str]]]:
    """The committed feed's tables as CSV rows, in the zip's order."""
    with zipfile.ZipFile(feed) as zf:
        return {n: list(csv.reader(io.StringIO(zf.read(n).decode("utf-8")))) for n in zf.namelist()}


def _rows(tables: Tables, name: str) -> list[list[str]] | None:
    """The rows of ``name`` if it is still parsed CSV with a header (None: missing or already raw bytes)."""
    rows = tables.get(name)
    return rows if isinstance(rows, list) and rows else None


def _column(rows: list[list[str]], col: str) -> int | None:
    return rows[0].index(col) if col in rows[0] else None


def _set_cell(rng: random.Random, tables: Tables, name: str, col: str, values: tuple[str, ...]) -> str:
    rows = _rows(tables, name)
    k = _column(rows, col) if rows else None
    if rows is None or k is None or len(rows) < 2:
        return f"{name}.{col}: absent"
    i = rng.randrange(1, len(rows))
    value = rng.choice(values)
    rows[i][k] = value
    return f"{name}.{col}[{i}]={value!r}"


def _trip_rows(rng: random.Random, tables: Tables) -> tuple[list[list[str]], list[int], int] | None:
    """stop_times rows, the row indices of one random trip, and the stop_sequence column."""
    rows = _rows(tables, "stop_times.txt")
    if rows is None or len(rows) < 2 or _column(rows, "trip_id") is None or _column(rows, "stop_sequence") is None:
        return None
    tk, sk = rows[0].index("trip_id"), rows[0].index("stop_sequence")
    trip = rows[rng.randrange(1, len(rows))][tk]
    return rows, [i for i in range(1, len(rows)) if rows[i][tk] == trip], sk


def op_drop_column(rng: random.Random, tables: Tables) -> str:
    name = rng.choice(sorted(REQUIRED_COLUMNS))
    rows, col = _rows(tables, name), rng.choice(REQUIRED_COLUMNS[name])
    k = _column(rows, col) if rows else None
    if rows is None or k is None:
        return f"drop {name}.{col}: absent"
    rename = rng.random() < 0.5
    for row in rows:
        if rename:
            row[k] = row[k] + "_x" if row is rows[0] else row[k]
        elif k < len(row):
            del row[k]
    return f"{'rename' if rename else 'drop'} {name}.{col}"


def op_table(rng: random.Random, tables: Tables) -> str:
    name = rng.choice(sorted(tables))
    kind = rng.choice(("remove", "empty", "header only"))
    if kind == "remove":
        del tables[name]
    elif kind == "empty":
        tables[name] = b""
    elif isinstance(tables[name], list):
        del tables[name][1:]  # type: ignore[union-attr]
    return f"{kind} {name}"


def op_encoding(rng: random.Random, tables: Tables) -> str:
    name = rng.choice(sorted(tables))
    data = _bytes(tables[name])
    kind = rng.choice(("bom", "crlf", "utf-8", "nul"))
    i = rng.randrange(len(data) + 1)
    if kind == "bom":
        data = b"\xef\xbb\xbf" + data
    elif kind == "crlf":
        data = data.replace(b"\n", b"\r\n")
    elif kind == "utf-8":
        data = data[:i] + b"\xff\xfe\x80" + data[i:]
    else:
        data = data[:i] + b"\x00" + data[i:]
    tables[name] = data
    return f"{kind} in {name}" + (f" at {i}" if kind in ("utf-8", "nul") else "")


def op_duplicate_row(rng: random.Random, tables: Tables) -> str:
    name = rng.choice(("routes.txt", "trips.txt", "stops.txt", "calendar.txt", "stop_times.txt", "frequencies.txt"))
    rows = _rows(tables, name)
    if rows is None or len(rows) < 2:
        return f"duplicate in {name}: no rows"
    i = rng.randrange(1, len(rows))
    rows.insert(i, list(rows[i]))
    return f"duplicate {name}[{i}]"


def op_sequence(rng: random.Random, tables: Tables) -> str:
    found = _trip_rows(rng, tables)
    if found is None:
        return "sequence: no stop_times"
    rows, idx, sk = found
    kind = rng.choice(("shuffle", "repeat", "hostile"))
    if kind == "shuffle":
        values = [rows[i][sk] for i in idx]
        rng.shuffle(values)
        for i, v in zip(idx, values):
            rows[i][sk] = v
    elif kind == "repeat":
        i = rng.choice(idx)
        rows.insert(i, list(rows[i]))
    else:
        return _set_cell(rng, tables, "stop_times.txt", "stop_sequence", HOSTILE_SEQUENCES)
    return f"{kind} calls of {rows[idx[0]][rows[0].index('trip_id')] if 'trip_id' in rows[0] else '?'}"


def op_time(rng: random.Random, tables: Tables) -> str:
    name, col = rng.choice(
        (
            ("stop_times.txt", "arrival_time"),
            ("stop_times.txt", "departure_time"),
            ("frequencies.txt", "start_time"),
            ("frequencies.txt", "end_time"),
        )
    )
    return _set_cell(rng, tables, name, col, HOSTILE_TIMES)


def op_order(rng: random.Random, tables: Tables) -> str:
    """An arrival after its departure, or a frequency window ending before it starts."""
    if rng.random() < 0.5:
        rows = _rows(tables, "stop_times.txt")
        if rows is None or _column(rows, "arrival_time") is None or _column(rows, "departure_time") is None:
            return "arrival after departure: absent"
        a, d = rows[0].index("arrival_time"), rows[0].index("departure_time")
        i = rng.randrange(1, len(rows))
        rows[i][a], rows[i][d] = "08:10:00", "08:00:00"
        return f"arrival after departure at stop_times.txt[{i}]"
    rows = _rows(tables, "frequencies.txt")
    if rows is None or _column(rows, "start_time") is None or _column(rows, "end_time") is None:
        return "start after end: absent"
    s, e = rows[0].index("start_time"), rows[0].index("end_time")
    i = rng.randrange(1, len(rows))
    rows[i][s], rows[i][e] = rows[i][e], rows[i][s]
    return f"start_time after end_time at frequencies.txt[{i}]"


def op_headway(rng: random.Random, tables: Tables) -> str:
    return _set_cell(rng, tables, "frequencies.txt", "headway_secs", HOSTILE_HEADWAYS)


def op_coord(rng: random.Random, tables: Tables) -> str:
    return _set_cell(rng, tables, "stops.txt", rng.choice(("stop_lat", "stop_lon")), HOSTILE_COORDS)


def op_reference(rng: random.Random, tables: Tables) -> str:
    name, col = rng.choice(
        (
            ("stop_times.txt", "stop_id"),
            ("stop_times.txt", "trip_id"),
            ("trips.txt", "route_id"),
            ("trips.txt", "service_id"),
        )
    )
    return _set_cell(rng, tables, name, col, ("NO_SUCH_ID",))


def op_calendar(rng: random.Random, tables: Tables) -> str:
    col = rng.choice(("start_date", "end_date", "end_date", "tuesday"))
    return _set_cell(rng, tables, "calendar.txt", col, ("2", "x", "") if col == "tuesday" else HOSTILE_DATES)


def op_route_type(rng: random.Random, tables: Tables) -> str:
    return _set_cell(rng, tables, "routes.txt", "route_type", HOSTILE_ROUTE_TYPES)


def op_blocks(rng: random.Random, tables: Tables) -> str:
    """One block_id over several trips of a route (frequency templates that run at the same time)."""
    rows = _rows(tables, "trips.txt")
    if rows is None:
        return "blocks: no trips"
    rows[0].append("block_id")
    for k, row in enumerate(rows[1:]):
        row.append("B1" if k % rng.choice((1, 2, 3)) == 0 else "")
    return "one block_id over overlapping trips"


def op_ragged(rng: random.Random, tables: Tables) -> str:
    name = rng.choice(sorted(n for n in tables if _rows(tables, n)))
    rows = _rows(tables, name)
    assert rows is not None
    i = rng.randrange(len(rows))
    kind = rng.choice(("extra", "short", "quote"))
    if kind == "extra":
        rows[i].extend(["x", "y"])
    elif kind == "short":
        del rows[i][1:]
    else:
        rows[i][0] = '"' + rows[i][0]
    return f"ragged ({kind}) {name}[{i}]"


TABLE_OPS: tuple[Callable[[random.Random, Tables], str], ...] = (
    op_drop_column,
    op_table,
    op_encoding,
    op_duplicate_row,
    op_sequence,
    op_sequence,
    op_time,
    op_time,
    op_order,
    op_headway,
    op_coord,
    op_reference,
    op_calendar,
    op_route_type,
    op_blocks,
    op_ragged,
)


def _bytes(table: list[list[str]] | bytes) -> bytes:
    """A table's bytes: CSV with ``\n`` line ends; a cell opening with a quote (op_ragged's unbalanced quote)
    is written as it is."""
    if isinstance(table, bytes):
        return table
    return "".join(",".join(c if c.startswith('"') else _cell(c) for c in row) + "\n" for row in table).encode()


def _cell(text: str) -> str:
    return '"' + text.replace('"', '""') + '"' if any(ch in text for ch in ',"\n\r') else text


def zip_bytes(files: dict[str, bytes]) -> bytes:
    """A stored zip of ``files`` with fixed timestamps (the same bytes everywhere); a name ending in ``/`` is a
    directory entry."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_STORED) as zf:
        for name, data in files.items():
            zf.writestr(zipfile.ZipInfo(name, ZIP_TIME), data)
    return buf.getvalue()


def archive_op(rng: random.Random, files: dict[str, bytes]) -> tuple[bytes, str]:
    """One mutation of the archive itself; returns the feed's bytes and a label."""
    kind = rng.choice(("truncate", "directory", "nested", "subfolder", "twice", "empty zip", "empty", "text"))
    if kind == "truncate":
        data = zip_bytes(files)
        cut = rng.randrange(len(data))
        return data[:cut], f"zip truncated at {cut}"
    if kind == "directory":
        return zip_bytes({"extra/": b"", **files}), "a directory entry"
    if kind == "nested":
        return zip_bytes({"feed.zip": zip_bytes(files)}), "the feed zipped in a zip"
    if kind == "subfolder":
        return zip_bytes({f"gtfs/{n}": d for n, d in files.items()}), "the tables in a sub-folder"
    if kind == "twice":
        return zip_bytes({**files, **{f"gtfs/{n}": d for n, d in files.items()}}), "the tables twice"
    if kind == "empty zip":
        return zip_bytes({}), "an empty zip"
    if kind == "empty":
        return b"", "an empty file"
    return b"route_id,route_type\nr,1\n", "a text file"


def mutant(index: int, seed: int = 0) -> Mutant:
    """Mutant ``index`` of the campaign ``seed`` (deterministic)."""
    rng = random.Random(seed * 1_000_003 + index)
    tables: Tables = dict(base_tables())
    ops = [rng.choice(TABLE_OPS)(rng, tables) for _ in range(rng.choice((1, 1, 2, 3)))]
    files = {name: _bytes(table) for name, table in tables.items()}
    if rng.random() < 0.12:
        data, label = archive_op(rng, files)
        ops.append(label)
    else:
        data = zip_bytes(files)
    return Mutant(index, tuple(ops), data)


# ---- classifying outcomes ----------------------------------------------------------------------------------------


@dataclass
class Verdict:
    kind: str  # "ok" | "refused" | "defect"
    detail: str
    seconds: float


def _bad_times(feed: object) -> str | None:
    """Why a read feed's trips or stops are wrong (None: they are fine)."""
    from railsim.timetable.gtfs import Feed

    assert isinstance(feed, Feed)
    for trip in feed.trips:
        last = 0.0
        for c in trip.calls:
            if not (math.isfinite(c.arrival_s) and math.isfinite(c.departure_s)):
                return f"trip {trip.trip_id}: a non-finite time {c}"
            if c.arrival_s < last or c.departure_s < c.arrival_s:
                return f"trip {trip.trip_id}: a time out of order or negative {c}"
            last = c.departure_s
    for stop in feed.stops.values():
        for value, limit in ((stop.lon, 180.0), (stop.lat, 90.0)):
            if not math.isnan(value) and not abs(value) <= limit:
                return f"stop {stop.stop_id}: position {stop.lon}, {stop.lat}"
    return None


def read_in_process(path: Path, timeout_s: float = TIMEOUT_S) -> Verdict:
    """:func:`read_trips` on ``path`` under a time limit, classified (module docstring)."""
    from railsim.errors import ConfigError
    from railsim.timetable.gtfs import read_trips

    old = signal.signal(signal.SIGALRM, _on_alarm)
    signal.setitimer(signal.ITIMER_REAL, timeout_s)
    t0 = time.perf_counter()
    try:
        feed = read_trips(path, DAY, FROM_S, TO_S)
        bad = _bad_times(feed)
        verdict = Verdict("defect", bad, 0.0) if bad else Verdict("ok", f"{len(feed.trips)} trips", 0.0)
    except ConfigError as err:
        named = err.source == str(path) and bool(err.field or "not a zip" in err.message)
        verdict = Verdict("refused" if named else "defect", ("" if named else "unnamed: ") + str(err)[:300], 0.0)
    except Hang:
        verdict = Verdict("defect", f"hang (> {timeout_s:g} s)", 0.0)
    except Exception as exc:  # noqa: BLE001 - anything but a ConfigError breaks the contract
        verdict = Verdict("defect", f"{type(exc).__name__}: {str(exc)[:200]}", 0.0)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    verdict.seconds = time.perf_counter() - t0
    return verdict


def import_in_process(path: Path, world: Path, out: Path, timeout_s: float = TIMEOUT_S) -> Verdict:
    """``railsim timetable import`` of ``path`` onto ``world`` in this process, classified (module docstring)."""
    argv = ["timetable", "import", str(path), "--world", str(world), "--date", DAY.isoformat()]
    argv += ["--from", "07:00", "--to", "07:05", "--out", str(out)]
    res = cli_in_process(argv, timeout_s)
    if res.problem is not None:
        return Verdict("defect", f"{res.problem}: {res.stderr[-300:]}", res.seconds)
    if res.rc == 2:
        head = f"railsim: error: {path}: "
        line = res.stderr.strip()
        named = line.startswith(head) and (": " in line[len(head) :] or "not a zip" in line)
        return Verdict("refused" if named else "defect", ("" if named else "unnamed: ") + line[:300], res.seconds)
    check = cli_in_process(["validate", str(out)], timeout_s)
    if check.rc != 0:
        return Verdict("defect", f"written scenario fails validate: {check.stderr[-300:]}", res.seconds)
    return Verdict("ok", "", res.seconds)


@dataclass
class Figures:
    mutants: int = 0
    ok: int = 0
    refused: int = 0
    defects: int = 0
    seconds: float = 0.0
    slowest_s: float = 0.0
    problems: list[str] = field(default_factory=list)


def campaign(n: int, workdir: Path, seed: int = 0, world: Path | None = None, first: int = 0) -> Figures:
    """Mutants ``first`` to ``first + n - 1`` through the reading layer (``world`` None) or the import command."""
    fig = Figures()
    t0 = time.perf_counter()
    for k in range(first, first + n):
        m = mutant(k, seed)
        path = workdir / f"feed_{k:05d}.zip"
        path.write_bytes(m.data)
        if world is None:
            v = read_in_process(path)
        else:
            v = import_in_process(path, world, workdir / f"scenario_{k:05d}.yaml")
        fig.mutants += 1
        fig.slowest_s = max(fig.slowest_s, v.seconds)
        fig.ok += v.kind == "ok"
        fig.refused += v.kind == "refused"
        if v.kind == "defect":
            fig.defects += 1
            fig.problems.append(f"mutant {k} ({'; '.join(m.ops)}): {v.detail}")
        path.unlink()
    fig.seconds = time.perf_counter() - t0
    return fig


def import_world(out: Path) -> Path:
    """The São Paulo centre world (``railsim network import``; runs netconvert)."""
    from railsim.cli.main import main

    rc = main(["network", "import", str(SAO_PAULO_OSM), "--out", str(out)])
    if rc != 0:
        raise RuntimeError(f"network import failed with exit {rc}")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = campaign_parser("Fuzz railsim timetable import with mutants of the committed GTFS feed.", 200, first=True)
    ap.add_argument("--reader", action="store_true", help="the reading layer only (read_trips; no world)")
    ap.add_argument("--world", type=Path, default=None, help="an imported world to reuse (default: import one)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="railsim-fuzz-gtfs-") as tmp:
        world = None if args.reader else (args.world or import_world(Path(tmp) / "world"))
        fig = campaign(args.mutants, Path(tmp), args.seed, world, args.first)
    print(json.dumps(fig.__dict__, indent=1))
    return 1 if fig.problems else 0


if __name__ == "__main__":
    sys.exit(main())
