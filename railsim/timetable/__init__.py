"""Timetables from open data: a GTFS feed (or an imported world's lines) -> an ordinary railsim scenario.

``railsim timetable import FEED.zip --world DIR --date D --from T0 --to T1 --out SCENARIO.yaml`` reads the rail
trips of one day and window (:mod:`.gtfs`), matches their stops to the stations of a world made by
``railsim network import`` (:mod:`.matching`), groups them into services and builds rotations
(:mod:`.builder`, :mod:`.rotations`), and writes a scenario the user can edit and run. ``--from-lines
--headway-s H`` builds services from the world's imported OSM lines instead, when there is no feed.

:func:`import_timetable` and :func:`timetable_from_lines` are the whole API; both return an
:class:`ImportReport` whose ``text()`` the CLI prints. The world folder must hold what the network import
writes: ``*.net.xml``, ``*.stops.<class>.add.xml``, ``*.stations.yaml`` (and ``*.lines.yaml`` for lines).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import date as Date
from pathlib import Path
from typing import Any

import yaml

from railsim.errors import ConfigError
from railsim.timetable.builder import Built, build_scenario, cut_to_routable, plan_trips, trips_from_lines
from railsim.timetable.gtfs import read_trips
from railsim.timetable.matching import DEFAULT_RADIUS_M, Match, WorldStation, match_stops, report_lines
from railsim.timetable.rotations import DEFAULT_TURNBACK_MIN_S

__all__ = ["ImportReport", "World", "import_timetable", "load_world", "timetable_from_lines"]

# GTFS route types -> the rail classes their trains may run on (first = preferred)
_TYPE_CLASSES = {
    0: ("tram",),
    1: ("subway", "rail_urban"),
    2: ("rail", "rail_urban", "rail_electric", "rail_fast"),
    12: ("rail_urban",),
}


def classes_of_route_type(route_type: int) -> tuple[str, ...]:
    """Rail classes a GTFS route type can run on (extended types by their hundreds)."""
    if route_type in _TYPE_CLASSES:
        return _TYPE_CLASSES[route_type]
    if 100 <= route_type < 200:
        return ("rail", "rail_urban", "rail_electric", "rail_fast")
    if 400 <= route_type < 500:
        return ("subway", "rail_urban")
    if 900 <= route_type < 1000:
        return ("tram",)
    return ()


@dataclass(frozen=True)
class World:
    """An imported world folder: the net, stops file per class, stations (with lon/lat) and lines."""

    folder: Path
    net: Path
    stops: dict[str, Path]
    stations: list[WorldStation]
    lines: list[dict[str, Any]]


def load_world(folder: str | Path) -> World:
    """Read an imported world folder (ConfigError naming what is missing)."""
    from network.osm_import import stop_files

    d = Path(folder)
    if not d.is_dir():
        raise ConfigError(d, None, "expected a world folder written by `railsim network import`")
    nets = sorted(d.glob("*.net.xml"))
    stations_files = sorted(d.glob("*.stations.yaml"))
    if not nets or not stations_files:
        raise ConfigError(
            d, None, "expected a world folder written by `railsim network import` (a .net.xml and a .stations.yaml)"
        )
    raw = yaml.safe_load(stations_files[0].read_text(encoding="utf-8")) or {}
    stations = [
        WorldStation(str(s["name"]), str(s["class"]), float(s.get("lon", math.nan)), float(s.get("lat", math.nan)))
        for s in raw.get("stations", [])
    ]
    lines: list[dict[str, Any]] = []
    for lf in sorted(d.glob("*.lines.yaml")):
        lines += (yaml.safe_load(lf.read_text(encoding="utf-8")) or {}).get("lines", [])
    return World(d, nets[0], stop_files(d), stations, lines)


@dataclass
class ImportReport:
    """What an import did, for the terminal."""

    out: Path
    vclass: str
    built: Built
    lines: list[str] = field(default_factory=list)

    def text(self) -> str:
        b = self.built
        head = [
            f"wrote {self.out}: {b.trips} trips in {b.services} services on {self.vclass}",
        ]
        if b.units:
            head.append(
                f"  rotations: {b.units} units ({b.units_from_blocks} from block_id, {b.block_splits} block splits; "
                "the rest built: same line, fewest units, shortest turnback)"
            )
            if b.units == b.trips:
                head.append(
                    "  (no unit could turn anywhere: the lines' ends lie outside the extract or their termini have no "
                    "turnaround, so every trip is its own unit, entering and leaving the world)"
                )
        elif "rotations" in b.scenario:
            head.append("  rotations: auto (railsim chains units at run time)")
        if b.dropped_short:
            head.append(f"  dropped: {b.dropped_short} trips with fewer than 2 stations in the world")
        if b.dropped_duplicate:
            head.append(
                f"  dropped: {b.dropped_duplicate} trips leaving at the same second as another of their service"
            )
        return "\n".join(head + [f"  {ln}" for ln in self.lines])


def _write(out: Path, built: Built, header: Sequence[str]) -> None:
    text = yaml.safe_dump(built.scenario, sort_keys=False, allow_unicode=True, width=120)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("".join(f"# {h}\n" for h in header) + text, encoding="utf-8")


def _choose_class(world: World, requested: str | None, counts: dict[str, int]) -> str:
    if requested is not None:
        if requested not in world.stops:
            raise ConfigError(
                "<command line>",
                "--vclass",
                f"expected one of the world's classes {sorted(world.stops)}, got {requested!r}",
            )
        return requested
    if not counts or max(counts.values()) == 0:
        raise ConfigError(
            "<command line>",
            "--world",
            f"expected a world whose stations match the feed; no trip has 2 stations in any class of {sorted(world.stops)}",
        )
    return max(sorted(counts), key=lambda vc: counts[vc])


def import_timetable(
    feed: str | Path,
    world_dir: str | Path,
    day: Date,
    from_s: float,
    to_s: float,
    out: str | Path,
    *,
    routes: Sequence[str] | None = None,
    vclass: str | None = None,
    turnback_min_s: float = DEFAULT_TURNBACK_MIN_S,
    rotations: str = "explicit",
    radius_m: float = DEFAULT_RADIUS_M,
) -> ImportReport:
    """GTFS feed -> scenario file (module docstring)."""
    if to_s <= from_s:
        raise ConfigError("<command line>", "--to", "expected a time after --from")
    world = load_world(world_dir)
    data = read_trips(feed, day, from_s, to_s, routes)
    if not data.trips:
        raise ConfigError(feed, "--from/--to", "expected rail trips leaving in the window, got none")
    per_class: dict[str, dict[str, Match]] = {}
    counts: dict[str, int] = {}
    for vc in world.stops:
        matches = match_stops(data.stops.values(), [s for s in world.stations if s.vclass == vc], radius_m)
        per_class[vc] = matches
        compatible = [t for t in data.trips if vc in classes_of_route_type(t.route_type)]
        planned, _ = plan_trips(compatible, matches, {s.name: vc for s in world.stations if s.vclass == vc}, vc)
        counts[vc] = len(planned)
    chosen = _choose_class(world, vclass, counts)
    matches = per_class[chosen]
    compatible = [t for t in data.trips if chosen in classes_of_route_type(t.route_type)]
    planned, short = plan_trips(
        compatible, matches, {s.name: chosen for s in world.stations if s.vclass == chosen}, chosen
    )
    world_routes = _Routes(world, chosen)
    planned, cut_notes = cut_to_routable(planned, world_routes.routable)
    out_path = Path(out)
    built = build_scenario(
        planned,
        name=out_path.stem.removesuffix(".yaml"),
        net=_relative(world.net, out_path),
        stops_file=_relative(world.stops[chosen], out_path),
        vclass=chosen,
        start_s=from_s,
        turnback_min_s=turnback_min_s,
        rotations=rotations,
        can_turn=world_routes.can_turn,
    )
    built.dropped_short = short
    relevant = {c.stop_id for t in compatible for c in t.calls}
    lines = [
        f"feed: {data.rail_routes} rail routes, {len(data.trips)} trips in the window "
        f"({data.expanded_from_frequencies} expanded from frequencies.txt), {len(data.trips) - len(compatible)} of "
        f"other classes than {chosen}",
        *report_lines({k: v for k, v in matches.items() if k in relevant}),
        *cut_notes,
    ]
    others = {vc: n for vc, n in counts.items() if vc != chosen and n}
    if others:
        lines.append(
            "other classes with trips (import them with --vclass): "
            + ", ".join(f"{vc} {n}" for vc, n in others.items())
        )
    _write(
        out_path,
        built,
        [
            f"Imported by `railsim timetable import` from {Path(feed).name}, {day.isoformat()}, "
            f"{_hhmm(from_s)}-{_hhmm(to_s)}, world {world.folder.name} ({chosen}).",
            "Services group trips with the same line and stations; rotations: units from block_id, else built "
            "(same line, fewest units, shortest turnback).",
        ],
    )
    return ImportReport(out_path, chosen, built, lines)


def timetable_from_lines(
    world_dir: str | Path,
    from_s: float,
    to_s: float,
    headway_s: float,
    out: str | Path,
    *,
    vclass: str | None = None,
    turnback_min_s: float = DEFAULT_TURNBACK_MIN_S,
    lines: Sequence[str] | None = None,
) -> ImportReport:
    """The world's imported lines at a fixed headway -> scenario file (rotations: auto)."""
    if not (math.isfinite(headway_s) and headway_s > 0):
        raise ConfigError("<command line>", "--headway-s", f"expected a number > 0, got {headway_s!r}")
    if to_s <= from_s:
        raise ConfigError("<command line>", "--to", "expected a time after --from")
    world = load_world(world_dir)
    chosen_lines = [ln for ln in world.lines if not lines or str(ln.get("ref")) in set(lines)]
    counts = {vc: len(trips_from_lines(chosen_lines, vc, from_s, to_s, headway_s)) for vc in world.stops}
    if not world.lines:
        raise ConfigError(
            world.folder,
            None,
            "expected imported lines (*.lines.yaml with lines): the OSM extract had no route relations",
        )
    chosen = _choose_class(world, vclass, counts)
    planned, cut_notes = cut_to_routable(
        trips_from_lines(chosen_lines, chosen, from_s, to_s, headway_s), _Routes(world, chosen).routable
    )
    out_path = Path(out)
    built = build_scenario(
        planned,
        name=out_path.stem,
        net=_relative(world.net, out_path),
        stops_file=_relative(world.stops[chosen], out_path),
        vclass=chosen,
        start_s=from_s,
        turnback_min_s=turnback_min_s,
        rotations="auto",
    )
    built.scenario["simulation"]["duration_s"] = float(round(to_s - from_s + 3600.0))
    _write(
        out_path,
        built,
        [
            f"Built by `railsim timetable import --from-lines` from the OSM lines of world {world.folder.name} "
            f"({chosen}), every {headway_s:g} s, {_hhmm(from_s)}-{_hhmm(to_s)}; rotations: auto.",
        ],
    )
    return ImportReport(
        out_path, chosen, built, [f"lines: {', '.join(sorted({str(p.line) for p in planned}))}", *cut_notes]
    )


