"""Reading a GTFS feed into the rail trips of one day and one time window.

The feed is read with **partridge** (https://github.com/remix/partridge): it resolves which ``service_id``s run
on a date from ``calendar.txt`` and ``calendar_dates.txt`` together (the fiddly part of GTFS), reads only the
trips of those services, and parses GTFS times (past 24:00 too) into seconds after midnight. gtfs-kit was the
other candidate: it pulls in geopandas, shapely, rtree and folium, none of which a timetable needs.

What :func:`read_trips` keeps:

* **Rail routes** (:data:`RAIL_ROUTE_TYPES`): GTFS ``route_type`` 0 tram, 1 subway/metro, 2 rail, 12 monorail,
  and the extended types 100-199 (railway services), 400-499 (urban railway), 900-999 (tram). ``--routes``
  narrows further (route ids or short names).
* **Trips running on the date**, with their stop times. A trip listed in ``frequencies.txt`` is a template:
  it is **expanded** into one trip every ``headway_secs`` from ``start_time`` up to (not including)
  ``end_time`` (GTFS reference), each a copy of the template's stop times shifted so it leaves its first stop
  at that time; the copies are named ``<trip_id>@HH:MM:SS``. ``exact_times`` makes no difference here (a
  simulation schedules what the feed gives either way).
* **The window**: trips whose first departure lies in ``[from, to)``.

Every trip carries its ``block_id`` when the feed has one (a vehicle's chain of trips, used as an explicit
rotation by :mod:`railsim.timetable.rotations`). A feed that is not a zip of GTFS tables, lacks a required table
or column, has no service on the date or no rail route gives a :class:`~railsim.errors.ConfigError` (one line,
exit 2).
"""

from __future__ import annotations

import logging
import math
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, replace
from datetime import date as Date
from pathlib import Path
from typing import Any

from railsim.errors import ConfigError

log = logging.getLogger(__name__)

RAIL_ROUTE_TYPES = frozenset({0, 1, 2, 12} | set(range(100, 200)) | set(range(400, 500)) | set(range(900, 1000)))
REQUIRED_TABLES = ("routes.txt", "trips.txt", "stop_times.txt", "stops.txt")


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


def _num(value: Any, default: float = math.nan) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        return default
    return out


def _clock(t_s: float) -> str:
    t = int(round(t_s))
    return f"{t // 3600:02d}:{t % 3600 // 60:02d}:{t % 60:02d}"


def _open(feed: Path) -> None:
    """Refuse what is not a readable GTFS zip with the tables we need (one line each)."""
    if not feed.is_file():
        raise ConfigError(feed, None, "expected an existing GTFS feed (.zip)")
    try:
        with zipfile.ZipFile(feed) as zf:
            names = {Path(n).name for n in zf.namelist()}
    except zipfile.BadZipFile:
        raise ConfigError(
            feed, None, "expected a GTFS feed (a .zip of .txt tables), got a file that is not a zip"
        ) from None
    missing = [t for t in REQUIRED_TABLES if t not in names]
    if missing:
        raise ConfigError(feed, missing[0], f"expected the GTFS table {missing[0]} in the feed, got {sorted(names)}")
    if "calendar.txt" not in names and "calendar_dates.txt" not in names:
        raise ConfigError(feed, "calendar.txt", "expected calendar.txt or calendar_dates.txt in the feed")


