"""Line descriptions: the YAML a user writes to describe a railway, loaded into frozen dataclasses.

A *line description* is the single input of the network builder (:func:`network.build`). It says where the
stations are (chainage in km), how long their platforms are, the line speed and local speed limits, the
gradient profile, the turnback crossovers, and the branches that leave or join the main line at junctions.
Everything is validated on load; a mistake raises :class:`railsim.errors.ConfigError` naming the file, the
field path and what was expected, e.g.::

    lines/bad.yaml: stations[3].km: expected a chainage greater than stations[2].km (12.565), got 12.0

Schema (units in the key names; chainage ``km``, lengths ``_m``, speeds ``_kmh``)::

    name: chongqing_line3            # required; letters, digits, '_' or '-' (used for file names)
    description: "..."               # optional free text
    track: double                    # double (one one-way track per direction) | single (one bidirectional track)
    line_speed_kmh: 70               # required; lane speed wherever no lower limit applies
    platform_length_m: 220           # default platform length of every station
    overrun_m: 200                   # tail track beyond the platform end of a terminus (default 200)
    main_line_id: main               # id of the main line (edge ids start with it; default 'main')
    start_name: yudong               # optional names of the main line's two free ends (used in route ids);
    end_name: jiangbei-airport-t2    #   default: first / last station id, else '<main_line_id>_start/_end'
    from_km: -0.31                   # optional extent of the main line; default: first/last platform
    to_km: 54.29                     #   -/+ overrun_m
    stations:                        # main-line stations, strictly increasing chainage
      - {id: yudong, name: Yudong, km: 0.0, platform_length_m: 220, turnback: true, basis: "..."}
      - {id: jiugongli, km: 12.565, pocket: low}   # a turnback pocket track beyond the platform, on the
                                                   #   low-km side (trains from the high side turn there)
    speed_limits:                    # lower lane speeds on a stretch (edges are split at the boundaries)
      - {line: main, from_km: 53.67, to_km: 54.29, speed_kmh: 30, direction: up, basis: "..."}
    gradients:                       # per mille, positive = rising in the up direction; default 0
      - {line: main, from_km: 3.0, to_km: 4.5, permille: 12.0}
    crossovers:                      # turnback crossovers (recorded in the topology; no SUMO edges)
      - {id: yudong_xo, station: yudong, speed_kmh: 30}
    points:                          # named locations kept in every route passing them (e.g. coupling point F)
      - {id: F, line: trunk, km: 2.8}
    depots:                          # depot lead tracks (units start and end their day there, see below)
      - {id: daojiao, name: Daojiao, between: [yuhulu, xuetangwan], length_m: 300, throw_time_s: 15,
         speed_kmh: 30, basis: "..."}  # or `line: main, km: 4.5` instead of `between`
    branches:
      - id: konggang                 # line id of the branch
        name: Konggang branch
        joins: main                  # the line it leaves/joins: the main line or an earlier branch
        at_km: 52.83                 # junction (switch) point on that line
        side: up                     # up: the branch lies beyond the junction in the up direction (up trains
                                     #     diverge onto it, down trains merge from it); down: it lies before
        leg: reverse                 # which leg of the switches the branch is (the parent's continuation is
                                     #   the other leg); default reverse
        turnout_length_m: 50         # stretch of the reverse (and normal) leg next to the switch point that
                                     #   carries the switch speed; default 50
        switches:                    # double track: one switch per direction
          up:   {id: bijin_up, throw_time_s: 15, diverging_speed_kmh: 30, normal_speed_kmh: 70}
          down: {id: bijin_down, throw_time_s: 15, diverging_speed_kmh: 30}
        end_name: jurenba            # name of the branch's free end (default: its last/first station, else id)
        from_km: ...                 # side down: where the branch track starts (default: first platform -
        to_km: ...                   #   overrun); side up: where it ends (default: last platform + overrun)
        stations: [...]              # as above, chainage continues the parent's chainage through the junction

Every mapping may carry a ``basis`` string (where the number comes from); unknown keys are errors.

Readings that matter:

* **Chainage continues through a junction.** A branch's km are measured in the parent's frame: a branch
  station 2.037 km beyond a junction station at km 52.668 sits at km 54.705. Route chainage along any
  through-route then equals design chainage minus the route origin.
* **Up direction = increasing chainage.** Gradients are given for the up direction and negated for down.
* **Turnbacks.** A terminus with ``turnback: true`` gets a turnback track beyond the line end; an
  intermediate station with ``pocket: low|high`` gets a pocket track between the tracks beyond its platform on
  that side (two switches: off the arriving track, onto the departing one). Rotations reverse units there
  (``network.generator``, ``railsim.engine.turnback``). Crossovers are recorded for the timetable only.
* **Depots.** A depot is a bidi *lead track* (``length_m``, default :data:`DEFAULT_DEPOT_TRACK_M`) joined to
  both running tracks at one point: in the middle of the gap between two adjacent stations of one line
  (``between``) or at a chainage (``line``/``km``, outside every platform). One switch per running track
  (``<id>_up``, ``<id>_down``; ``throw_time_s``, ``speed_kmh``) takes a unit into or out of the lead. Where
  the depot itself lies is not modelled: a unit appears at the lead's running-line end and disappears at its
  far end (``railsim.engine.depot``).
* **Single track** builds one bidirectional track (SUMO bidi edges) and does not support branches yet.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from railsim.errors import ConfigError
from railsim.inputs import BoundedSafeLoader, YAMLLimitError, describe_kind, excerpt, limit_error, read_input_text

_ID_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]*$")
_MISSING = object()
DEFAULT_OVERRUN_M = 200.0
DEFAULT_TURNOUT_LENGTH_M = 50.0
# Edge break nodes keep this clearance from platform ends: internal junction lanes (0.1 m, see generator)
# must never push a platform onto two edges.
PLATFORM_CLEARANCE_M = 1.0


@dataclass(frozen=True)
class Station:
    id: str
    name: str
    km: float
    platform_length_m: float
    turnback: bool
    path: str  # field path in the description, for error messages
    pocket: str | None = None  # "low" | "high": a turnback pocket track beyond the platform on that side


@dataclass(frozen=True)
class SpeedLimit:
    line: str
    from_km: float
    to_km: float
    speed_kmh: float
    direction: str  # 'up' | 'down' | 'both'
    path: str


@dataclass(frozen=True)
class Gradient:
    line: str
    from_km: float
    to_km: float
    permille: float
    path: str


@dataclass(frozen=True)
class Crossover:
    id: str
    station: str
    speed_kmh: float
    path: str


@dataclass(frozen=True)
class Point:
    id: str
    line: str
    km: float
    path: str


@dataclass(frozen=True)
class Depot:
    """A depot's lead track, joined to both running tracks of ``line`` at ``km`` (module docstring)."""

    id: str
    name: str
    line: str
    km: float
    length_m: float
    throw_time_s: float
    speed_kmh: float
    basis: str
    path: str


