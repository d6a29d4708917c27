"""Validating ``services``: routes, departures (clock times or headway grids), dwell times, and trip names.

A service runs trips between two stations; its departures are a list (``{times: [...]}``), a
grid (``{first, last, headway_s}`` → ``first + k·headway_s`` up to ``last``, with a 1 µs tolerance so
float arithmetic cannot drop the last trip), or **relative to another service** (``{after: {service, every,
first_trip, last_trip, offset_s, phase}}``, :class:`~railsim.scenario.model.RelativeDeparturesSpec`): one trip per ``every``
trips of the reference service (from ``first_trip`` to ``last_trip``), ``offset_s`` after the reference trip's origin departure plus ``phase`` of the
interval to the next reference trip (trips that would depart before t = 0 are dropped). A study that changes the reference's headway (an override of its
``headway_s``) thereby re-times the dependent service too — the Jurenba branch units of Line 3 keep their place in
the Airport pattern at every probed headway. The reference must itself be timetabled by a list or a grid (no
chains), so relative services are validated after the others. A departure string is a clock time relative to
``simulation.start_time``; a number is already seconds from t = 0. Trip ``k`` of service ``airport`` is
called ``airport.000`` (at least three digits, more for long services).

Later sections refer to trains; :func:`trip_ref` (``{service, trip}``, used by formations) and
:func:`trip_name` (a trip id, or a one-trip service id, used by events, faults, cooperative groups and the
junction) check those references against the services validated here. Station ids are checked later,
against the built world (:mod:`railsim.scenario.world`).
"""

from __future__ import annotations

import copy
import logging
import math
from collections.abc import Mapping, Sequence
from typing import Any

from railsim.physics.vehicle import VehicleParams
from railsim.scenario.clock import CLOCK_WHAT, format_clock
from railsim.scenario.model import (
    DEFAULT_DWELL_S,
    MAX_TRIPS_PER_SERVICE,
    ControllerSpec,
    RelativeDeparturesSpec,
    ServiceSpec,
    SimulationSpec,
    TripRef,
)
from railsim.scenario.validate import Checker, did_you_mean, short_repr
from railsim.scenario.validate_vehicles import roles as check_roles

log = logging.getLogger("railsim.scenario")  # the package's logger: messages read "railsim.scenario: ..."

_GRID_TOL_S = 1e-6  # tolerance for "last falls on the headway grid"


def services(
    ck: Checker,
    value: Any,
    sim: SimulationSpec,
    vehicles: Mapping[str, VehicleParams],
    ctrls: Mapping[str, ControllerSpec],
    roles: Mapping[str, str],
) -> tuple[tuple[ServiceSpec, ...], list[Any]]:
    """``services:`` → the services in file order (ids unique); ``roles`` are the scenario-wide roles."""
    if not isinstance(value, list) or not value:
        raise ck.expect("services", "a non-empty list of services", value)
    by_index: dict[int, tuple[ServiceSpec, dict[str, Any]]] = {}
    known: dict[str, ServiceSpec] = {}
    relative = [i for i, body in enumerate(value) if _is_relative(body)]
    # services timed by a list or a grid first: the relative ones refer to them
    for i in [i for i in range(len(value)) if i not in relative] + relative:
        spec, raw = service(ck, value[i], f"services[{i}]", sim, vehicles, ctrls, roles, known)
        if spec.id in known:
            later = max(i, next(j for j, (s, _) in by_index.items() if s.id == spec.id))
            raise ck.fail(f"services[{later}].id", f"expected a unique service id, got {spec.id!r} twice")
        known[spec.id] = spec
        by_index[i] = (spec, raw)
    ordered = [by_index[i] for i in range(len(value))]
    if not any(t <= sim.duration_s for s, _ in ordered for t in s.departures_s):
        first = min((t for s, _ in ordered for t in s.departures_s), default=None)
        raise ck.fail(
            "simulation.duration_s",
            f"expected a horizon that reaches the first departure ({'none' if first is None else f'{first:g} s'}); "
            f"got {sim.duration_s:g} s: no train would run",
        )
    return tuple(s for s, _ in ordered), [r for _, r in ordered]


