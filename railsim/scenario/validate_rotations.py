"""Validating the ``rotations:`` section: which trips a unit chains into its day, and the turnback minimum.

Accepted forms::

    rotations: auto                      # first-in-first-out at each terminal, 120 s minimum turnback
    rotations:
      units: auto                        # or {unit id: [trip id, trip id, ...]} in running order
      turnback_min_s: 180                # default minimum turnback (driver / cab change) [s]
      turnback_min_by_station: {yudong: 240}
      max_layover_s: 1800                # auto: a unit that would wait longer for its next departure (from
                                         #   arrival + turnback minimum) leaves service instead (the depot)
      depots: auto                       # depot runs: each unit leaves a depot before its first trip and
                                         #   returns to one after its last; auto = the nearest by track, or a
                                         #   depot id, or {depot: auto|id, by_unit: {unit id: depot id}}

An explicit list names each trip once, in departure order. That each trip starts at the station where the one
before it ended, and that the world lets a unit reverse there, is checked against the world when the run is
set up (``railsim.engine.turnback``: stations may be named by name or id, resolved by the world), and so are
depot ids (``railsim.engine.depot``: a ConfigError naming ``rotations.depots...``, exit 2).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from railsim.scenario.model import RotationSpec, ServiceSpec
from railsim.scenario.validate import Checker
from railsim.scenario.validate_services import trip_name

_KEYS = ("units", "turnback_min_s", "turnback_min_by_station", "max_layover_s", "depots")


def rotations(ck: Checker, value: Any, services: Sequence[ServiceSpec]) -> tuple[RotationSpec, Any]:
    """The ``rotations`` section → a :class:`RotationSpec` and its resolved raw form."""
    path = "rotations"
    if value == "auto":
        value = {"units": "auto"}
    m = ck.mapping(value, path, (), _KEYS, what="'auto' or a mapping")
    default_s = ck.number(m.get("turnback_min_s", 120.0), f"{path}.turnback_min_s", ge=0.0)
    by_station: dict[str, float] = {}
    raw_by = ck.free_mapping(m.get("turnback_min_by_station") or {}, f"{path}.turnback_min_by_station")
    for sid, secs in raw_by.items():
        by_station[sid] = ck.number(secs, f"{path}.turnback_min_by_station.{sid}", ge=0.0)
    layover_s = ck.number(m.get("max_layover_s", 1800.0), f"{path}.max_layover_s", ge=0.0)
    units_raw = m.get("units", "auto")
    units: dict[str, tuple[str, ...]] | None = None
    if units_raw != "auto":
        units = {}
        seen: dict[str, str] = {}
        departs = {t: d for svc in services for t, d in zip(svc.trip_ids, svc.departures_s)}
        for uid, trips in ck.free_mapping(units_raw, f"{path}.units", "'auto' or {unit: [trip ids]}").items():
            upath = f"{path}.units.{uid}"
            if not isinstance(trips, list) or not trips:
                raise ck.expect(upath, "a non-empty list of trip ids", trips)
            chain = [trip_name(ck, t, f"{upath}[{k}]", services) for k, t in enumerate(trips)]
            for k, tid in enumerate(chain):
                if tid in seen:
                    raise ck.fail(f"{upath}[{k}]", f"trip {tid!r} is already run by unit {seen[tid]!r}")
                seen[tid] = uid
                if k == 0:
                    continue
                prev = chain[k - 1]
                if departs[tid] <= departs[prev]:
                    raise ck.fail(f"{upath}[{k}]", f"trip {tid!r} departs before {prev!r}, the trip before it")
            units[uid] = tuple(chain)
    depot, by_unit = _depots(ck, m.get("depots"), f"{path}.depots")
    spec = RotationSpec(
        units=units,
        turnback_min_s=default_s,
        turnback_min_by_station=by_station,
        max_layover_s=layover_s,
        depot=depot,
        depot_by_unit=by_unit,
    )
    raw: dict[str, Any] = {
        "units": "auto" if units is None else {u: list(c) for u, c in units.items()},
        "turnback_min_s": default_s,
        "turnback_min_by_station": dict(by_station),
        "max_layover_s": layover_s,
    }
    if depot is not None:
        raw["depots"] = {"depot": depot, "by_unit": dict(by_unit)}
    return spec, raw


def _depots(ck: Checker, value: Any, path: str) -> tuple[str | None, dict[str, str]]:
    """``depots``: None (no depot runs), ``auto``, a depot id, or ``{depot: ..., by_unit: {...}}``."""
    if value is None:
        return None, {}
    if isinstance(value, str):
        value = {"depot": value}
    m = ck.mapping(value, path, (), ("depot", "by_unit"), what="'auto', a depot id or a mapping")
    depot = m.get("depot", "auto")
    if not isinstance(depot, str) or not depot:
        raise ck.expect(f"{path}.depot", "'auto' or a depot id", depot)
    by_unit: dict[str, str] = {}
    for uid, did in ck.free_mapping(m.get("by_unit") or {}, f"{path}.by_unit", "{unit id: depot id}").items():
        if not isinstance(did, str) or not did:
            raise ck.expect(f"{path}.by_unit.{uid}", "a depot id", did)
        by_unit[str(uid)] = did
    return depot, by_unit
