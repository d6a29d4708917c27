"""Line sections: what each train did between two consecutive stations, read back from a finished run.

A **line section** here is the track between two consecutive stations a train serves, in one direction of
travel (``up`` = increasing line km, ``down``). It is named by its ends, e.g. ``liugongli → chongqing-university-
of-technology-and-business (up)``. Two services that serve the same two stations one after the other share the
section (the Airport and Jurenba units between Liugongli and Bijin); after a fork they run on different
sections (``bijin → jiangbei-airport-t2`` vs ``bijin → shuangfengqiao``).

:func:`section_table` gives one row per (trip, section) the trip ran, from the recorder's tables:

==================  ====================================================================================
``departure_s``     when the train left ``from_station``: the stop's departure in ``stops.csv``, at the origin
                    the trip's departure in ``trips.csv`` (simulation seconds since t = 0)
``arrival_s``       when it halted at ``to_station`` (``stops.csv`` arrival)
``running_time_s``  ``arrival_s − departure_s``
``length_m``        route metres between the two stopping marks (the train front at each halt)
``from_km/to_km``   line km of the two stations (platform centres: the world's design chainage; on a user's
                    net the chainage :func:`network.chainage.line_chainage` gives it)
``headway_s``       ``departure_s`` minus the departure of the train that left the same section (same two
                    stations, same direction) just before; NaN for the first train on that section
``formation``       the formation id when the trip ran this section inside a virtually coupled formation
                    (leader or follower), else ``""``; ``formation_role`` is ``leader``/``follower``/``""``
==================  ====================================================================================

Readings:

* Only sections a train **completed** are listed (it departed ``from_station`` and halted at ``to_station``);
  a missed stop is not a station served, so the section runs on to the next served station.
* A coupled **follower cannot leave before its leader**: a follower inserted behind its dwelling leader is
  "departed" by the engine at insertion but moves off with the leader, so its departure is taken as the later
  of its own and its leader's departure from that station (otherwise its first running time would include
  the leader's remaining dwell).
* "Ran the section inside a formation" = the formation was ``coupled`` at some moment of the follower's run
  (``coupled`` … ``decouple_requested``/``decoupled`` in ``events.csv``) and its leader ran the same section.

:class:`LineFrame` holds what the run's world says about positions: each service's route, its stations' line
km and the map route chainage (trace ``chainage_m``) → line km, linear between the stations' platform centres.
Other analyses (capacity, time-distance plots) use it to put every train on one distance axis.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from railsim.errors import ConfigError
from railsim.record import run_folder

SECTION_COLUMNS = [
    "trip_id",
    "service",
    "direction",
    "from_station",
    "to_station",
    "from_km",
    "to_km",
    "departure_s",
    "arrival_s",
    "running_time_s",
    "length_m",
    "headway_s",
    "formation",
    "formation_role",
]


# --------------------------------------------------------------------------------------------------------------
# Reading a run folder
# --------------------------------------------------------------------------------------------------------------


def require_run_dir(run_dir: str | Path) -> Path:
    """``run_dir`` as a Path; ConfigError if it is not a folder."""
    run = Path(run_dir)
    if not run.is_dir():
        raise ConfigError(run, None, "expected a run folder (written by railsim run), found no such folder")
    return run


def read_table(run_dir: str | Path, stem: str) -> pd.DataFrame:
    """A recorder table (``trips``, ``stops``, ``events``, ``trace``, ``formations``) of a run folder.

    Parquet is preferred when the run wrote it (exact dtypes), else CSV. A missing or unreadable table is a
    :class:`ConfigError` naming the file.
    """
    run = require_run_dir(run_dir)
    pq, csv = run / f"{stem}.parquet", run / f"{stem}.csv"
    own_pq, own_csv = run_folder.member(run, pq.name), run_folder.member(run, csv.name)  # the manifest's files only
    try:
        if own_pq is not None:
            return pd.read_parquet(pq)
        if own_csv is not None:
            return pd.read_csv(csv, keep_default_na=True)
    except Exception as exc:  # pandas raises many kinds for a corrupt file
        raise ConfigError(pq if pq.exists() else csv, None, f"cannot read the table: {exc}") from None
    if pq.exists() or csv.exists():
        raise ConfigError(run, stem, f"{stem} is not a file of the run its manifest describes (an earlier run's?)")
    raise ConfigError(run, stem, f"expected {stem}.csv or {stem}.parquet in the run folder, found neither")


def read_summary(run_dir: str | Path) -> dict[str, Any]:
    """``summary.json`` of a run folder (ConfigError if missing or not JSON)."""
    path = Path(run_dir) / "summary.json"
    if path.is_file() and run_folder.member(run_dir, "summary.json") is None:
        raise ConfigError(path, None, "not the summary of the run its manifest describes (an earlier run's?)")
    try:
        return dict(json.loads(path.read_text(encoding="utf-8")))
    except FileNotFoundError:
        raise ConfigError(path, None, "expected the run's summary.json, found no such file") from None
    except ValueError as exc:
        raise ConfigError(path, None, f"not valid JSON: {exc}") from None


def coupled_intervals(events: pd.DataFrame) -> dict[str, list[tuple[float, float]]]:
    """Per formation, the ``[coupled, decouple)`` time intervals from the event log (open at the end: +inf)."""
    out: dict[str, list[tuple[float, float]]] = {}
    start: dict[str, float] = {}
    ev = events[events["kind"].isin(("coupled", "decouple_requested", "decoupled"))]
    for t, kind, subject in zip(ev["t_s"].astype(float), ev["kind"], ev["subject"].astype(str)):
        if kind == "coupled":
            start.setdefault(subject, t)
        elif subject in start:
            out.setdefault(subject, []).append((start.pop(subject), t))
    for subject, t0 in start.items():
        out.setdefault(subject, []).append((t0, math.inf))
    return out


# --------------------------------------------------------------------------------------------------------------
# The run's world: routes, stations, line km
# --------------------------------------------------------------------------------------------------------------


@dataclass
class ServiceFrame:
    """One service's route in line terms: the stations in route order with route chainage and line km."""

    service: str
    direction: str  # 'up' | 'down' (by the line km of its two ends)
    route: Any  # network.RouteInfo
    stations: list[str]
    mark_m: dict[str, float]  # route chainage of the stopping mark (front of a halted train)
    km: dict[str, float]  # line km of the platform centre
    _x: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)  # platform centres, route chainage
    _km: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)

    def km_of(self, chainage_m: Any) -> Any:
        """Line km of route chainage ``chainage_m`` (array or scalar): linear between platform centres and
        at 1 km per 1000 m beyond the end stations."""
        x = np.asarray(chainage_m, dtype=float)
        if len(self._x) < 2:
            sign = 1.0 if self.direction == "up" else -1.0
            return self._km[0] + sign * (x - self._x[0]) / 1000.0
        k = np.interp(x, self._x, self._km)
        lo = x < self._x[0]
        hi = x > self._x[-1]
        slope0 = np.sign(self._km[1] - self._km[0]) / 1000.0
        slope1 = np.sign(self._km[-1] - self._km[-2]) / 1000.0
        k = np.where(lo, self._km[0] + slope0 * (x - self._x[0]), k)
        k = np.where(hi, self._km[-1] + slope1 * (x - self._x[-1]), k)
        return k if k.ndim else float(k)


