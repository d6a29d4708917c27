"""A finished line run, read for plotting: stations in line order, every trip's path, a colour per service.

:func:`load_line_run` reads a run folder once (through :mod:`railsim.analysis.sections`) into a
:class:`LineRun`, which every line plot (:mod:`.line`) and the report draw from.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from railsim.analysis import sections
from railsim.errors import ConfigError
from railsim.report import export

DIRECTIONS = ("up", "down")
DEPOT_SERVICES = ("depot_out", "depot_in")  # a unit's empty runs out of and into a depot (railsim.engine.depot)
DEPOT_COLOUR = "#999999"
PALETTE = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#56B4E9", "#E69F00", "#000000", "#F0E442")


@dataclass(frozen=True)
class StationMark:
    """A station on the distance axis: line km of its platform centre; ``branch`` is False on the main line,
    ``turnback`` True where trains can start and end (drawn bold)."""

    id: str
    name: str
    km: float
    branch: bool
    turnback: bool


@dataclass
class TrainPath:
    """One trip's trace on the line: clock time [s after midnight], line km of its front, speed, state."""

    trip_id: str
    service: str
    direction: str
    clock_s: np.ndarray
    km: np.ndarray
    speed_mps: np.ndarray
    gap_m: np.ndarray
    formation_state: np.ndarray  # str per sample ("" when not in a formation)


@dataclass
class LineRun:
    """A run folder read for line plots: its world (:class:`railsim.analysis.sections.LineFrame`), stations on the axis,
    one :class:`TrainPath` per trip that left its origin, and the colour of each service."""

    run_dir: Path
    frame: sections.LineFrame
    start_time_s: float
    stations: list[StationMark]
    paths: dict[str, TrainPath]
    colours: dict[str, str]

    @property
    def name(self) -> str:
        return str(self.frame.scenario.name)

    def directions(self) -> list[str]:
        """Directions that have at least one train, in ``up``, ``down`` order."""
        present = {p.direction for p in self.paths.values()}
        return [d for d in DIRECTIONS if d in present]

    def trips_in(self, direction: str) -> list[TrainPath]:
        return [p for p in self.paths.values() if p.direction == direction]

    def services_in(self, direction: str) -> list[str]:
        return [
            s
            for s, sf in self.frame.services.items()
            if sf.direction == direction and any(p.service == s for p in self.paths.values())
        ]


_ABBREVIATIONS = (
    ("University", "Univ."),
    ("Station", "Stn."),
    ("Square", "Sq."),
    ("Technology", "Tech."),
    ("North", "N."),
    ("South", "S."),
    (" and ", " & "),
)
NAME_CHARS = 30  # longest station label before abbreviating


def station_label(name: str, max_chars: int = NAME_CHARS) -> str:
    """A station's axis label: the Latin name only (``"Yudong (鱼洞)"`` → ``"Yudong"``; matplotlib's default font
    has no CJK glyphs), common words abbreviated and cut with "…" if it is longer than ``max_chars``."""
    label = name.split(" (", 1)[0].strip() or name
    for word, short in _ABBREVIATIONS:
        if len(label) <= max_chars:
            break
        label = label.replace(word, short)
    return label if len(label) <= max_chars else label[: max_chars - 1].rstrip() + "…"