@dataclass(frozen=True)
class SwitchSpec:
    id: str
    throw_time_s: float
    diverging_speed_kmh: float
    normal_speed_kmh: float | None
    path: str


@dataclass(frozen=True)
class Branch:
    id: str
    name: str
    joins: str
    at_km: float
    side: str  # 'up' | 'down'
    leg: str  # 'normal' | 'reverse'
    turnout_length_m: float
    switch_up: SwitchSpec
    switch_down: SwitchSpec
    end_name: str
    from_km: float
    to_km: float
    stations: tuple[Station, ...]
    path: str


@dataclass(frozen=True)
class LineDescription:
    name: str
    description: str
    track: str
    line_speed_kmh: float
    platform_length_m: float
    overrun_m: float
    main_line_id: str
    start_name: str
    end_name: str
    from_km: float
    to_km: float
    stations: tuple[Station, ...]
    speed_limits: tuple[SpeedLimit, ...]
    gradients: tuple[Gradient, ...]
    crossovers: tuple[Crossover, ...]
    points: tuple[Point, ...]
    branches: tuple[Branch, ...]
    source: str
    depots: tuple[Depot, ...] = ()

    def line_ids(self) -> list[str]:
        return [self.main_line_id] + [b.id for b in self.branches]

    def all_stations(self) -> list[tuple[str, Station]]:
        """(line id, station) for every station, main line first."""
        out = [(self.main_line_id, s) for s in self.stations]
        for b in self.branches:
            out += [(b.id, s) for s in b.stations]
        return out

    def line_extent_km(self, line: str) -> tuple[float, float]:
        if line == self.main_line_id:
            return self.from_km, self.to_km
        b = next(b for b in self.branches if b.id == line)
        return b.from_km, b.to_km


