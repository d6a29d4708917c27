"""An ordinary railsim scenario from imported trips: services, departures, dwell times and rotations.

The scenario schema has **services** (a route from one station to another through ``via`` stations, with a list
of departure times; railsim drives the train and works out the running times itself) and **rotations**
(``units: {unit: [trip ids]}``). :func:`build_scenario` maps an import onto it:

* Each trip becomes the sequence of **world stations** its calls matched (consecutive calls at one station
  collapse; unmatched calls are left out — a trip running beyond the extract is cut to the part inside it).
  A trip with fewer than two stations is dropped and counted.
* Trips of one line with the same station sequence form one **service**, id ``<line>_<first>_<last>``
  (``from``/``to`` the first and last station, ``via`` every station between, so the route follows the feed);
  its ``departures: {times: [...]}`` are the trips' first departures (clock strings, ``HH:MM:SS``). Two trips
  of a service leaving at the same second are one (the second is dropped and counted).
* **Dwell**: per service, the median GTFS dwell (departure minus arrival) over its intermediate calls, at least
  :data:`MIN_DWELL_S` (feeds often give 0 s dwells).
* **Rotations** (:mod:`railsim.timetable.rotations`): explicit ``units`` (block_id chains, else built),
  ``turnback_min_s``; or ``auto`` (railsim chains units itself at run time) when asked.
* **One rail class per scenario**: the world's stops file of that class is the scenario's additional file and
  its ``vclass``; trips whose stations are of another class are left to a scenario of their own.
* The **vehicle** per class: ``cq3_6car`` (89.4 m metro unit) for metro and rail classes; for ``tram`` the same
  preset cut to 27 m (a 30 m stop leaves it 3 m to stop in), 70 km/h. Edit ``vehicles:`` to taste.

The output is plain YAML with a comment header saying where it came from; nothing in it is special to imports.
"""

from __future__ import annotations

import statistics
from collections import defaultdict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from railsim.timetable.gtfs import Trip
from railsim.timetable.matching import Match
from railsim.timetable.rotations import DEFAULT_TURNBACK_MIN_S, Leg, build_units

MIN_DWELL_S = 20.0
END_MARGIN_S = 1800.0  # simulated time after the last departure's planned arrival (late trains still arrive)
VEHICLES: dict[str, dict[str, Any]] = {
    "metro": {"preset": "cq3_6car"},
    "tram": {"preset": "cq3_6car", "length_m": 27.0, "max_speed_kmh": 70.0},
}

# The moving-block separation margin written for each vehicle: how far behind the last known rear of the train ahead
# a train's braking curve ends. Metro 50 m, Line 3's value. Trams run on sight, close up at platforms and round
# city-centre loops, and slower: 20 m, the interlocking's default overlap (what a train may overrun its stopping
# point by). With 50 m, five trams stood nose to tail round Potsdam's Platz der Einheit loop every 720 s, each too
# close to the next to move (a deadlock); with 20 m the peak runs on (docs/results/2026-11-29-open-data-cities.md).
SEPARATION_MARGIN_M: dict[str, int] = {"metro": 50, "tram": 20}


def vehicle_for(vclass: str) -> str:
    return "tram" if vclass == "tram" else "metro"


@dataclass(frozen=True)
class PlannedTrip:
    """A trip cut to the world: line, station names with their arrival and departure [s], block, source id."""

    line: str
    stations: tuple[str, ...]
    arrivals_s: tuple[float, ...]
    departures_s: tuple[float, ...]
    block: str
    source_id: str

    @property
    def departure_s(self) -> float:
        return self.departures_s[0]

    @property
    def arrival_s(self) -> float:
        return self.arrivals_s[-1]

    @property
    def dwell_s(self) -> tuple[float, ...]:
        return tuple(max(0.0, d - a) for a, d in zip(self.arrivals_s[1:-1], self.departures_s[1:-1]))

    def cut(self, first: int, last: int) -> PlannedTrip:
        """The part from station ``first`` to station ``last`` (inclusive)."""
        sl = slice(first, last + 1)
        return PlannedTrip(
            self.line, self.stations[sl], self.arrivals_s[sl], self.departures_s[sl], self.block, self.source_id
        )


@dataclass
class Built:
    """The scenario (a dict ready for YAML) and what happened on the way (for the report)."""

    scenario: dict[str, Any]
    services: int = 0
    trips: int = 0
    units: int = 0
    units_from_blocks: int = 0
    block_splits: int = 0
    dropped_short: int = 0
    dropped_duplicate: int = 0
    notes: list[str] = field(default_factory=list)