def _is_relative(body: Any) -> bool:
    """True if a raw service body times its departures relative to another service (``departures: {after:}``)."""
    return isinstance(body, dict) and isinstance(body.get("departures"), dict) and "after" in body["departures"]


def service(
    ck: Checker,
    body: Any,
    path: str,
    sim: SimulationSpec,
    vehicles: Mapping[str, VehicleParams],
    ctrls: Mapping[str, ControllerSpec],
    roles: Mapping[str, str],
    known: Mapping[str, ServiceSpec] | None = None,
) -> tuple[ServiceSpec, dict[str, Any]]:
    """One service; a departure after ``duration_s`` is logged, not rejected (a study may look at an hour).
    ``known`` are the services validated so far (the references of relative departures)."""
    m = ck.mapping(
        body, path, ("id", "from", "to", "vehicle", "departures"), ("via", "dwell_s", "skip", "roles", "start")
    )
    sid = ck.ident(m["id"], f"{path}.id")
    pins: dict[str, str] = {}
    origin = _place(ck, m["from"], f"{path}.from", pins)
    dest = _place(ck, m["to"], f"{path}.to", pins)
    if origin == dest:
        raise ck.fail(f"{path}.to", f"expected a station other than 'from', got {dest!r}")
    via_in = m.get("via") or []
    if not isinstance(via_in, list):
        raise ck.expect(f"{path}.via", "a list of stations", via_in)
    via = [_place(ck, v, f"{path}.via[{j}]", pins) for j, v in enumerate(via_in)]
    skip = ck.string_list(m.get("skip") or [], f"{path}.skip")
    for j, st in enumerate(skip):
        if st in (origin, dest):
            raise ck.fail(f"{path}.skip[{j}]", f"expected an intermediate station, got the terminal {st!r}")
    vehicle = m["vehicle"]
    if not isinstance(vehicle, str) or vehicle not in vehicles:
        hint = did_you_mean(vehicle, vehicles) if isinstance(vehicle, str) else ""
        raise ck.fail(
            f"{path}.vehicle", f"expected one of the vehicles ({', '.join(vehicles)}), got {short_repr(vehicle)}{hint}"
        )
    after = None
    if _is_relative(m):
        departures, dep_raw, after = relative_departures(ck, m["departures"], f"{path}.departures", known or {})
    else:
        departures, dep_raw = departure_times(ck, m["departures"], f"{path}.departures", sim)
    dwell_default, dwell_stations, dwell_raw = dwell(ck, m.get("dwell_s", DEFAULT_DWELL_S), f"{path}.dwell_s")
    own_roles, own_raw = check_roles(ck, m.get("roles") or {}, ctrls, f"{path}.roles", required=False)
    start_in = ck.mapping(
        m.get("start") or {}, f"{path}.start", (), ("offset_m", "speed_kmh", "before_switch", "distance_m")
    )
    start_offset = ck.number(start_in.get("offset_m", 0.0), f"{path}.start.offset_m", ge=0.0)
    max_kmh = vehicles[vehicle].max_speed_mps * 3.6
    start_kmh = ck.number(start_in.get("speed_kmh", 0.0), f"{path}.start.speed_kmh", ge=0.0)
    if start_kmh > max_kmh + 1e-9:
        raise ck.fail(
            f"{path}.start.speed_kmh",
            f"expected a speed in km/h at most the vehicle's max_speed_kmh ({max_kmh:g}), got {start_kmh:g}",
        )
    start_switch = None
    start_distance = 0.0
    if "before_switch" in start_in or "distance_m" in start_in:
        if "offset_m" in start_in:
            raise ck.fail(f"{path}.start", "give either offset_m or before_switch + distance_m, not both")
        if "before_switch" not in start_in or "distance_m" not in start_in:
            raise ck.fail(f"{path}.start", "before_switch and distance_m go together")
        start_switch = ck.string(start_in["before_switch"], f"{path}.start.before_switch")
        start_distance = ck.number(start_in["distance_m"], f"{path}.start.distance_m", gt=0.0)
    width = max(3, len(str(len(departures) - 1)))
    trip_ids = tuple(f"{sid}.{k:0{width}d}" for k in range(len(departures)))
    late = [t for t in departures if t > sim.duration_s]
    if late:
        log.warning(
            "%s: %s: %d of %d departures fall after duration_s=%g and will not run",
            ck.source,
            path,
            len(late),
            len(departures),
            sim.duration_s,
        )
    spec = ServiceSpec(
        id=sid,
        from_station=origin,
        to_station=dest,
        vehicle=vehicle,
        departures_s=departures,
        trip_ids=trip_ids,
        via=tuple(via),
        dwell_default_s=dwell_default,
        dwell_by_station=dwell_stations,
        skip=tuple(skip),
        roles={**roles, **own_roles},
        start_offset_m=start_offset,
        start_speed_mps=start_kmh / 3.6,
        start_before_switch=start_switch,
        start_distance_m=start_distance,
        departures_after=after,
        platforms=pins,
    )
    raw = {
        "id": sid,
        "from": _place_raw(origin, pins),
        "to": _place_raw(dest, pins),
        "via": [_place_raw(v, pins) for v in via],
        "vehicle": vehicle,
        "departures": dep_raw,
        "dwell_s": dwell_raw,
        "skip": skip,
        "roles": own_raw,
    }
    if start_in and start_switch is not None:
        raw["start"] = {"before_switch": start_switch, "distance_m": start_distance, "speed_kmh": start_kmh}
    elif start_in:
        raw["start"] = {"offset_m": start_offset, "speed_kmh": start_kmh}
    return spec, raw


