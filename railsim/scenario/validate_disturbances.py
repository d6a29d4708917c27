"""Validating ``disturbances:``: the primary delays a run injects (:mod:`railsim.scenario.disturbances`).

Every number is finite and in range (delays ≥ 0, probabilities in [0, 1], performance factors in (0, 1],
windows ``from_s ≤ until_s``); services and trips must exist, stations are checked against the world when the
run is set up (:mod:`railsim.engine.primary_delays`). The resolved raw mapping writes every rule out with its
defaults, so ``scenario.resolved.yaml`` shows exactly what was injected.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from railsim.scenario.clock import format_clock
from railsim.scenario.disturbances import (
    DWELL_DISTS,
    DelayDist,
    DelayRule,
    DemandSpec,
    DisturbanceSpec,
    IncidentSpec,
    PerformanceSpec,
)
from railsim.scenario.model import MIN_RUNNING_TIME_FACTOR, ServiceSpec
from railsim.scenario.validate import Checker, did_you_mean
from railsim.scenario.validate_services import trip_name

_TOP = ("intensity", "dwell", "departure", "running_time", "incidents", "demand")
MAX_PAX_PER_H = 100_000.0  # boarding passengers per hour at one platform: more is a typo
MAX_S_PER_PASSENGER = 60.0
_RULE_KEYS: tuple[str, ...] = ("stations", "services", "from_s", "until_s", "prob", "dist", "weights")
_RULE_KEYS += ("value_s", "mean_s", "sd_s", "values_s")
MAX_DELAY_S = 86_400.0  # one day: a longer primary delay is a typo


def disturbances(ck: Checker, value: Any, services: Sequence[ServiceSpec]) -> tuple[DisturbanceSpec, dict[str, Any]]:
    """``disturbances:`` → a :class:`DisturbanceSpec` and its written-out raw mapping."""
    m = ck.mapping(value if value is not None else {}, "disturbances", (), _TOP)
    intensity = ck.number(m.get("intensity", 1.0), "disturbances.intensity", ge=0.0, le=100.0)
    service_ids = [s.id for s in services]
    dwell, dwell_raw = _rules(ck, m.get("dwell"), "disturbances.dwell", service_ids, stations=True)
    dep, dep_raw = _rules(ck, m.get("departure"), "disturbances.departure", service_ids, stations=False)
    perf, perf_raw = _performance(ck, m.get("running_time"), "disturbances.running_time", service_ids)
    inc, inc_raw = _incidents(ck, m.get("incidents"), "disturbances.incidents", services)
    demand, demand_raw = _demand(ck, m.get("demand"), "disturbances.demand")
    spec = DisturbanceSpec(intensity, dwell, dep, perf, inc, demand)
    raw = {"intensity": intensity, "dwell": dwell_raw, "departure": dep_raw, "running_time": perf_raw}
    raw["incidents"] = inc_raw
    if demand_raw:  # only when given: older scenarios resolve as they did
        raw["demand"] = demand_raw
    return spec, raw


def _demand(ck: Checker, value: Any, path: str) -> tuple[DemandSpec | None, dict[str, Any]]:
    """``demand:`` (passenger-driven dwell) → a :class:`DemandSpec`, or None when absent."""
    if value is None:
        return None, {}
    m = ck.mapping(value, path, ("s_per_passenger",), ("s_per_passenger", "stations", "default"))
    c = ck.number(m["s_per_passenger"], f"{path}.s_per_passenger", ge=0.0, le=MAX_S_PER_PASSENGER)
    stations = ck.free_mapping(m.get("stations") or {}, f"{path}.stations")
    rates = tuple((str(sid), _rate_table(ck, table, f"{path}.stations.{sid}")) for sid, table in stations.items())
    default = _rate_table(ck, m["default"], f"{path}.default") if m.get("default") is not None else ()
    raw: dict[str, Any] = {"s_per_passenger": c, "stations": {sid: _table_raw(t) for sid, t in rates}}
    if default:
        raw["default"] = _table_raw(default)
    return DemandSpec(c, rates, default), raw


def _rate_table(ck: Checker, value: Any, path: str) -> tuple[tuple[float, float], ...]:
    """``{"HH:MM": passengers per hour, ...}`` → ``((seconds after midnight, rate), ...)`` in time order."""
    what = 'a table {"HH:MM": boarding passengers per hour, ...}'
    if not isinstance(value, dict) or not value:
        raise ck.expect(path, what, value)
    steps = []
    for key, rate in value.items():
        if not isinstance(key, str):  # YAML reads an unquoted 07:00 as the number 420
            raise ck.expect(f"{path}.{key}", 'a quoted clock time "HH:MM" as the key', key)
        clock_s = ck.clock(key, f"{path}.{key}")
        steps.append((clock_s, ck.number(rate, f"{path}.{key}", ge=0.0, le=MAX_PAX_PER_H)))
    return tuple(sorted(steps))


def _table_raw(steps: tuple[tuple[float, float], ...]) -> dict[str, float]:
    return {format_clock(t): rate for t, rate in steps}


def _list(ck: Checker, value: Any, path: str) -> list[Any]:
    if value is None:
        return []
    if not isinstance(value, list):
        raise ck.expect(path, "a list of rules", value)
    return value


def _services(ck: Checker, value: Any, path: str, service_ids: Sequence[str]) -> tuple[str, ...]:
    names = ck.string_list(value, path)
    for k, name in enumerate(names):
        if name not in service_ids:
            raise ck.fail(f"{path}[{k}]", f"expected a service id, got {name!r}{did_you_mean(name, service_ids)}")
    return tuple(names)


def _window(ck: Checker, r: dict[str, Any], path: str) -> tuple[float, float]:
    from_s = ck.number(r.get("from_s", 0.0), f"{path}.from_s", ge=0.0)
    until_s = ck.number(r["until_s"], f"{path}.until_s", ge=from_s) if r.get("until_s") is not None else math.inf
    return from_s, until_s


def _rules(
    ck: Checker, value: Any, path: str, service_ids: Sequence[str], stations: bool
) -> tuple[tuple[DelayRule, ...], list[dict[str, Any]]]:
    keys = _RULE_KEYS if stations else tuple(k for k in _RULE_KEYS if k != "stations")
    out: list[DelayRule] = []
    raws: list[dict[str, Any]] = []
    for k, body in enumerate(_list(ck, value, path)):
        p = f"{path}[{k}]"
        r = ck.mapping(body, p, ("dist",), keys)
        dist, dist_raw = delay_dist(ck, r, p)
        sts = tuple(ck.string_list(r["stations"], f"{p}.stations")) if stations and r.get("stations") else ()
        svcs = _services(ck, r["services"], f"{p}.services", service_ids) if r.get("services") else ()
        from_s, until_s = _window(ck, r, p)
        prob = ck.number(r.get("prob", 1.0), f"{p}.prob", ge=0.0, le=1.0)
        out.append(DelayRule(dist, sts, svcs, from_s, until_s, prob))
        raw = {**dist_raw, "services": list(svcs), "from_s": from_s, "prob": prob}
        if stations:
            raw["stations"] = list(sts)
        if math.isfinite(until_s):
            raw["until_s"] = until_s
        raws.append(raw)
    return tuple(out), raws


def delay_dist(ck: Checker, r: dict[str, Any], path: str) -> tuple[DelayDist, dict[str, Any]]:
    """The ``dist`` of a rule and its parameters (:data:`DWELL_DISTS`), each in range."""
    dist = ck.string(r["dist"], f"{path}.dist", tuple(DWELL_DISTS))
    for key in DWELL_DISTS[dist]:
        if key not in r:
            raise ck.fail(f"{path}.{key}", f"missing required key (distribution {dist!r})")
    others = {"value_s", "mean_s", "sd_s", "values_s", "weights"} - set(DWELL_DISTS[dist])
    if dist == "empirical":
        others.discard("weights")
    for key in sorted(others):
        if key in r:
            raise ck.fail(f"{path}.{key}", f"not a parameter of distribution {dist!r}")
    if dist == "constant":
        v = ck.number(r["value_s"], f"{path}.value_s", ge=0.0, le=MAX_DELAY_S)
        return DelayDist(dist, value_s=v), {"dist": dist, "value_s": v}
    if dist == "exponential":
        mean = ck.number(r["mean_s"], f"{path}.mean_s", ge=0.0, le=MAX_DELAY_S)
        return DelayDist(dist, mean_s=mean), {"dist": dist, "mean_s": mean}
    if dist == "lognormal":
        mean = ck.number(r["mean_s"], f"{path}.mean_s", gt=0.0, le=MAX_DELAY_S)
        sd = ck.number(r["sd_s"], f"{path}.sd_s", ge=0.0, le=MAX_DELAY_S)
        return DelayDist(dist, mean_s=mean, sd_s=sd), {"dist": dist, "mean_s": mean, "sd_s": sd}
    vals_in = r["values_s"]
    if not isinstance(vals_in, list) or not vals_in:
        raise ck.expect(f"{path}.values_s", "a non-empty list of delays [s]", vals_in)
    values = tuple(ck.number(v, f"{path}.values_s[{i}]", ge=0.0, le=MAX_DELAY_S) for i, v in enumerate(vals_in))
    weights: tuple[float, ...] = ()
    if r.get("weights") is not None:
        w_in = r["weights"]
        if not isinstance(w_in, list) or len(w_in) != len(values):
            raise ck.expect(f"{path}.weights", f"a list of {len(values)} weights (one per value)", w_in)
        weights = tuple(ck.number(w, f"{path}.weights[{i}]", ge=0.0) for i, w in enumerate(w_in))
        if sum(weights) <= 0.0:
            raise ck.fail(f"{path}.weights", "expected at least one weight > 0")
    raw: dict[str, Any] = {"dist": dist, "values_s": list(values)}
    if weights:
        raw["weights"] = list(weights)
    return DelayDist(dist, values_s=values, weights=weights), raw


def _performance(
    ck: Checker, value: Any, path: str, service_ids: Sequence[str]
) -> tuple[PerformanceSpec, dict[str, Any]]:
    m = ck.mapping(value if value is not None else {}, path, (), ("low", "high", "services"))
    low = ck.number(m.get("low", 1.0), f"{path}.low", ge=MIN_RUNNING_TIME_FACTOR, le=1.0)
    high = ck.number(m.get("high", 1.0), f"{path}.high", ge=low, le=1.0)
    svcs = _services(ck, m["services"], f"{path}.services", service_ids) if m.get("services") else ()
    return PerformanceSpec(low, high, svcs), {"low": low, "high": high, "services": list(svcs)}


def _incidents(
    ck: Checker, value: Any, path: str, services: Sequence[ServiceSpec]
) -> tuple[tuple[IncidentSpec, ...], list[dict[str, Any]]]:
    out: list[IncidentSpec] = []
    raws: list[dict[str, Any]] = []
    keys = ("hold_s", "trip", "station", "rate_per_h", "stations", "from_s", "until_s")
    for k, body in enumerate(_list(ck, value, path)):
        p = f"{path}[{k}]"
        r = ck.mapping(body, p, ("hold_s",), keys)
        hold = ck.number(r["hold_s"], f"{p}.hold_s", ge=0.0, le=MAX_DELAY_S)
        if r.get("trip") is not None:
            for key in ("rate_per_h", "stations", "from_s", "until_s"):
                if key in r:
                    raise ck.fail(f"{p}.{key}", "not allowed with 'trip' (a single incident: trip, station, hold_s)")
            if r.get("station") is None:
                raise ck.fail(f"{p}.station", "missing required key (an incident on a trip names its station)")
            trip = trip_name(ck, r["trip"], f"{p}.trip", services)
            station = ck.string(r["station"], f"{p}.station")
            out.append(IncidentSpec(hold_s=hold, trip=trip, station=station))
            raws.append({"trip": trip, "station": station, "hold_s": hold})
            continue
        if "station" in r:
            raise ck.fail(f"{p}.station", "only with 'trip'; incidents at a rate take 'stations'")
        if "rate_per_h" not in r:
            raise ck.fail(f"{p}.rate_per_h", "missing required key (give 'trip' and 'station', or 'rate_per_h')")
        rate = ck.number(r["rate_per_h"], f"{p}.rate_per_h", ge=0.0, le=3600.0)
        sts = tuple(ck.string_list(r["stations"], f"{p}.stations")) if r.get("stations") else ()
        from_s, until_s = _window(ck, r, p)
        out.append(IncidentSpec(hold_s=hold, rate_per_h=rate, stations=sts, from_s=from_s, until_s=until_s))
        raw: dict[str, Any] = {"rate_per_h": rate, "hold_s": hold, "stations": list(sts), "from_s": from_s}
        if math.isfinite(until_s):
            raw["until_s"] = until_s
        raws.append(raw)
    return tuple(out), raws