# ---------------------------------------------------------------------------------------------- reading
class _Reader:
    """Typed access to one mapping of the YAML with error messages that name the field path."""

    def __init__(self, source: str, data: Any, path: str, allowed: tuple[str, ...]) -> None:
        self.source = source
        self.path = path
        if not isinstance(data, Mapping):
            got = describe_kind(data) if not path else _describe(data)  # the top level: a file's content, unquoted
            raise ConfigError(source, path or None, f"expected a mapping, got {got}")
        if not path and data and not any(key in allowed for key in data):
            # none of a line description's keys: some other file (a password file, a config) named by mistake;
            # its content is not ours to print, not even a key
            raise ConfigError(
                source, None, f"not a line description (it has none of the keys {', '.join(allowed[:5])}, ...)"
            )
        for key in data:
            if key not in allowed:
                raise ConfigError(
                    source,
                    _join(path, str(key)),
                    f"expected one of {', '.join(allowed)}, got unknown key {excerpt(str(key))}",
                )
        self.data = data

    def field(self, key: str) -> str:
        return _join(self.path, key)

    def error(self, key: str, message: str) -> ConfigError:
        return ConfigError(self.source, self.field(key), message)

    def get(self, key: str, default: Any = _MISSING, what: str = "a value") -> Any:
        value = self.data.get(key, _MISSING)
        if value is _MISSING or value is None:
            if default is _MISSING:
                raise self.error(key, f"expected {what}, got nothing (required key is missing)")
            return default
        return value

    def number(
        self, key: str, default: Any = _MISSING, *, minimum: float | None = None, positive: bool = False
    ) -> float:
        what = "a number > 0" if positive else (f"a number >= {minimum:g}" if minimum is not None else "a number")
        value = self.get(key, default, what)
        if value is default and default is not _MISSING:
            return value
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise self.error(key, f"expected {what}, got {_describe(value)}")
        if (positive and value <= 0) or (minimum is not None and value < minimum):
            raise self.error(key, f"expected {what}, got {value!r}")
        return float(value)

    def string(self, key: str, default: Any = _MISSING) -> str:
        value = self.get(key, default, "a non-empty string")
        if not isinstance(value, str) or not value.strip():
            raise self.error(key, f"expected a non-empty string, got {_describe(value)}")
        return value

    def ident(self, key: str, default: Any = _MISSING) -> str:
        what = "an id of letters, digits, '_' or '-'"
        value = self.get(key, default, what)
        if not isinstance(value, str) or not _ID_RE.match(value):
            raise self.error(key, f"expected {what}, got {_describe(value)}")
        return value

    def boolean(self, key: str, default: bool) -> bool:
        value = self.get(key, default)
        if not isinstance(value, bool):
            raise self.error(key, f"expected true or false, got {_describe(value)}")
        return value

    def choice(self, key: str, choices: tuple[str, ...], default: Any = _MISSING) -> str:
        value = self.get(key, default, f"one of {', '.join(choices)}")
        if value not in choices:
            raise self.error(key, f"expected one of {', '.join(choices)}, got {_describe(value)}")
        return str(value)

    def seq(self, key: str) -> list[Any]:
        value = self.get(key, [])
        if not isinstance(value, list):
            raise self.error(key, f"expected a list, got {_describe(value)}")
        return value


def _join(path: str, key: str) -> str:
    return f"{path}.{key}" if path else key


def _describe(value: Any) -> str:
    if value is _MISSING or value is None:
        return "nothing"
    if isinstance(value, (dict, list)):
        return f"a {type(value).__name__}"
    return excerpt(value)