def _place(ck: Checker, value: Any, path: str, pins: dict[str, str]) -> str:
    """A station of a service's ``from``/``to``/``via``: its id, name or stop id, or ``{station, platform}``
    pinning the stop id ``platform`` (recorded in ``pins``). Returns the station as written."""
    if not isinstance(value, dict):
        return ck.string(value, path)
    m = ck.mapping(value, path, ("station", "platform"))
    station = ck.string(m["station"], f"{path}.station")
    platform = ck.string(m["platform"], f"{path}.platform")
    if pins.get(station, platform) != platform:
        raise ck.fail(f"{path}.platform", f"expected the platform pinned before ({pins[station]!r}), got {platform!r}")
    pins[station] = platform
    return station


def _place_raw(station: str, pins: dict[str, str]) -> Any:
    return {"station": station, "platform": pins[station]} if station in pins else station


def time_point(ck: Checker, value: Any, path: str, sim: SimulationSpec) -> float:
    """A departure time: a clock string (relative to start_time) or seconds from t = 0."""
    if isinstance(value, str):
        t = ck.clock(value, path) - sim.start_time_s
        if t < 0.0:
            raise ck.fail(
                path, f"expected a time at or after start_time ({format_clock(sim.start_time_s)}), got {value!r}"
            )
        return t
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ck.expect(path, f"{CLOCK_WHAT} or seconds >= 0", value)
    return ck.number(value, path, ge=0.0)


