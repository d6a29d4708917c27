"""Validating trains that run together: formations (virtual coupling), cooperative groups, junction plans.

* ``formations`` pair a leader trip and a follower trip (:class:`TripRef`) with a target gap and optional
  couple/decouple triggers (:class:`TriggerSpec`: at a time, at a station, on departure, before a switch);
  ``pairs: {leader: <service>, follower: <service>}`` stands for one formation per follower trip when the follower
  service departs relative to the leader service (``departures: {after: ...}``).
  A train follows in at most one formation, and following may not loop back to itself.
* ``cooperative`` is a graph-coupled group (Paper C): edges ``x_a − x_b → d_m`` within ``[lower_m, upper_m]``
  with activity windows.
* ``junction`` hands 2–8 trains to the cooperative-game planner (Paper E); its ``params``/``pso`` blocks are
  checked by building the planner's own dataclasses (:meth:`Checker.dataclass_fields`).

Trains are referred to by :func:`railsim.scenario.validate_services.trip_ref` (formations) or
:func:`railsim.scenario.validate_services.trip_name` (the others). Triggers' station and switch ids are
checked against the built world by :mod:`railsim.scenario.world`.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from typing import Any

from railsim.scenario.model import (
    DEFAULT_COUPLING_TIMEOUT_S,
    JUNCTION_METHODS,
    CooperativeEdge,
    CooperativeSpec,
    FormationSpec,
    JunctionSpec,
    ServiceSpec,
    TriggerSpec,
    TripRef,
)
from railsim.scenario.validate import Checker, did_you_mean, short_repr
from railsim.scenario.validate_services import trip_name, trip_ref

COUPLE_TRIGGERS = ("at_s", "at_station", "on_departure", "after_switch")
DECOUPLE_TRIGGERS = ("before_switch", "at_s", "at_station")


def formations(ck: Checker, value: Any, services: Sequence[ServiceSpec]) -> tuple[tuple[FormationSpec, ...], list[Any]]:
    """``formations:`` → the formations in file order (ids unique, every follower in one formation, no cycle)."""
    if not isinstance(value, list):
        raise ck.expect("formations", "a list of formations", value)
    specs: list[FormationSpec] = []
    raws: list[Any] = []
    follower_of: dict[TripRef, str] = {}
    leader_of: dict[TripRef, TripRef] = {}
    trip_ids_of = {s.id: s.trip_ids for s in services}
    for i, body in enumerate(value):
        path = f"formations[{i}]"
        for fid, leader, follower, m in _entries(ck, body, path, services):
            if any(f.id == fid for f in specs):
                raise ck.fail(f"{path}.id", f"expected a unique formation id, got {fid!r} twice")
            follower_name = trip_ids_of[follower.service][follower.trip]
            if follower == leader:
                raise ck.fail(f"{path}.follower", f"expected a train other than the leader, got {follower_name}")
            if follower in follower_of:
                raise ck.fail(
                    f"{path}.follower",
                    f"expected a train that follows in at most one formation, got {follower_name} "
                    f"(already the follower in {follower_of[follower]!r})",
                )
            # Following must not loop back: walking leaders from the leader may not reach the follower.
            node: TripRef | None = leader
            while node is not None:
                if node == follower:
                    raise ck.fail(
                        f"{path}.follower",
                        f"expected formations without a cycle, got {follower_name} following itself",
                    )
                node = leader_of.get(node)
            follower_of[follower] = fid
            leader_of[follower] = leader
            gap = ck.number(m["target_gap_m"], f"{path}.target_gap_m", gt=0.0)
            timeout = ck.number(
                m.get("coupling_timeout_s", DEFAULT_COUPLING_TIMEOUT_S), f"{path}.coupling_timeout_s", gt=0.0
            )
            raw: dict[str, Any] = {
                "id": fid,
                "leader": {"service": leader.service, "trip": leader.trip},
                "follower": {"service": follower.service, "trip": follower.trip},
                "target_gap_m": gap,
            }
            couple = decouple = None
            if m.get("couple") is not None:
                couple, raw["couple"] = trigger(ck, m["couple"], f"{path}.couple", COUPLE_TRIGGERS)
            if m.get("decouple") is not None:
                decouple, raw["decouple"] = trigger(ck, m["decouple"], f"{path}.decouple", DECOUPLE_TRIGGERS)
            raw["coupling_timeout_s"] = timeout
            together = ck.boolean(m.get("depart_together", False), f"{path}.depart_together")
            if together:  # listed only when set: resolved scenarios without it stay as they were
                raw["depart_together"] = True
            specs.append(FormationSpec(fid, leader, follower, gap, couple, decouple, timeout, together))
            raws.append(raw)
    return tuple(specs), raws


_OPTIONAL = ("couple", "decouple", "coupling_timeout_s", "depart_together")


def _entries(
    ck: Checker, body: Any, path: str, services: Sequence[ServiceSpec]
) -> list[tuple[str, TripRef, TripRef, dict[str, Any]]]:
    """One formation entry → ``(id, leader, follower, fields)`` per formation it stands for.

    An entry names two trips (``leader``/``follower``: ``{service, trip}``), or two services (``pairs: {leader,
    follower}``) when the follower service's departures are relative to the leader service
    (``departures: {after: {service: <leader>, ...}}``): every follower trip then forms a formation ``<id><k>``
    with the reference trip it departs after — as many formations as the headway gives trips, so a headway search
    keeps every branch unit coupled. The resolved scenario lists the expanded formations."""
    if isinstance(body, dict) and "pairs" in body:
        m = ck.mapping(body, path, ("id", "pairs", "target_gap_m"), _OPTIONAL)
        fid = ck.ident(m["id"], f"{path}.id")
        p = ck.mapping(m["pairs"], f"{path}.pairs", ("leader", "follower"))
        by_id = {s.id: s for s in services}
        for key in ("leader", "follower"):
            if not isinstance(p[key], str) or p[key] not in by_id:
                hint = did_you_mean(p[key], by_id) if isinstance(p[key], str) else ""
                raise ck.fail(
                    f"{path}.pairs.{key}", f"expected a service id ({', '.join(by_id)}), got {short_repr(p[key])}{hint}"
                )
        lead, follow = by_id[p["leader"]], by_id[p["follower"]]
        rule = follow.departures_after
        if rule is None or rule.service != lead.id:
            raise ck.fail(
                f"{path}.pairs.follower",
                f"expected a service whose departures are relative to {lead.id!r} "
                f"(departures: {{after: {{service: {lead.id}}}}}), got {follow.id!r}",
            )
        refs = rule.reference_trips
        return [(f"{fid}{k}", TripRef(lead.id, i), TripRef(follow.id, k), m) for k, i in enumerate(refs)]
    m = ck.mapping(body, path, ("id", "leader", "follower", "target_gap_m"), _OPTIONAL)
    fid = ck.ident(m["id"], f"{path}.id")
    leader = trip_ref(ck, m["leader"], f"{path}.leader", services)
    follower = trip_ref(ck, m["follower"], f"{path}.follower", services)
    return [(fid, leader, follower, m)]


def trigger(ck: Checker, value: Any, path: str, kinds: Sequence[str]) -> tuple[TriggerSpec, dict[str, Any]]:
    """A one-key mapping ``{<kind>: <value>}`` with ``kind`` one of ``kinds`` → a :class:`TriggerSpec`."""
    m = ck.mapping(value, path, (), kinds)
    if len(m) != 1:
        raise ck.fail(path, f"expected exactly one of {', '.join(kinds)}, got {short_repr(m)}")
    kind, v = next(iter(m.items()))
    kpath = f"{path}.{kind}"
    if kind == "at_s":
        return TriggerSpec(kind, at_s=ck.number(v, kpath, ge=0.0)), {kind: float(v)}
    if kind == "on_departure":
        if v is not True:
            raise ck.expect(kpath, "true", v)
        return TriggerSpec(kind), {kind: True}
    text = ck.string(v, kpath)
    if kind == "at_station":
        return TriggerSpec(kind, station=text), {kind: text}
    return TriggerSpec(kind, switch=text), {kind: text}


def cooperative(ck: Checker, value: Any, services: Sequence[ServiceSpec]) -> tuple[CooperativeSpec, dict[str, Any]]:
    """``cooperative: {edges: [...]}`` → a :class:`CooperativeSpec` (raw ``until_s`` only when finite)."""
    m = ck.mapping(value, "cooperative", (), ("edges",))
    edges_in = m.get("edges") or []
    if not isinstance(edges_in, list):
        raise ck.expect("cooperative.edges", "a list of edges", edges_in)
    edges, raws = [], []
    for i, body in enumerate(edges_in):
        path = f"cooperative.edges[{i}]"
        e = ck.mapping(body, path, ("between", "d_m", "lower_m", "upper_m"), ("from_s", "until_s"))
        pair = e["between"]
        if not isinstance(pair, list) or len(pair) != 2:
            raise ck.expect(f"{path}.between", "a list of two trains [a, b] (x_a − x_b is constrained)", pair)
        a = trip_name(ck, pair[0], f"{path}.between[0]", services)
        b = trip_name(ck, pair[1], f"{path}.between[1]", services)
        if a == b:
            raise ck.fail(f"{path}.between", f"expected two different trains, got {a!r} twice")
        lower = ck.number(e["lower_m"], f"{path}.lower_m")
        upper = ck.number(e["upper_m"], f"{path}.upper_m")
        d = ck.number(e["d_m"], f"{path}.d_m")
        if not lower < d < upper:
            raise ck.fail(f"{path}.d_m", f"expected lower_m < d_m < upper_m ({lower} < d < {upper}), got {d}")
        frm, until = ck.window(e, path)
        edges.append(CooperativeEdge(a, b, d, lower, upper, frm, until))
        r = {"between": [a, b], "d_m": d, "lower_m": lower, "upper_m": upper, "from_s": frm}
        if math.isfinite(until):
            r["until_s"] = until
        raws.append(r)
    return CooperativeSpec(tuple(edges)), {"edges": raws}


def junction(
    ck: Checker, value: Any, services: Sequence[ServiceSpec], formations: Sequence[FormationSpec]
) -> tuple[JunctionSpec, dict[str, Any]]:
    """``junction:`` → a :class:`JunctionSpec`; its trains may not already be in a formation."""
    m = ck.mapping(
        value,
        "junction",
        ("trains",),
        ("method", "replan_s", "target_gap_m", "params", "pso", "replan_pso", "fixed_order"),
    )
    if not isinstance(m["trains"], list) or not 2 <= len(m["trains"]) <= 8:
        raise ck.expect("junction.trains", "a list of 2 to 8 trains (trip ids or one-trip service ids)", m["trains"])
    trains = [trip_name(ck, v, f"junction.trains[{i}]", services) for i, v in enumerate(m["trains"])]
    if len(set(trains)) != len(trains):
        raise ck.fail("junction.trains", f"a train is listed twice: {trains}")
    for f in formations:
        for ref in (f.leader, f.follower):
            tid = next(svc.trip_ids[ref.trip] for svc in services if svc.id == ref.service)
            if tid in trains:
                raise ck.fail(
                    "junction.trains",
                    f"{tid} is in formation {f.id!r}; the junction planner "
                    "forms the formations of its trains itself (in passing order)",
                )
    method = ck.string(m.get("method", "improved_pso"), "junction.method", JUNCTION_METHODS)
    replan = ck.number(m.get("replan_s", 2.0), "junction.replan_s", gt=0.0)
    gap = m.get("target_gap_m")
    gap = None if gap is None else ck.number(gap, "junction.target_gap_m", gt=0.0)
    params = dict(ck.free_mapping(m.get("params") or {}, "junction.params"))
    pso = dict(ck.free_mapping(m.get("pso") or {}, "junction.pso"))
    replan_pso = dict(ck.free_mapping(m.get("replan_pso") or {}, "junction.replan_pso"))
    ck.dataclass_fields(params, "junction.params", "controllers.junction.model", "JunctionParams")
    ck.dataclass_fields(pso, "junction.pso", "controllers.junction.pso", "PSOParams")
    ck.dataclass_fields(replan_pso, "junction.replan_pso", "controllers.junction.pso", "PSOParams")
    fixed = ck.boolean(m.get("fixed_order", False), "junction.fixed_order")
    if fixed and method in ("naive1", "naive2"):
        raise ck.fail("junction.fixed_order", f"the naive baselines choose their order by rule; method is {method!r}")
    spec = JunctionSpec(tuple(trains), method, replan, gap, params, pso, replan_pso, fixed)
    raw = {
        "trains": trains,
        "method": method,
        "replan_s": replan,
        "params": copy.deepcopy(params),
        "pso": copy.deepcopy(pso),
        "replan_pso": copy.deepcopy(replan_pso),
    }
    if gap is not None:
        raw["target_gap_m"] = gap
    if fixed:
        raw["fixed_order"] = True
    return spec, raw