@dataclass
class LineFrame:
    """A finished run's scenario and world, with a :class:`ServiceFrame` per service."""

    run_dir: Path
    scenario: Any  # railsim.scenario.Scenario
    bundle: Any  # network.NetworkBundle
    services: dict[str, ServiceFrame]
    _trace_by_train: dict[str, pd.DataFrame] | None = field(default=None, repr=False, compare=False)

    def trace_by_train(self) -> dict[str, pd.DataFrame]:
        """The run's trace, one time-ordered frame per train; read once per LineFrame (the trace is the
        largest table of a run and several analyses need it)."""
        if self._trace_by_train is None:
            trace = read_table(self.run_dir, "trace").sort_values(["train", "t_s"], kind="mergesort")
            self._trace_by_train = {str(tid): g for tid, g in trace.groupby("train", sort=False)}
        return self._trace_by_train

    @classmethod
    def from_run(cls, run_dir: str | Path) -> LineFrame:
        """Rebuild the world of ``run_dir`` from its ``scenario.resolved.yaml`` (the network cache makes this a
        file read when the world was built before)."""
        import network
        from railsim import scenario as scenario_mod

        run = require_run_dir(run_dir)
        resolved = run / "scenario.resolved.yaml"
        if not resolved.exists():
            raise ConfigError(
                run, None, "expected scenario.resolved.yaml in the run folder (written by railsim run), found none"
            )
        scn = scenario_mod.load(resolved)
        if scn.world.kind == "net":  # a user's net: line chainage from its routes (network.chainage.line_chainage)
            from network.world import load_world

            bundle = load_world(scn.world, resolved)
            scn = scenario_mod.with_station_ids(scn, bundle)
            _require_chainage(scn, bundle, resolved)
        else:
            name_or_path, params = scn.world.build_args()
            bundle = network.build(name_or_path, **params)
        frames = {svc.id: _service_frame(svc, bundle) for svc in scn.services}
        return cls(run, scn, bundle, frames)

    def capacity_pax(self, service: str) -> int:
        """Passenger capacity of one unit of ``service`` (its vehicle's ``capacity_pax``)."""
        return int(self.scenario.vehicle_of(service).capacity_pax)

    def length_m(self, service: str) -> float:
        """Train length of ``service``'s vehicle [m]."""
        return float(self.scenario.vehicle_of(service).length_m)