def departure_times(
    ck: Checker, value: Any, path: str, sim: SimulationSpec
) -> tuple[tuple[float, ...], dict[str, Any]]:
    """``departures:`` → sorted seconds from t = 0 and the resolved raw form (as written, numbers checked)."""
    what = "a mapping {first, last, headway_s} or {times: [...]}"
    if not isinstance(value, dict):
        raise ck.expect(path, what, value)
    if "times" in value:
        m = ck.mapping(value, path, ("times",))
        times_in = m["times"]
        if not isinstance(times_in, list) or not times_in:
            raise ck.expect(f"{path}.times", "a non-empty list of departure times", times_in)
        if len(times_in) > MAX_TRIPS_PER_SERVICE:
            raise ck.fail(f"{path}.times", f"expected at most {MAX_TRIPS_PER_SERVICE} departures, got {len(times_in)}")
        times = [time_point(ck, v, f"{path}.times[{i}]", sim) for i, v in enumerate(times_in)]
        order = sorted(range(len(times)), key=times.__getitem__)
        for a, b in zip(order, order[1:]):
            if times[a] == times[b]:
                raise ck.fail(f"{path}.times[{b}]", f"expected distinct departure times, got {times_in[b]!r} twice")
        return tuple(times[k] for k in order), {"times": copy.deepcopy(times_in)}
    m = ck.mapping(value, path, ("first", "last", "headway_s"), what=what)
    first = time_point(ck, m["first"], f"{path}.first", sim)
    last = time_point(ck, m["last"], f"{path}.last", sim)
    headway = ck.number(m["headway_s"], f"{path}.headway_s", gt=0.0)
    if last < first:
        raise ck.fail(f"{path}.last", f"expected a time at or after first ({m['first']!r}), got {m['last']!r}")
    spans = (last - first) / headway + _GRID_TOL_S / headway  # huge or inf for a tiny (subnormal) headway
    if not spans < MAX_TRIPS_PER_SERVICE:
        got = f"{int(spans) + 1}" if spans < 1e12 else "more"
        raise ck.fail(
            path, f"expected at most {MAX_TRIPS_PER_SERVICE} departures, got {got} (from first to last every headway_s)"
        )
    n = int(math.floor(spans)) + 1
    times = tuple(first + k * headway for k in range(n))  # type: ignore[assignment]
    return times, {"first": m["first"], "last": m["last"], "headway_s": headway}  # type: ignore[return-value]


def relative_departures(
    ck: Checker, value: Any, path: str, known: Mapping[str, ServiceSpec]
) -> tuple[tuple[float, ...], dict[str, Any], RelativeDeparturesSpec]:
    """``departures: {after: {service, every, first_trip, last_trip, offset_s, phase}}`` → sorted seconds from t = 0, the
    resolved raw form and the rule (module docstring). ``known`` are the services it may refer to."""
    m = ck.mapping(value, path, ("after",))
    apath = f"{path}.after"
    a = ck.mapping(m["after"], apath, ("service",), ("every", "first_trip", "last_trip", "offset_s", "phase"))
    ref_id = a["service"]
    if not isinstance(ref_id, str) or ref_id not in known:
        hint = did_you_mean(ref_id, known) if isinstance(ref_id, str) else ""
        raise ck.fail(
            f"{apath}.service",
            f"expected a service timetabled by times or first/last/headway_s ({', '.join(known) or 'none'}), "
            f"got {short_repr(ref_id)}{hint}",
        )
    every = a.get("every", 1)
    if isinstance(every, bool) or not isinstance(every, int) or every < 1:
        raise ck.expect(f"{apath}.every", "an integer >= 1", every)
    ref = known[ref_id].departures_s
    first = a.get("first_trip", 0)
    if isinstance(first, bool) or not isinstance(first, int) or not 0 <= first < len(ref):
        raise ck.fail(
            f"{apath}.first_trip",
            f"expected a trip index in [0, {len(ref) - 1}] of service {ref_id!r}, got {short_repr(first)}",
        )
    last = a.get("last_trip")
    if last is not None and (isinstance(last, bool) or not isinstance(last, int) or not first <= last < len(ref)):
        raise ck.fail(
            f"{apath}.last_trip",
            f"expected a trip index in [{first}, {len(ref) - 1}] of service {ref_id!r} (>= first_trip), "
            f"got {short_repr(last)}",
        )
    offset = ck.number(a.get("offset_s", 0.0), f"{apath}.offset_s")
    phase = ck.number(a.get("phase", 0.0), f"{apath}.phase", ge=0.0)
    if phase >= 1.0:
        raise ck.fail(f"{apath}.phase", f"expected a fraction of the reference interval in [0, 1), got {phase:g}")
    if phase > 0.0 and len(ref) < 2:
        raise ck.fail(f"{apath}.phase", f"service {ref_id!r} has one trip: there is no interval to take a phase of")
    times, refs = [], []
    for i in range(first, len(ref) if last is None else last + 1, every):
        interval = (ref[i + 1] - ref[i]) if i + 1 < len(ref) else (ref[i] - ref[i - 1] if i > 0 else 0.0)
        t = ref[i] + phase * interval + offset
        if t >= 0.0:  # a negative offset drops the trips that would depart before t = 0
            times.append(t)
            refs.append(i)
    if not times:
        raise ck.fail(f"{apath}.offset_s", f"every departure after {ref_id!r} falls before t = 0 (offset {offset:g} s)")
    rule = RelativeDeparturesSpec(ref_id, every, first, offset, phase, last, tuple(refs))
    raw = {"after": {"service": ref_id, "every": every, "first_trip": first, "offset_s": offset, "phase": phase}}
    if last is not None:
        raw["after"]["last_trip"] = last
    return tuple(times), raw, rule