_STATION_KEYS = ("id", "name", "km", "platform_length_m", "turnback", "pocket", "basis", "name_zh")
_SWITCH_KEYS = ("id", "throw_time_s", "diverging_speed_kmh", "normal_speed_kmh", "basis")
_BRANCH_KEYS = (
    "id",
    "name",
    "joins",
    "at_km",
    "side",
    "leg",
    "turnout_length_m",
    "switches",
    "end_name",
    "from_km",
    "to_km",
    "stations",
    "basis",
)
_TOP_KEYS = (
    "name",
    "description",
    "track",
    "line_speed_kmh",
    "platform_length_m",
    "overrun_m",
    "main_line_id",
    "start_name",
    "end_name",
    "from_km",
    "to_km",
    "stations",
    "speed_limits",
    "gradients",
    "crossovers",
    "points",
    "branches",
    "depots",
    "basis",
    "sources",
)
_DEPOT_KEYS = ("id", "name", "between", "line", "km", "length_m", "throw_time_s", "speed_kmh", "basis")
DEFAULT_DEPOT_TRACK_M = 300.0  # estimated: one 6/8-car unit (<= 120 m) and room to stop short of the end
DEFAULT_DEPOT_THROW_S = 15.0  # estimated: as the Bijin switches
DEFAULT_DEPOT_SPEED_KMH = 30.0  # estimated: as the other Line 3 turnouts (S15)


def _stations(r: _Reader, key: str, default_platform_m: float, used_ids: dict[str, str]) -> tuple[Station, ...]:
    out: list[Station] = []
    for i, raw in enumerate(r.seq(key)):
        path = f"{r.field(key)}[{i}]"
        s = _Reader(r.source, raw, path, _STATION_KEYS)
        sid = s.ident("id")
        if sid in used_ids:
            raise s.error("id", f"expected a unique station id, got {sid!r} (already used at {used_ids[sid]})")
        used_ids[sid] = path
        km = s.number("km")
        if out and km <= out[-1].km:
            raise s.error(
                "km", f"expected a chainage greater than {r.field(key)}[{i - 1}].km ({out[-1].km:g}), got {km!r}"
            )
        plat = s.number("platform_length_m", default_platform_m, positive=True)
        pocket = s.choice("pocket", ("low", "high")) if s.get("pocket", None) is not None else None
        turnback = s.boolean("turnback", False) or pocket is not None
        st = Station(sid, str(s.get("name", sid)), km, plat, turnback, path, pocket)
        if out:
            prev = out[-1]
            gap_m = (st.km - prev.km) * 1000.0 - (st.platform_length_m + prev.platform_length_m) / 2.0
            if gap_m < 2 * PLATFORM_CLEARANCE_M:
                raise s.error(
                    "km",
                    f"expected platforms not to overlap: {sid} starts {-gap_m:.1f} m before "
                    f"the end of {prev.id}'s platform, got km {km!r}",
                )
        out.append(st)
    return tuple(out)


def _switch(source: str, raw: Any, path: str) -> SwitchSpec:
    s = _Reader(source, raw, path, _SWITCH_KEYS)
    normal = s.get("normal_speed_kmh", None)
    return SwitchSpec(
        id=s.ident("id"),
        throw_time_s=s.number("throw_time_s", minimum=0.0),
        diverging_speed_kmh=s.number("diverging_speed_kmh", positive=True),
        normal_speed_kmh=None if normal is None else s.number("normal_speed_kmh", positive=True),
        path=path,
    )


def _extent(
    r: _Reader,
    stations: tuple[Station, ...],
    overrun_m: float,
    lo_default: float | None,
    hi_default: float | None,
    what: str,
) -> tuple[float, float]:
    """Extent of a line: explicit ``from_km``/``to_km`` or the outer platforms +/- the overrun tail."""
    lo = r.get("from_km", None)
    hi = r.get("to_km", None)
    if lo is None:
        if lo_default is not None:
            lo = lo_default
        elif stations:
            lo = stations[0].km - (stations[0].platform_length_m / 2 + overrun_m) / 1000.0
        else:
            raise r.error("from_km", f"expected a number (the {what} has no stations to derive it from), got nothing")
    else:
        lo = r.number("from_km")
    if hi is None:
        if hi_default is not None:
            hi = hi_default
        elif stations:
            hi = stations[-1].km + (stations[-1].platform_length_m / 2 + overrun_m) / 1000.0
        else:
            raise r.error("to_km", f"expected a number (the {what} has no stations to derive it from), got nothing")
    else:
        hi = r.number("to_km")
    if hi <= lo:
        raise r.error("to_km", f"expected a chainage greater than from_km ({lo:g}), got {hi!r}")
    for st in stations:
        a = st.km - st.platform_length_m / 2000.0
        b = st.km + st.platform_length_m / 2000.0
        if a < lo or b > hi:
            raise ConfigError(
                r.source,
                f"{st.path}.km",
                f"expected the platform to lie within the line extent [{lo:g}, {hi:g}] km, "
                f"got km {st.km:g} with a {st.platform_length_m:g} m platform",
            )
    return float(lo), float(hi)