def _slug(text: str) -> str:
    from railsim.timetable.matching import normalise

    return normalise(text).replace(" ", "-") or "x"


def _clock(t_s: float) -> str:
    t = int(round(t_s))
    return f"{t // 3600:02d}:{t % 3600 // 60:02d}:{t % 60:02d}"


def plan_trips(
    trips: Sequence[Trip], matches: Mapping[str, Match], station_class: Mapping[str, str], vclass: str
) -> tuple[list[PlannedTrip], int]:
    """Trips cut to the world stations of ``vclass`` (module docstring); and how many had fewer than 2."""
    out: list[PlannedTrip] = []
    short = 0
    for trip in trips:
        seq: list[tuple[str, float, float]] = []
        for call in trip.calls:
            m = matches.get(call.stop_id)
            if m is None or m.station is None or station_class.get(m.station) != vclass:
                continue
            if seq and seq[-1][0] == m.station:
                seq[-1] = (m.station, seq[-1][1], call.departure_s)
            else:
                seq.append((m.station, call.arrival_s, call.departure_s))
        if len(seq) < 2:
            short += 1
            continue
        out.append(
            PlannedTrip(
                trip.route_name,
                tuple(x[0] for x in seq),
                tuple(x[1] for x in seq),
                tuple(x[2] for x in seq),
                trip.block_id,
                trip.trip_id,
            )
        )
    return out, short


def _revisits(run: Sequence[str]) -> bool:
    """A station twice in one run: the trip reverses there (an OSM line that visits a stub, A-B-A) or loops. A ring
    (first station again at the end, at least four stations, no other repeat) is no revisit."""
    body = list(run[:-1]) if len(run) >= 4 and run[0] == run[-1] else list(run)
    return len(set(body)) != len(body)


def longest_routable(stations: Sequence[str], routable: Callable[[Sequence[str]], bool]) -> tuple[int, int]:
    """``(first, last)`` indices of the longest run of consecutive ``stations`` the world has a route through
    (``routable(chain)``: a route from the first through every station to the last, no reversal) that visits no
    station twice (:func:`_revisits`: a reversal the route search may still find a way around). A feed's line
    may leave the extract and come back, or run over track the OSM data does not connect: the trip is cut to its
    longest part the world can drive rather than refused."""
    best = (0, 0)
    i = 0
    n = len(stations)
    while i < n - 1:
        j = i + 1
        while j < n and not _revisits(stations[i : j + 1]) and routable(stations[i : j + 1]):
            j += 1
        if j - 1 - i > best[1] - best[0]:
            best = (i, j - 1)
        i = j - 1 if j - 1 > i else i + 1
    return best


def cut_to_routable(
    planned: Sequence[PlannedTrip], routable: Callable[[Sequence[str]], bool]
) -> tuple[list[PlannedTrip], list[str]]:
    """Every trip cut to :func:`longest_routable` of its station sequence (computed once per sequence);
    trips left with fewer than two stations are dropped. Returns the trips and one note per cut sequence."""
    cuts: dict[tuple[str, ...], tuple[int, int]] = {}
    notes: list[str] = []
    out: list[PlannedTrip] = []
    for p in planned:
        if p.stations not in cuts:
            first, last = longest_routable(p.stations, routable)
            cuts[p.stations] = (first, last)
            if (first, last) != (0, len(p.stations) - 1):
                kept = f"{p.stations[first]}-{p.stations[last]}" if last > first else "nothing"
                notes.append(
                    f"line {p.line} {p.stations[0]}-{p.stations[-1]}: the world has no route through all its "
                    f"{len(p.stations)} stations; kept {kept} ({last - first + 1 if last > first else 0} stations)"
                )
        first, last = cuts[p.stations]
        if last > first:
            out.append(p.cut(first, last))
    return out, notes