def dwell(ck: Checker, value: Any, path: str) -> tuple[float, dict[str, float], Any]:
    """``dwell_s:`` a number, or ``{default, stations}`` → (default [s], station -> s, resolved raw)."""
    if isinstance(value, dict):
        m = ck.mapping(value, path, (), ("default", "stations"))
        default = ck.number(m.get("default", DEFAULT_DWELL_S), f"{path}.default", ge=0.0)
        st_in = ck.free_mapping(m.get("stations") or {}, f"{path}.stations", what="a mapping station -> seconds")
        stations = {k: ck.number(v, f"{path}.stations.{k}", ge=0.0) for k, v in st_in.items()}
        return default, stations, {"default": default, "stations": dict(stations)}
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ck.expect(path, "a number >= 0 or a mapping {default, stations}", value)
    default = ck.number(value, path, ge=0.0)
    return default, {}, default


def trip_ref(ck: Checker, value: Any, path: str, services: Sequence[ServiceSpec]) -> TripRef:
    """``{service, trip}`` → a :class:`TripRef`; ``trip`` is a 0-based index into the sorted departures."""
    m = ck.mapping(value, path, ("service", "trip"))
    by_id = {s.id: s for s in services}
    sid = m["service"]
    if not isinstance(sid, str) or sid not in by_id:
        hint = did_you_mean(sid, by_id) if isinstance(sid, str) else ""
        raise ck.fail(f"{path}.service", f"expected a service id ({', '.join(by_id)}), got {short_repr(sid)}{hint}")
    n = len(by_id[sid].departures_s)
    trip = m["trip"]
    if isinstance(trip, bool) or not isinstance(trip, int) or not 0 <= trip < n:
        raise ck.fail(
            f"{path}.trip",
            f"expected a trip index in [0, {n - 1}] (service {sid!r} has {n} departures), got {short_repr(trip)}",
        )
    return TripRef(service=sid, trip=int(trip))


def trip_name(ck: Checker, value: Any, path: str, services: Sequence[ServiceSpec]) -> str:
    """A trip id, or the id of a service that has exactly one trip (→ that trip's id)."""
    trips = {t for svc in services for t in svc.trip_ids}
    if isinstance(value, str) and value in trips:
        return value
    for svc in services:
        if value == svc.id:
            if len(svc.trip_ids) != 1:
                raise ck.fail(
                    path,
                    f"expected a trip id; service {svc.id!r} has {len(svc.trip_ids)} trips "
                    f"(name one of {svc.trip_ids[0]}…)",
                )
            return svc.trip_ids[0]
    names = [svc.id for svc in services]
    hint = did_you_mean(value, names) if isinstance(value, str) else ""
    raise ck.fail(path, f"expected a trip id or a one-trip service id, got {short_repr(value)}{hint}")