def load_line_run(run_dir: Path | str) -> LineRun:
    """Read a run folder for line plots (rebuilds its world from ``scenario.resolved.yaml``; ConfigError if the
    folder is not a run or the world has no stations)."""
    run = Path(run_dir)
    if export.check_folder(run) != "run":
        raise ConfigError(run, None, "line plots need a run folder (railsim run), this is a sweep folder")
    frame = sections.LineFrame.from_run(run)
    bundle = frame.bundle
    on_routes = {s for sf in frame.services.values() for s in sf.stations}
    lines = [bundle.stations[s].line for s in on_routes]
    main_line = max(set(lines), key=lines.count) if lines else ""
    stations = sorted(
        (
            StationMark(
                s,
                station_label(bundle.stations[s].name),
                float(bundle.stations[s].km),
                bundle.stations[s].line != main_line,
                bool(bundle.stations[s].turnback),
            )
            for s in on_routes
        ),
        key=lambda m: (m.km, m.branch),
    )

    trace = export.read_table(run, "trace")
    trips = export.read_table(run, "trips")
    t0 = float(frame.scenario.simulation.start_time_s)
    paths: dict[str, TrainPath] = {}
    service_of = dict(zip(trips["trip_id"].astype(str), trips["service"].astype(str)))
    trip_of = {str(r.trip_id): r for r in trips.itertuples(index=False)}
    for tid, grp in trace.groupby(trace["train"].astype(str), sort=False):
        svc = service_of.get(tid, str(grp["service"].iloc[0]))
        sf = frame.services.get(svc)
        grp = grp.sort_values("t_s", kind="mergesort")
        if sf is not None:
            direction, km = sf.direction, np.asarray(sf.km_of(grp["chainage_m"].to_numpy(float)), dtype=float)
        elif svc in DEPOT_SERVICES and tid in trip_of:
            placed = _depot_run_km(grp, trip_of[tid], bundle)
            if placed is None:
                continue
            direction, km = placed
        else:
            continue
        fs = grp["formation_state"]
        state = np.where(fs.isna(), "", fs.astype(str)).astype(str)  # all-empty columns read back as NaN
        paths[tid] = TrainPath(
            tid,
            svc,
            direction,
            t0 + grp["t_s"].to_numpy(float),
            km,
            grp["speed_mps"].to_numpy(float),
            pd.to_numeric(grp["gap_m"]).to_numpy(float),
            state,
        )
    # route families: services between the same two end stations share a colour (airport_up and airport_down);
    # a second service of the same family and direction gets the next colour, so no panel repeats one
    families: dict[tuple[frozenset[str], int], str] = {}
    colours: dict[str, str] = {}
    seen: list[tuple[frozenset[str], str]] = []
    for svc in frame.scenario.services:
        ends = frozenset((svc.from_station, svc.to_station))
        direction = frame.services[svc.id].direction
        key = (ends, seen.count((ends, direction)))
        seen.append((ends, direction))
        if key not in families:
            families[key] = PALETTE[len(families) % len(PALETTE)]
        colours[svc.id] = families[key]
    colours.update({svc: DEPOT_COLOUR for svc in DEPOT_SERVICES})
    return LineRun(run, frame, t0, stations, dict(sorted(paths.items())), colours)


def _depot_run_km(grp: pd.DataFrame, trip: Any, bundle: Any) -> tuple[str, np.ndarray] | None:
    """(direction, line km of each trace sample) of a depot run: it runs along the line without reversing of its
    own, so its km moves 1 km per 1000 m of route chainage from the station at its platform end (anchored when it
    arrives there, or leaves it) towards its depot's km, where the lead begins (held there on the lead)."""
    depots = bundle.graph.graph.get("depots", {})
    out = trip.service == "depot_out"
    depot, station = (str(trip.origin), str(trip.destination)) if out else (str(trip.destination), str(trip.origin))
    at_s = pd.to_numeric(trip.arrival_s if out else trip.departure_s, errors="coerce")
    if depot not in depots or station not in bundle.stations or not np.isfinite(at_s):
        return None
    t, c = grp["t_s"].to_numpy(float), grp["chainage_m"].to_numpy(float)
    km_station, km_depot = float(bundle.stations[station].km), float(depots[depot]["km"])
    toward = 1.0 if km_depot >= km_station else -1.0
    from_station_m = (np.interp(at_s, t, c) - c) if out else (c - np.interp(at_s, t, c))
    km = km_station + toward * from_station_m / 1000.0
    km = np.minimum(km, km_depot) if toward > 0 else np.maximum(km, km_depot)
    moves_up = (toward < 0) if out else (toward > 0)
    return ("up" if moves_up else "down"), km