def parse_description(data: Any, source: str | Path) -> LineDescription:
    """Validate a raw mapping (as loaded from YAML) into a :class:`LineDescription`."""
    source = str(source)
    r = _Reader(source, data, "", _TOP_KEYS)
    name = r.ident("name")
    track = r.choice("track", ("double", "single"), "double")
    line_speed = r.number("line_speed_kmh", positive=True)
    platform_m = r.number("platform_length_m", 200.0, positive=True)
    overrun_m = r.number("overrun_m", DEFAULT_OVERRUN_M, minimum=0.0)
    main_id = r.ident("main_line_id", "main")
    used: dict[str, str] = {}
    stations = _stations(r, "stations", platform_m, used)
    from_km, to_km = _extent(r, stations, overrun_m, None, None, "main line")
    start_name = r.ident("start_name", stations[0].id if stations else f"{main_id}_start")
    end_name = r.ident("end_name", stations[-1].id if stations else f"{main_id}_end")

    line_ids = [main_id]
    extents = {main_id: (from_km, to_km)}
    branches: list[Branch] = []
    switch_ids: dict[str, str] = {}
    for i, raw in enumerate(r.seq("branches")):
        path = f"branches[{i}]"
        b = _Reader(source, raw, path, _BRANCH_KEYS)
        bid = b.ident("id")
        if bid in line_ids:
            raise b.error("id", f"expected a line id not used before, got {bid!r}")
        joins = b.get("joins", what=f"one of {', '.join(line_ids)}")
        if joins not in line_ids:
            raise b.error("joins", f"expected one of {', '.join(line_ids)}, got {_describe(joins)}")
        if track == "single":
            raise b.error(
                "joins",
                f"expected no branches on a single-track line (not supported yet), got a branch joining {joins!r}",
            )
        at_km = b.number("at_km")
        side = b.choice("side", ("up", "down"))
        leg = b.choice("leg", ("normal", "reverse"), "reverse")
        turnout_m = b.number("turnout_length_m", DEFAULT_TURNOUT_LENGTH_M, positive=True)
        lo, hi = extents[joins]
        margin_km = (turnout_m + PLATFORM_CLEARANCE_M) / 1000.0
        if not lo + margin_km < at_km < hi - margin_km:
            raise b.error(
                "at_km",
                f"expected a chainage inside line {joins!r} ({lo + margin_km:g} < km < "
                f"{hi - margin_km:g}), got {at_km!r}",
            )
        sw = b.get("switches", what="a mapping with 'up' and 'down' switches")
        sw_r = _Reader(source, sw, b.field("switches"), ("up", "down"))
        sw_up = _switch(source, sw_r.get("up", what="a switch mapping"), sw_r.field("up"))
        sw_down = _switch(source, sw_r.get("down", what="a switch mapping"), sw_r.field("down"))
        for spec in (sw_up, sw_down):
            if spec.id in switch_ids:
                raise ConfigError(
                    source,
                    f"{spec.path}.id",
                    f"expected a unique switch id, got {spec.id!r} (already used at {switch_ids[spec.id]})",
                )
            switch_ids[spec.id] = spec.path
        bstations = _stations(b, "stations", platform_m, used)
        if side == "up":
            blo, bhi = _extent(b, bstations, overrun_m, at_km, None, "branch")
            if b.get("from_km", None) is not None:
                raise b.error(
                    "from_km", f"expected no from_km on a side-up branch (it starts at at_km), got {b.get('from_km')!r}"
                )
        else:
            blo, bhi = _extent(b, bstations, overrun_m, None, at_km, "branch")
            if b.get("to_km", None) is not None:
                raise b.error(
                    "to_km", f"expected no to_km on a side-down branch (it ends at at_km), got {b.get('to_km')!r}"
                )
        if bhi - blo <= margin_km:
            raise b.error(
                "stations",
                f"expected the branch to be longer than its turnout ({turnout_m:g} m), got {1000 * (bhi - blo):.1f} m",
            )
        default_end = (bstations[-1].id if side == "up" else bstations[0].id) if bstations else bid
        branches.append(
            Branch(
                id=bid,
                name=str(b.get("name", bid)),
                joins=str(joins),
                at_km=at_km,
                side=side,
                leg=leg,
                turnout_length_m=turnout_m,
                switch_up=sw_up,
                switch_down=sw_down,
                end_name=b.ident("end_name", default_end),
                from_km=blo,
                to_km=bhi,
                stations=bstations,
                path=path,
            )
        )
        line_ids.append(bid)
        extents[bid] = (blo, bhi)
    # Two junctions on one line must leave room for both turnouts.
    for i, b1 in enumerate(branches):
        for b2 in branches[:i]:
            if (
                b1.joins == b2.joins
                and abs(b1.at_km - b2.at_km) * 1000.0 < b1.turnout_length_m + b2.turnout_length_m + 2
            ):
                raise ConfigError(
                    source,
                    f"{b1.path}.at_km",
                    f"expected a junction at least {b1.turnout_length_m + b2.turnout_length_m + 2:g} m "
                    f"from {b2.path} (km {b2.at_km:g}), got km {b1.at_km:g}",
                )

    def line_field(rr: _Reader) -> str:
        line = rr.get("line", main_id)
        if line not in line_ids:
            raise rr.error("line", f"expected one of {', '.join(line_ids)}, got {_describe(line)}")
        return str(line)

    def span(rr: _Reader, line: str) -> tuple[float, float]:
        a = rr.number("from_km")
        z = rr.number("to_km")
        if z <= a:
            raise rr.error("to_km", f"expected a chainage greater than from_km ({a:g}), got {z!r}")
        lo, hi = extents[line]
        if a < lo - 1e-9 or z > hi + 1e-9:
            raise rr.error(
                "from_km" if a < lo - 1e-9 else "to_km",
                f"expected a stretch within line {line!r} [{lo:g}, {hi:g}] km, got [{a:g}, {z:g}]",
            )
        return a, z

    limits = []
    for i, raw in enumerate(r.seq("speed_limits")):
        rr = _Reader(source, raw, f"speed_limits[{i}]", ("line", "from_km", "to_km", "speed_kmh", "direction", "basis"))
        line = line_field(rr)
        a, z = span(rr, line)
        limits.append(
            SpeedLimit(
                line,
                a,
                z,
                rr.number("speed_kmh", positive=True),
                rr.choice("direction", ("up", "down", "both"), "both"),
                rr.path,
            )
        )
    gradients = []
    for i, raw in enumerate(r.seq("gradients")):
        rr = _Reader(source, raw, f"gradients[{i}]", ("line", "from_km", "to_km", "permille", "basis"))
        line = line_field(rr)
        a, z = span(rr, line)
        g = rr.number("permille")
        if abs(g) > 100:
            raise rr.error("permille", f"expected a gradient within +/-100 per mille, got {g!r}")
        gradients.append(Gradient(line, a, z, g, rr.path))
    for line in line_ids:  # gradients on one line must not overlap (one value per point)
        own = sorted((g for g in gradients if g.line == line), key=lambda g: g.from_km)
        for g1, g2 in zip(own, own[1:]):
            if g2.from_km < g1.to_km - 1e-9:
                raise ConfigError(
                    source,
                    f"{g2.path}.from_km",
                    f"expected no overlap with {g1.path} (ends at km {g1.to_km:g}), got {g2.from_km:g}",
                )
    crossovers = []
    for i, raw in enumerate(r.seq("crossovers")):
        rr = _Reader(source, raw, f"crossovers[{i}]", ("id", "station", "speed_kmh", "basis"))
        st = rr.get("station", what="a station id of this line")
        if st not in used:
            raise rr.error("station", f"expected a station id of this line, got {_describe(st)}")
        crossovers.append(Crossover(rr.ident("id"), str(st), rr.number("speed_kmh", positive=True), rr.path))
    points = []
    for i, raw in enumerate(r.seq("points")):
        rr = _Reader(source, raw, f"points[{i}]", ("id", "line", "km", "basis"))
        line = line_field(rr)
        km = rr.number("km")
        lo, hi = extents[line]
        if not lo <= km <= hi:
            raise rr.error("km", f"expected a chainage within line {line!r} [{lo:g}, {hi:g}], got {km!r}")
        points.append(Point(rr.ident("id"), line, km, rr.path))
    depots = _depots(r, source, main_id, extents, used, [(main_id, stations)] + [(b.id, b.stations) for b in branches])

    return LineDescription(
        name=name,
        description=str(r.get("description", "")).strip(),
        track=track,
        line_speed_kmh=line_speed,
        platform_length_m=platform_m,
        overrun_m=overrun_m,
        main_line_id=main_id,
        start_name=start_name,
        end_name=end_name,
        from_km=from_km,
        to_km=to_km,
        stations=stations,
        speed_limits=tuple(limits),
        gradients=tuple(gradients),
        crossovers=tuple(crossovers),
        points=tuple(points),
        branches=tuple(branches),
        source=source,
        depots=depots,
    )


