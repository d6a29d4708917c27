"""Reading a GTFS feed into the rail trips of one day and one time window.

The tables are read one at a time from the zip and every value used is parsed strictly (:mod:`.feed_tables`):
a damaged archive, a table that is not UTF-8 CSV, a missing column, a time like ``25:61:00`` or a
``stop_sequence`` like ``x`` is a :class:`~railsim.errors.ConfigError` naming the feed and ``table.column`` (one
line, exit 2), never a traceback and never a value carried on silently.

``trips.txt`` and ``stop_times.txt`` are streamed: only the rows of rail trips (``trips.txt``) and of the trips
kept for the date (``stop_times.txt``) are held, so a city's feed with millions of bus calls reads in seconds and
in the memory of its rail part. Every row of every table read is checked as text (UTF-8, no NUL byte, well-formed
CSV with the header's number of fields), and every ``trip_id`` of ``trips.txt`` must be unique and name a route
of ``routes.txt``; the other values of a row that is not kept (the times and stops of a bus trip, a trip of
another day) are not parsed, so a bad one there is not refused: it cannot reach the trips read.

What :func:`read_trips` keeps:

* **Services running on the date**: ``calendar.txt`` (the weekday's flag, between ``start_date`` and
  ``end_date``) with ``calendar_dates.txt``'s exceptions (type 1 adds a service on a date, 2 removes it). Only
  the asked date is resolved, so a calendar spanning centuries costs nothing.
* **Rail routes** (:data:`RAIL_ROUTE_TYPES`): GTFS ``route_type`` 0 tram, 1 subway/metro, 2 rail, 12 monorail,
  and the extended types 100-199 (railway services), 400-499 (urban railway), 900-999 (tram). ``--routes``
  narrows further (route ids or short names).
* **Trips running on the date**, with their stop times in ``stop_sequence`` order. Calls without times between
  timed calls are interpolated (the reference allows them); the first and last call must have times, and times
  may not run backwards (an arrival after its departure, or before the previous call's departure). A trip with
  fewer than two calls is left out. A trip listed in ``frequencies.txt`` is a template: it is **expanded** into
  one trip every ``headway_secs`` (a whole number > 0) from ``start_time`` up to (not including) ``end_time``
  (GTFS reference; a template's periods may not overlap), each a copy of the template's stop times shifted so it
  leaves its first stop at that time; the copies are named ``<trip_id>@HH:MM:SS``. Only the copies leaving in the
  window are made, so a one-second headway costs the window, not the day. ``exact_times`` makes no difference
  here (a simulation schedules what the feed gives either way).
* **The window**: trips whose first departure lies in ``[from, to)``.
* **Stops** of the kept trips: every call must name a stop of ``stops.txt``; the name is the parent station's
  when it has one; an empty ``stop_lat``/``stop_lon`` is unknown (NaN: the stop matches by name only).

Ids are keys: ``route_id``, ``trip_id``, ``stop_id`` and ``service_id`` (in ``calendar.txt``) appear once each.
Every trip carries its ``block_id`` when the feed has one (a vehicle's chain of trips, used as an explicit
rotation by :mod:`railsim.timetable.rotations`). A feed with no service on the date or no rail route is a
ConfigError too.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from datetime import date as Date
from pathlib import Path

from railsim.errors import ConfigError
from railsim.inputs import excerpt
from railsim.timetable.feed_tables import FeedZip, Table, coordinate, gtfs_date, gtfs_time, non_negative_int

RAIL_ROUTE_TYPES = frozenset({0, 1, 2, 12} | set(range(100, 200)) | set(range(400, 500)) | set(range(900, 1000)))
REQUIRED_TABLES = ("routes.txt", "trips.txt", "stop_times.txt", "stops.txt")
DAY_NAMES = ("monday", "tuesday", "wednesday", "thursday", "friday", "saturday", "sunday")


@dataclass(frozen=True)
class StopTime:
    """One call of a trip: GTFS stop, arrival and departure [s after midnight of the service date]."""

    stop_id: str
    arrival_s: float
    departure_s: float


@dataclass(frozen=True)
class Trip:
    """A rail trip of the day: its route (id, short name, GTFS type), direction, block and calls in order."""

    trip_id: str
    route_id: str
    route_name: str
    route_type: int
    direction: str
    block_id: str
    calls: tuple[StopTime, ...]

    @property
    def departure_s(self) -> float:
        return self.calls[0].departure_s

    @property
    def arrival_s(self) -> float:
        return self.calls[-1].arrival_s


@dataclass(frozen=True)
class GtfsStop:
    """A GTFS stop: id, name (its parent station's name when it has one), lon/lat (NaN if absent)."""

    stop_id: str
    name: str
    lon: float
    lat: float


@dataclass
class Feed:
    """The rail part of a feed on one date: trips in the window, their stops, and counts for the report."""

    trips: list[Trip]
    stops: dict[str, GtfsStop]
    rail_routes: int = 0
    expanded_from_frequencies: int = 0
    outside_window: int = 0


def _clock(t_s: float) -> str:
    t = int(round(t_s))
    return f"{t // 3600:02d}:{t % 3600 // 60:02d}:{t % 60:02d}"


def _unique(path: Path, table: Table, col: str) -> None:
    """Refuse a key ``col`` that appears twice in ``table``."""
    seen: dict[str, int] = {}
    for row, line in zip(table.rows, table.lines):
        _once(path, f"{table.name}.{col}", seen, row[col], line)


def _once(path: Path, field: str, seen: dict[str, int], key: str, line: int) -> None:
    """Refuse ``key`` if ``seen`` has it (the line of each key so far); else note it."""
    if key in seen:
        raise ConfigError(path, field, f"expected unique ids, got {excerpt(key)} in lines {seen[key]} and {line}")
    seen[key] = line


def _services_on(path: Path, zf: FeedZip, wanted: set[str], day: Date) -> tuple[set[str], str]:
    """The services of ``wanted`` running on ``day``, and the span of dates the feed names (for a message)."""
    cal = zf.table("calendar.txt", ("service_id", *DAY_NAMES, "start_date", "end_date"))
    dates = zf.table("calendar_dates.txt", ("service_id", "date", "exception_type"))
    _unique(path, cal, "service_id")
    on: set[str] = set()
    span: list[Date] = []
    for row, line in zip(cal.rows, cal.lines):
        if row["service_id"] not in wanted:
            continue
        where = f"line {line}"
        start = gtfs_date(path, "calendar.txt.start_date", row["start_date"], where)
        end = gtfs_date(path, "calendar.txt.end_date", row["end_date"], where)
        if end < start:
            raise ConfigError(path, "calendar.txt.end_date", f"expected a date on or after start_date ({where})")
        for name in DAY_NAMES:
            if row[name] not in ("0", "1"):
                raise ConfigError(path, f"calendar.txt.{name}", f"expected 0 or 1, got {excerpt(row[name])} ({where})")
        span += [start, end]
        if start <= day <= end and row[DAY_NAMES[day.weekday()]] == "1":
            on.add(row["service_id"])
    removed: set[str] = set()
    for row, line in zip(dates.rows, dates.lines):
        if row["service_id"] not in wanted:
            continue
        when = gtfs_date(path, "calendar_dates.txt.date", row["date"], f"line {line}")
        kind = row["exception_type"]
        if kind not in ("1", "2"):
            raise ConfigError(
                path, "calendar_dates.txt.exception_type", f"expected 1 or 2, got {excerpt(kind)} (line {line})"
            )
        span.append(when)
        if when == day:
            (on if kind == "1" else removed).add(row["service_id"])
    return on - removed, f"{min(span)} to {max(span)}" if span else "no dates at all"


def _rail_routes(path: Path, table: Table) -> dict[str, tuple[str, int]]:
    """``{route_id: (short name or id, route_type)}`` of the rail routes."""
    _unique(path, table, "route_id")
    rail: dict[str, tuple[str, int]] = {}
    for row, line in zip(table.rows, table.lines):
        rtype = non_negative_int(path, "routes.txt.route_type", row["route_type"], f"line {line}")
        if rtype in RAIL_ROUTE_TYPES:
            rail[row["route_id"]] = (row.get("route_short_name", "") or row["route_id"], rtype)
    return rail


def _calls(path: Path, zf: FeedZip, trips: set[str]) -> dict[str, list[StopTime]]:
    """The calls of ``trips`` in stop_sequence order, times filled and checked (module docstring). The table is
    read row by row and only the rows of ``trips`` are kept and parsed."""
    stop_times = zf.rows("stop_times.txt", ("trip_id", "stop_id", "stop_sequence"))
    if not {"arrival_time", "departure_time"} & set(stop_times.columns):
        raise ConfigError(path, "stop_times.txt.arrival_time", "expected arrival_time or departure_time columns")
    table = stop_times.collect("trip_id", trips)
    rows: dict[str, list[tuple[int, str, StopTime]]] = {}
    for row, where in table.rows_of_trips(trips):
        seq = non_negative_int(path, "stop_times.txt.stop_sequence", row["stop_sequence"], where)
        a = gtfs_time(path, "stop_times.txt.arrival_time", row.get("arrival_time", ""), where)
        d = gtfs_time(path, "stop_times.txt.departure_time", row.get("departure_time", ""), where)
        a = d if math.isnan(a) else a
        d = a if math.isnan(d) else d
        rows.setdefault(row["trip_id"], []).append((seq, where, StopTime(row["stop_id"], a, d)))
    calls: dict[str, list[StopTime]] = {}
    for tid, seq_calls in rows.items():
        seq_calls.sort(key=lambda x: x[0])
        for (s0, _, _), (s1, where, _) in zip(seq_calls, seq_calls[1:]):
            if s0 == s1:
                raise ConfigError(
                    path, "stop_times.txt.stop_sequence", f"expected each value once per trip, got {s0} again ({where})"
                )
        out = [c for _, _, c in seq_calls]
        if len(out) < 2:
            continue
        if math.isnan(out[0].departure_s) or math.isnan(out[-1].arrival_s):
            raise ConfigError(
                path,
                "stop_times.txt.arrival_time",
                f"expected times at the first and last call of a trip (trip {excerpt(tid)})",
            )
        out = _interpolate(out)
        last = -math.inf
        for (_, where, _), c in zip(seq_calls, out):
            if not last <= c.arrival_s <= c.departure_s:
                raise ConfigError(
                    path,
                    "stop_times.txt.arrival_time",
                    f"expected times that never run backwards along a trip, got arrival {_clock(c.arrival_s)} "
                    f"and departure {_clock(c.departure_s)} after {_clock(max(last, 0.0))} "
                    f"({where})",
                )
            last = c.departure_s
        calls[tid] = out
    return calls


def _trips(path: Path, zf: FeedZip, route_ids: set[str], rail: set[str]) -> tuple[list[dict[str, str]], set[str]]:
    """The rows of trips.txt on a route of ``rail``, and the service ids of all trips; every ``trip_id`` once and
    every ``route_id`` one of ``route_ids``. Read row by row: only the rail trips are kept."""
    trips = zf.rows("trips.txt", ("route_id", "service_id", "trip_id"))
    kt, kr, ks = trips.index("trip_id"), trips.index("route_id"), trips.index("service_id")
    seen: dict[str, int] = {}
    services: set[str] = set()
    out: list[dict[str, str]] = []
    for fields, line in trips:
        route = fields[kr].strip()
        _once(path, "trips.txt.trip_id", seen, fields[kt].strip(), line)
        if route not in route_ids:
            raise ConfigError(
                path, "trips.txt.route_id", f"expected a route of routes.txt, got {excerpt(route)} (line {line})"
            )
        services.add(fields[ks].strip())
        if route in rail:
            out.append(trips.record(fields))
    return out, services


def _frequencies(path: Path, zf: FeedZip, trips: set[str]) -> dict[str, list[tuple[int, int, int]]]:
    """``{template trip: [(start, end, headway) s, ...]}`` for ``trips``, checked (module docstring)."""
    table = zf.table("frequencies.txt", ("trip_id", "start_time", "end_time", "headway_secs"))
    out: dict[str, list[tuple[int, int, int]]] = {}
    for row, where in table.rows_of_trips(trips):
        start = gtfs_time(path, "frequencies.txt.start_time", row["start_time"], where)
        end = gtfs_time(path, "frequencies.txt.end_time", row["end_time"], where)
        headway = non_negative_int(path, "frequencies.txt.headway_secs", row["headway_secs"], where)
        if math.isnan(start) or math.isnan(end) or not end > start:
            raise ConfigError(path, "frequencies.txt.end_time", f"expected a time after start_time ({where})")
        if headway <= 0:
            raise ConfigError(path, "frequencies.txt.headway_secs", f"expected a whole number > 0, got 0 ({where})")
        out.setdefault(row["trip_id"], []).append((int(start), int(end), headway))
    for tid, periods in out.items():
        periods.sort()
        for (_, end0, _), (start1, _, _) in zip(periods, periods[1:]):
            if start1 < end0:
                raise ConfigError(
                    path,
                    "frequencies.txt.start_time",
                    f"expected periods of a trip that do not overlap, got one starting at {_clock(start1)} before "
                    f"{_clock(end0)} (trip {excerpt(tid)})",
                )
    return out


def _stops(path: Path, table: Table, used: set[str], calls_of: dict[str, str]) -> dict[str, GtfsStop]:
    """The stops in ``used`` (each must exist), named by their parent station when they have one."""
    _unique(path, table, "stop_id")
    by_id = {row["stop_id"]: (row, line) for row, line in zip(table.rows, table.lines)}
    missing = sorted(used - set(by_id))
    if missing:
        raise ConfigError(
            path,
            "stop_times.txt.stop_id",
            f"expected a stop of stops.txt, got {excerpt(missing[0])} (trip {excerpt(calls_of[missing[0]])})",
        )
    out: dict[str, GtfsStop] = {}
    for sid in sorted(used):
        row, line = by_id[sid]
        parent = by_id.get(row.get("parent_station", ""))
        name = (parent[0].get("stop_name", "") if parent else "") or row.get("stop_name", "") or sid
        where = f"stop {excerpt(sid)}, line {line}"
        lon = coordinate(path, "stops.txt.stop_lon", row.get("stop_lon", ""), 180.0, where)
        lat = coordinate(path, "stops.txt.stop_lat", row.get("stop_lat", ""), 90.0, where)
        out[sid] = GtfsStop(sid, name, lon, lat)
    return out


def read_trips(
    feed_path: str | Path,
    day: Date,
    from_s: float,
    to_s: float,
    routes: Sequence[str] | None = None,
) -> Feed:
    """The rail trips of ``day`` leaving their first stop in ``[from_s, to_s)`` (module docstring)."""
    path = Path(feed_path)
    zf = FeedZip(path)
    missing = [t for t in REQUIRED_TABLES if not zf.has(t)]
    if missing:
        raise ConfigError(
            path, missing[0], f"expected the GTFS table {missing[0]} in the feed, got {sorted(zf.members)}"
        )
    if not zf.has("calendar.txt") and not zf.has("calendar_dates.txt"):
        raise ConfigError(path, "calendar.txt", "expected calendar.txt or calendar_dates.txt in the feed")
    route_table = zf.table("routes.txt", ("route_id", "route_type"), present=True)
    route_ids = {row["route_id"] for row in route_table.rows}
    rail = _rail_routes(path, route_table)
    if not rail:
        raise ConfigError(
            path,
            "routes.txt.route_type",
            "expected at least one rail route (types 0, 1, 2, 12, 100-199, 400-499, 900-999), got none",
        )
    if routes:
        wanted = {r.strip() for r in routes}
        rail = {rid: v for rid, v in rail.items() if rid in wanted or v[0] in wanted}
        if not rail:
            raise ConfigError(
                "<command line>",
                "--routes",
                f"expected rail route ids or short names of the feed, got {sorted(wanted)}",
            )
    rail_trips, service_ids = _trips(path, zf, route_ids, set(rail))
    services, span = _services_on(path, zf, service_ids, day)
    if not services:
        raise ConfigError(path, "--date", f"expected a date the feed runs on ({span}), got {day.isoformat()}")
    trip_rows = [r for r in rail_trips if r["service_id"] in services]
    kept = {r["trip_id"] for r in trip_rows}
    calls = _calls(path, zf, kept)
    templates = _frequencies(path, zf, kept)
    result = Feed(trips=[], stops={}, rail_routes=len(rail))
    for row in trip_rows:
        tid = row["trip_id"]
        seq = calls.get(tid)
        if seq is None:
            continue
        route_name, rtype = rail[row["route_id"]]
        base = Trip(
            tid, row["route_id"], route_name, rtype, row.get("direction_id", ""), row.get("block_id", ""), tuple(seq)
        )
        if tid not in templates:
            result.trips.append(base)
            continue
        for start, end, headway in templates[tid]:
            times = range(start, end, headway)
            first = max(0, math.ceil((from_s - start) / headway))
            inside = [t for t in times[first:] if t < to_s]
            result.outside_window += len(times) - len(inside)
            for t in inside:
                shift = t - seq[0].departure_s
                shifted = tuple(StopTime(c.stop_id, c.arrival_s + shift, c.departure_s + shift) for c in seq)
                result.trips.append(replace(base, trip_id=f"{tid}@{_clock(t)}", calls=shifted))
                result.expanded_from_frequencies += 1
    in_window = [t for t in result.trips if from_s <= t.departure_s < to_s]
    result.outside_window += len(result.trips) - len(in_window)
    result.trips = sorted(in_window, key=lambda t: (t.departure_s, t.trip_id))
    calls_of = {c.stop_id: t.trip_id for t in result.trips for c in t.calls}
    result.stops = _stops(path, zf.table("stops.txt", ("stop_id",), present=True), set(calls_of), calls_of)
    return result


def _interpolate(calls: list[StopTime]) -> list[StopTime]:
    """Fill calls without times (GTFS allows them between timepoints) linearly by position in the sequence."""
    known = [k for k, c in enumerate(calls) if not math.isnan(c.departure_s)]
    if len(known) == len(calls) or len(known) < 2:
        return calls
    out = list(calls)
    for a, b in zip(known, known[1:]):
        for k in range(a + 1, b):
            t = calls[a].departure_s + (calls[b].arrival_s - calls[a].departure_s) * (k - a) / (b - a)
            out[k] = StopTime(calls[k].stop_id, t, t)
    return out