def _require_chainage(scn: Any, bundle: Any, source: Path) -> None:
    """A user's net gets line km only up to ``network.external.MAX_LISTED_STATIONS`` stations."""
    from network.external import MAX_LISTED_STATIONS

    for i, svc in enumerate(scn.services):
        for sid in (svc.from_station, svc.to_station):
            if not bundle.stations[sid].line:
                raise ConfigError(
                    source,
                    f"services[{i}]",
                    f"station {sid!r} has no line km: {bundle.name} has {len(bundle.stations)} stations, line "
                    f"chainage is computed for nets with up to {MAX_LISTED_STATIONS}",
                )


def _service_frame(svc: Any, bundle: Any) -> ServiceFrame:
    route = bundle.route_between(svc.from_station, svc.to_station, tuple(svc.via), svc.platforms)
    stations: list[str] = []
    mark: dict[str, float] = {}
    centre: dict[str, float] = {}
    km: dict[str, float] = {}
    started = False
    for rs in route.stops:
        started = started or rs.station_id == svc.from_station
        if not started:
            continue
        stations.append(rs.station_id)
        mark[rs.station_id] = float(rs.end_m) - 1.0  # railsim.engine.trips.STOP_MARK_BEFORE_END_M
        centre[rs.station_id] = 0.5 * (float(rs.start_m) + float(rs.end_m))
        km[rs.station_id] = float(bundle.stations[rs.station_id].km)
        if rs.station_id == svc.to_station:
            break
    direction = "up" if km[svc.to_station] > km[svc.from_station] else "down"
    frame = ServiceFrame(svc.id, direction, route, stations, mark, km)
    frame._x = np.array([centre[s] for s in stations])
    frame._km = np.array([km[s] for s in stations])
    return frame


# --------------------------------------------------------------------------------------------------------------
# The section table
# --------------------------------------------------------------------------------------------------------------