def read_trips(
    feed_path: str | Path,
    day: Date,
    from_s: float,
    to_s: float,
    routes: Sequence[str] | None = None,
) -> Feed:
    """The rail trips of ``day`` leaving their first stop in ``[from_s, to_s)`` (module docstring)."""
    import partridge as ptg

    path = Path(feed_path)
    _open(path)
    try:
        by_date = ptg.read_service_ids_by_date(str(path))
    except Exception as exc:  # noqa: BLE001 - partridge raises KeyError/ValueError/pandas errors on bad tables
        raise ConfigError(path, "calendar.txt", f"expected a readable service calendar, got an error: {exc}") from None
    services = by_date.get(day)
    if not services:
        span = f"{min(by_date)} to {max(by_date)}" if by_date else "no dates at all"
        raise ConfigError(path, "--date", f"expected a date the feed runs on ({span}), got {day.isoformat()}")
    try:
        feed = ptg.load_feed(str(path), view={"trips.txt": {"service_id": sorted(services)}})
        route_df = feed.routes
        trip_df = feed.trips
        st_df = feed.stop_times
        stop_df = feed.stops
        freq_df = feed.frequencies
    except Exception as exc:  # noqa: BLE001
        raise ConfigError(path, None, f"expected well-formed GTFS tables, got an error: {exc}") from None
    for table, df, cols in (
        ("routes.txt", route_df, ("route_id", "route_type")),
        ("trips.txt", trip_df, ("route_id", "trip_id")),
        ("stop_times.txt", st_df, ("trip_id", "stop_id", "stop_sequence")),
        ("stops.txt", stop_df, ("stop_id",)),
    ):
        for col in cols:
            if col not in df.columns:
                raise ConfigError(path, f"{table}.{col}", "expected this column, got a table without it")
    rail: dict[str, tuple[str, int]] = {}
    for row in route_df.itertuples(index=False):
        rtype = int(_num(row.route_type, -1))
        if rtype not in RAIL_ROUTE_TYPES:
            continue
        short = str(getattr(row, "route_short_name", "") or "").strip()
        name = short if short and short != "nan" else str(row.route_id)
        rail[str(row.route_id)] = (name, rtype)
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
    trip_df = trip_df[trip_df["route_id"].astype(str).isin(rail)]
    st_df = st_df[st_df["trip_id"].isin(set(trip_df["trip_id"]))].sort_values(["trip_id", "stop_sequence"])
    calls: dict[str, list[StopTime]] = {}
    for trip_id, grp in st_df.groupby("trip_id", sort=False):
        arr = grp["arrival_time"].to_numpy(dtype=float) if "arrival_time" in grp else None
        dep = grp["departure_time"].to_numpy(dtype=float) if "departure_time" in grp else None
        out = []
        for k, stop_id in enumerate(grp["stop_id"].astype(str)):
            a = arr[k] if arr is not None else math.nan
            d = dep[k] if dep is not None else math.nan
            a = d if math.isnan(a) else a
            d = a if math.isnan(d) else d
            out.append(StopTime(stop_id, a, d))
        calls[str(trip_id)] = _interpolate(out)
    templates: dict[str, list[tuple[float, float, float]]] = {}
    if freq_df is not None and len(freq_df):
        for row in freq_df.itertuples(index=False):
            start, end, headway = (_num(getattr(row, c)) for c in ("start_time", "end_time", "headway_secs"))
            if not (headway > 0 and end > start):
                raise ConfigError(
                    path,
                    "frequencies.txt",
                    f"expected start_time < end_time and headway_secs > 0 for trip {row.trip_id}",
                )
            templates.setdefault(str(row.trip_id), []).append((start, end, headway))
    result = Feed(trips=[], stops={}, rail_routes=len(rail))
    for row in trip_df.itertuples(index=False):
        tid = str(row.trip_id)
        seq = calls.get(tid)
        if not seq or len(seq) < 2 or math.isnan(seq[0].departure_s):
            continue
        route_name, rtype = rail[str(row.route_id)]
        block = getattr(row, "block_id", "")
        block = "" if block is None or str(block) in ("", "nan") else str(block)
        direction = getattr(row, "direction_id", "")
        direction = "" if direction is None or str(direction) in ("", "nan") else str(direction).removesuffix(".0")
        base = Trip(tid, str(row.route_id), route_name, rtype, direction, block, tuple(seq))
        if tid in templates:
            for start, end, headway in templates[tid]:
                t = start
                while t < end - 1e-9:
                    shift = t - seq[0].departure_s
                    shifted = tuple(StopTime(c.stop_id, c.arrival_s + shift, c.departure_s + shift) for c in seq)
                    result.trips.append(replace(base, trip_id=f"{tid}@{_clock(t)}", calls=shifted))
                    result.expanded_from_frequencies += 1
                    t += headway
        else:
            result.trips.append(base)
    kept = [t for t in result.trips if from_s <= t.departure_s < to_s]
    result.outside_window = len(result.trips) - len(kept)
    result.trips = sorted(kept, key=lambda t: (t.departure_s, t.trip_id))
    used = {c.stop_id for t in result.trips for c in t.calls}
    parent_names = {}
    if "parent_station" in stop_df.columns:
        names = dict(zip(stop_df["stop_id"].astype(str), stop_df.get("stop_name", stop_df["stop_id"]).astype(str)))
        for sid, parent in zip(stop_df["stop_id"].astype(str), stop_df["parent_station"].astype(str)):
            if parent and parent != "nan" and parent in names:
                parent_names[sid] = names[parent]
    for row in stop_df.itertuples(index=False):
        sid = str(row.stop_id)
        if sid not in used:
            continue
        name = parent_names.get(sid) or str(getattr(row, "stop_name", "") or sid)
        result.stops[sid] = GtfsStop(
            sid, name, _num(getattr(row, "stop_lon", None)), _num(getattr(row, "stop_lat", None))
        )
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