def _depots(
    r: _Reader,
    source: str,
    main_id: str,
    extents: dict[str, tuple[float, float]],
    used: dict[str, str],
    lines: list[tuple[str, tuple[Station, ...]]],
) -> tuple[Depot, ...]:
    """The ``depots`` list (module docstring): where each lead track joins the line."""
    out: list[Depot] = []
    for i, raw in enumerate(r.seq("depots")):
        rr = _Reader(source, raw, f"depots[{i}]", _DEPOT_KEYS)
        did = rr.ident("id")
        if did in used or any(d.id == did for d in out):
            raise rr.error("id", f"expected an id not used by a station or another depot, got {did!r}")
        between = rr.get("between", None)
        if between is not None:
            if rr.get("km", None) is not None:
                raise rr.error("km", "expected either between or km, got both")
            line, km = _between(rr, between, lines)
        else:
            line = rr.get("line", main_id)
            if line not in extents:
                raise rr.error("line", f"expected one of {', '.join(extents)}, got {_describe(line)}")
            km = rr.number("km")
            lo, hi = extents[line]
            if not lo < km < hi:
                raise rr.error("km", f"expected a chainage inside line {line!r} ({lo:g} < km < {hi:g}), got {km!r}")
        out.append(
            Depot(
                did,
                str(rr.get("name", did)),
                str(line),
                km,
                rr.number("length_m", DEFAULT_DEPOT_TRACK_M, positive=True),
                rr.number("throw_time_s", DEFAULT_DEPOT_THROW_S, minimum=0.0),
                rr.number("speed_kmh", DEFAULT_DEPOT_SPEED_KMH, positive=True),
                str(rr.get("basis", "")),
                rr.path,
            )
        )
    return tuple(out)