def section_table(run_dir: str | Path, frame: LineFrame | None = None) -> pd.DataFrame:
    """One row per (trip, section) a trip completed; columns :data:`SECTION_COLUMNS` (see module docstring).

    Rows are sorted by direction, section (in line order) and departure.
    """
    frame = frame or LineFrame.from_run(run_dir)
    trips = read_table(run_dir, "trips")
    stops = read_table(run_dir, "stops")
    events = read_table(run_dir, "events")

    # served stations of every trip, in route order: (station, arrival_s, departure_s)
    served: dict[str, list[tuple[str, float, float]]] = {}
    stops = stops[~stops["missed"].astype(str).str.lower().isin(("true", "1"))]
    by_trip = {tid: grp for tid, grp in stops.groupby("trip_id", sort=False)}
    service_of: dict[str, str] = {}
    for row in trips.itertuples(index=False):
        tid, svc = str(row.trip_id), str(row.service)
        service_of[tid] = svc
        if svc not in frame.services or pd.isna(row.departure_s):
            continue
        sf = frame.services[svc]
        seq = [(str(row.origin), math.nan, float(row.departure_s))]
        grp = by_trip.get(tid)
        if grp is not None:
            order = {s: i for i, s in enumerate(sf.stations)}
            for st, arr, dep in sorted(
                zip(grp["station"].astype(str), grp["arrival_s"].astype(float), grp["departure_s"].astype(float)),
                key=lambda r: order.get(r[0], 1e9),
            ):
                # a unit's next trip records its origin stop too (it reached the platform after its reversal)
                if st in order and not math.isnan(arr) and st != seq[0][0]:
                    seq.append((st, arr, dep))
        served[tid] = seq

    # formation membership per section run: leader id -> (formation, follower), coupled intervals
    form_rows = read_table(run_dir, "formations")
    intervals = coupled_intervals(events)
    rows: list[dict[str, Any]] = []
    for tid, seq in served.items():
        svc = service_of[tid]
        sf = frame.services[svc]
        for (a, _, dep), (b, arr, _) in zip(seq, seq[1:]):
            if math.isnan(dep):
                break  # the train never left a (served) station: nothing after it was run
            rows.append(
                {
                    "trip_id": tid,
                    "service": svc,
                    "direction": sf.direction,
                    "from_station": a,
                    "to_station": b,
                    "from_km": sf.km[a],
                    "to_km": sf.km[b],
                    "departure_s": dep,
                    "arrival_s": arr,
                    "length_m": sf.mark_m[b] - sf.mark_m[a],
                    "formation": "",
                    "formation_role": "",
                }
            )
    table = pd.DataFrame(rows, columns=[c for c in SECTION_COLUMNS if c not in ("running_time_s", "headway_s")])

    key = ["direction", "from_station", "to_station"]
    index = {(r["trip_id"], r["from_station"], r["to_station"]): i for i, r in enumerate(rows)}
    for f in form_rows.itertuples(index=False):
        fid, lead, fol = str(f.formation), str(f.leader), str(f.follower)
        spans = intervals.get(fid, [])
        if not spans:
            continue
        for (trip, a, b), i in list(index.items()):
            if trip != fol or (lead, a, b) not in index:
                continue
            j = index[(lead, a, b)]
            t0 = min(table.at[i, "departure_s"], table.at[j, "departure_s"])
            t1 = max(table.at[i, "arrival_s"], table.at[j, "arrival_s"])
            if not any(s < t1 and e > t0 for s, e in spans):
                continue
            table.at[i, "departure_s"] = max(table.at[i, "departure_s"], table.at[j, "departure_s"])
            table.loc[[i, j], "formation"] = fid
            table.at[i, "formation_role"] = "follower"
            table.at[j, "formation_role"] = "leader"

    table["running_time_s"] = table["arrival_s"] - table["departure_s"]
    order_km = table["from_km"].where(table["direction"] == "up", -table["from_km"])
    follower_last = (table["formation_role"] == "follower").astype(int)  # a leader before its follower
    table = (
        table.assign(_k=order_km, _f=follower_last)
        .sort_values(["direction", "_k", "to_station", "departure_s", "_f", "trip_id"], kind="mergesort")
        .drop(columns=["_k", "_f"])
    )
    table["headway_s"] = table.groupby(key, sort=False)["departure_s"].diff()
    return table.reset_index(drop=True)[SECTION_COLUMNS]