def build_scenario(
    planned: Sequence[PlannedTrip],
    *,
    name: str,
    net: Path,
    stops_file: Path,
    vclass: str,
    start_s: float,
    turnback_min_s: float = DEFAULT_TURNBACK_MIN_S,
    rotations: str = "explicit",
    seed: int = 1,
    can_turn: Callable[[Sequence[str], Sequence[str]], bool] | None = None,
) -> Built:
    """The scenario dict for ``planned`` trips (module docstring)."""
    groups: dict[tuple[str, tuple[str, ...]], list[PlannedTrip]] = defaultdict(list)
    for p in planned:
        groups[(p.line, p.stations)].append(p)
    built = Built(scenario={})
    services: list[dict[str, Any]] = []
    legs: list[Leg] = []
    used_ids: set[str] = set()
    vehicle = vehicle_for(vclass)
    for (line, stations), members in sorted(
        groups.items(), key=lambda kv: (kv[0][0], min(p.departure_s for p in kv[1]))
    ):
        members.sort(key=lambda p: (p.departure_s, p.source_id))
        unique: list[PlannedTrip] = []
        for p in members:
            if unique and abs(unique[-1].departure_s - p.departure_s) < 1.0:
                built.dropped_duplicate += 1
                continue
            unique.append(p)
        base = f"{_slug(line)}_{_slug(stations[0])}_{_slug(stations[-1])}"
        sid, k = base, 2
        while sid in used_ids:
            sid, k = f"{base}_{k}", k + 1
        used_ids.add(sid)
        dwells = [d for p in unique for d in p.dwell_s]
        dwell = max(MIN_DWELL_S, statistics.median(dwells)) if dwells else MIN_DWELL_S
        service: dict[str, Any] = {"id": sid, "from": stations[0], "to": stations[-1]}
        if len(stations) > 2:
            service["via"] = list(stations[1:-1])
        service.update(
            {
                "vehicle": vehicle,
                "departures": {"times": [_clock(p.departure_s) for p in unique]},
                "dwell_s": round(dwell, 1),
            }
        )
        services.append(service)
        width = max(3, len(str(len(unique) - 1)))
        for k, p in enumerate(unique):
            legs.append(
                Leg(
                    f"{sid}.{k:0{width}d}",
                    line,
                    p.block,
                    stations[0],
                    stations[-1],
                    p.departure_s,
                    p.arrival_s,
                    stations,
                )
            )
    built.services = len(services)
    built.trips = len(legs)
    end_s = max((p.arrival_s for p in planned), default=start_s) + END_MARGIN_S
    scenario: dict[str, Any] = {
        "name": name,
        "description": f"imported timetable: {built.trips} trips in {built.services} services ({vclass})",
        "world": {"net": str(net), "additional": [str(stops_file)], "vclass": vclass},
        "simulation": {
            "step_s": 0.5,
            "duration_s": float(max(60.0, round(end_s - start_s))),
            "start_time": _clock(start_s),
            "seed": seed,
        },
        "vehicles": {vehicle: dict(VEHICLES[vehicle])},
        "controllers": {
            "ato": {"type": "ato"},
            "sep": {"type": "separation", "params": {"margin_m": SEPARATION_MARGIN_M[vehicle]}},
            "vc": {"type": "cacc"},
        },
        "roles": {"ato": "ato", "separation": "sep", "coupled": "vc"},
        "services": services,
    }
    if rotations == "auto":
        scenario["rotations"] = {"units": "auto", "turnback_min_s": turnback_min_s}
    elif rotations == "explicit" and legs:
        rot = build_units(legs, turnback_min_s=turnback_min_s, can_turn=can_turn)
        scenario["rotations"] = {"units": rot.units, "turnback_min_s": turnback_min_s}
        built.units = len(rot.units)
        built.units_from_blocks = rot.from_blocks
        built.block_splits = rot.block_splits
    built.scenario = scenario
    return built


def trips_from_lines(
    lines: Sequence[Mapping[str, Any]], vclass: str, start_s: float, end_s: float, headway_s: float
) -> list[PlannedTrip]:
    """Trips at a fixed headway on every direction of the imported lines of ``vclass`` (``--from-lines``).

    Each direction with at least two distinct stations runs from ``start_s`` every ``headway_s`` up to (not
    including) ``end_s``; the opposite direction starts half a headway later so both termini see a train
    every headway. Running times are unknown without a timetable: rotations are left to railsim (``auto``).
    """
    out: list[PlannedTrip] = []
    for line in lines:
        if line.get("class") != vclass:
            continue
        for k, direction in enumerate(line.get("directions", [])):
            names: list[str] = []
            for st in direction.get("stations", []):
                if not names or names[-1] != st:
                    names.append(st)
            if len(set(names)) < 2:
                continue
            t = start_s + (0.5 * headway_s if k % 2 else 0.0)
            while t < end_s - 1e-9:
                times = tuple(t for _ in names)  # running times unknown: railsim drives the trip
                out.append(PlannedTrip(str(line["ref"]), tuple(names), times, times, "", f"{line['ref']}/{k}"))
                t += headway_s
    return out