def _between(rr: _Reader, between: Any, lines: list[tuple[str, tuple[Station, ...]]]) -> tuple[str, float]:
    """(line, km) of the middle of the gap between two adjacent stations (the generator's edge break there)."""
    if not (isinstance(between, list) and len(between) == 2):
        raise rr.error("between", f"expected two adjacent station ids [a, b], got {_describe(between)}")
    for line, stations in lines:
        for s1, s2 in zip(stations, stations[1:]):
            if {s1.id, s2.id} == set(between):
                end1 = s1.km * 1000.0 + s1.platform_length_m / 2
                start2 = s2.km * 1000.0 - s2.platform_length_m / 2
                return line, 0.5 * (end1 + start2) / 1000.0
    raise rr.error("between", f"expected two adjacent stations of one line, got {between!r}")


def load_description(path: str | Path) -> tuple[LineDescription, Any]:
    """Read and validate a line-description YAML file; returns the description and the raw mapping."""
    path = Path(path)
    text = read_input_text(path, str(path), "line description")
    try:
        data = yaml.load(text, Loader=BoundedSafeLoader)  # noqa: S506 - a SafeLoader with structural limits
    except YAMLLimitError as exc:
        raise limit_error(exc, str(path)) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
        raise ConfigError(
            path, None, f"expected valid YAML, got a syntax error{where}: {getattr(exc, 'problem', exc)}"
        ) from None
    return parse_description(data, path), data