TURNBACK_SEARCH_M = 5000.0  # as railsim's turnbacks: a turnaround farther than this is not a turnback


class _Routes:
    """The world as the import needs it: is there a service route through some stations, and can a unit that
    ends one route turn into the start of another (a turnaround within :data:`TURNBACK_SEARCH_M`)?"""

    def __init__(self, world: World, vclass: str) -> None:
        from network.external import load_net

        self.bundle = load_net(world.net, [world.stops[vclass]], vclass=vclass, where=("<command line>", "--"))
        self.ids = self.bundle.station_aliases
        g = self.bundle.graph
        self.reversals = {a: b for a, (b, _via) in g.graph.get("reversals", {}).items() if a in g and b in g}
        self._ends: dict[tuple[str, ...], tuple[str, str] | None] = {}
        self._turn: dict[tuple[str, str], bool] = {}

    def ends(self, chain: Sequence[str]) -> tuple[str, str] | None:
        """(first edge, last edge) of the route through ``chain``, or None if the world has none."""
        key = tuple(chain)
        if key not in self._ends:
            try:
                r = self.bundle.route_between(self.ids[key[0]], self.ids[key[-1]], [self.ids[c] for c in key[1:-1]])
                self._ends[key] = (r.edges[0], r.edges[-1])
            except (KeyError, ValueError):
                self._ends[key] = None
        return self._ends[key]

    def routable(self, chain: Sequence[str]) -> bool:
        return self.ends(chain) is not None

    def can_turn(self, arriving: Sequence[str], departing: Sequence[str]) -> bool:
        """A unit that ran ``arriving`` can reverse into ``departing`` (a turnaround reachable ahead of its last
        edge, from which the first edge of the next route is reachable). Not where the next route begins on the
        edge the last one ends on: the engine makes no turning move from an edge back onto itself
        (:func:`railsim.engine.turnback.turnback_path`), and whether the unit may depart where it stands depends on
        the other trips (:func:`railsim.engine.turnback._same_platform`), so such a unit is not chained here."""
        a, d = self.ends(arriving), self.ends(departing)
        if a is None or d is None or a[1] == d[0]:
            return False
        key = (a[1], d[0])
        if key not in self._turn:
            import networkx as nx

            g = self.bundle.graph
            weight = lambda u, v, data: float(g.nodes[v]["length_m"])  # noqa: E731
            ahead = nx.single_source_dijkstra_path_length(g, key[0], cutoff=TURNBACK_SEARCH_M, weight=weight)
            back = nx.single_source_dijkstra_path_length(
                g.reverse(copy=False), key[1], cutoff=TURNBACK_SEARCH_M, weight=weight
            )
            self._turn[key] = any(  # out to the turnaround and back within the search's reach in all
                x in ahead and y in back and ahead[x] + back[y] <= TURNBACK_SEARCH_M for x, y in self.reversals.items()
            )
        return self._turn[key]


def _relative(path: Path, scenario: Path) -> Path:
    """``path`` as the scenario file will name it: relative to the scenario's folder (a scenario and its world
    move together), absolute when they lie on different drives."""
    try:
        return Path(os.path.relpath(path.resolve(), scenario.resolve().parent))
    except ValueError:
        return path.resolve()


def _hhmm(t_s: float) -> str:
    t = int(round(t_s))
    return f"{t // 3600:02d}:{t % 3600 // 60:02d}"
