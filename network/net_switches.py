"""Switches of a SUMO net's track graph: where a track diverges or merges, which leg is normal, one lock per turnout.

A switch is a SUMO node where a rail edge leads to two or more rail edges (a *diverge*) or two or more lead to one
(a *merge*); there is one :class:`~network.topology.SwitchInfo` per direction of travel. The **normal leg** is the
straightest (smallest heading change across the node, then the higher speed, then the edge id); every other leg is
``reverse``. On ``bidi`` track the diverge in one direction and the merge in the other are the same physical
turnout: they become one switch, whose id both directions' connections carry, so the interlocking never lets two
opposing trains use the points at once. Switch ids are the SUMO node id, or ``<node>/<trunk edge>`` where a node
has several switches. A connection can be a leg of two switches — out of an edge that diverges, onto an edge that
others merge into: it carries both (the second in ``also``) and a route through it locks both (with the diverge
alone, a train on it and one on the merge's other leg were each given their own points and met in the junction:
Jena, node ``1831585450``). The diverging and normal speeds come from the connections' internal lanes.
"""

from __future__ import annotations

import math
from typing import Any

import networkx as nx

from network.plane import turn_rad
from network.topology import SwitchInfo


def _legs(g: nx.DiGraph, trunk: str, legs: list[str], diverge: bool) -> list[str]:
    """Legs ordered normal first: smallest heading change across the node, then higher speed, then id."""

    def key(leg: str) -> tuple[float, float, str]:
        if diverge:
            turn = turn_rad(g.nodes[trunk]["heading_in"], g.nodes[leg]["heading_out"])
            via = g.edges[trunk, leg]["via"]
        else:
            turn = turn_rad(g.nodes[leg]["heading_in"], g.nodes[trunk]["heading_out"])
            via = g.edges[leg, trunk]["via"]
        speed = min([g.nodes[leg]["speed_mps"]] + [v[2] for v in via])
        return (round(math.degrees(turn), 1), -round(speed, 3), leg)

    return sorted(legs, key=key)


def _leg_speed(g: nx.DiGraph, a: str, b: str) -> float:
    return float(min([g.nodes[a]["speed_mps"], g.nodes[b]["speed_mps"]] + [v[2] for v in g.edges[a, b]["via"]]))


def _set_switch(conn: dict[str, Any], switch_id: str, leg: str) -> None:
    """A connection is a leg of ``switch_id``; one already a leg of another switch (a diverge's leg that is a merge's
    too) keeps that one in ``also``."""
    if conn.get("switch") not in (None, switch_id):
        conn.setdefault("also", []).append((conn["switch"], conn["leg"]))
    conn["switch"], conn["leg"] = switch_id, leg


def find_switches(g: nx.DiGraph, throw_time_s: float) -> dict[str, SwitchInfo]:
    """Switches of the track graph (module docstring); sets ``switch``/``leg`` on the graph's connections."""
    found: list[dict[str, Any]] = []  # kind, node, trunk, legs (normal first)
    for eid in g.nodes:
        outs = sorted(g.successors(eid))
        if len(outs) >= 2:
            found.append(
                {"kind": "diverge", "node": g.nodes[eid]["to_node"], "trunk": eid, "legs": _legs(g, eid, outs, True)}
            )
        ins = sorted(g.predecessors(eid))
        if len(ins) >= 2:
            found.append(
                {"kind": "merge", "node": g.nodes[eid]["from_node"], "trunk": eid, "legs": _legs(g, eid, ins, False)}
            )
    bidi = {n: a["bidi"] for n, a in g.nodes(data=True)}
    # the other direction of a turnout on bidi track: a merge onto the trunk's partner from the legs' partners
    twin_of: dict[int, int] = {}
    for i, d in enumerate(found):
        if d["kind"] != "diverge":
            continue
        for j, m in enumerate(found):
            if (
                m["kind"] == "merge"
                and m["trunk"] == bidi[d["trunk"]]
                and sorted(m["legs"]) == sorted(bidi[x] or "" for x in d["legs"])
            ):
                twin_of[j] = i
    primary = [i for i in range(len(found)) if i not in twin_of]
    per_node: dict[str, int] = {}
    for i in primary:
        per_node[found[i]["node"]] = per_node.get(found[i]["node"], 0) + 1
    ids: dict[int, str] = {}
    for i in primary:
        d = found[i]
        ids[i] = d["node"] if per_node[d["node"]] == 1 else f"{d['node']}/{d['trunk']}"
    switches: dict[str, SwitchInfo] = {}
    for i in primary:
        d = found[i]
        trunk, legs = d["trunk"], d["legs"]
        pairs = [(trunk, x) if d["kind"] == "diverge" else (x, trunk) for x in legs]
        for k, (a, b) in enumerate(pairs):
            _set_switch(g.edges[a, b], ids[i], "normal" if k == 0 else "reverse")
        switches[ids[i]] = SwitchInfo(
            id=ids[i],
            sumo_node=d["node"],
            kind=d["kind"],
            normal_edge=legs[0],
            reverse_edge=legs[1],
            trunk_edge=trunk,
            throw_time_s=float(throw_time_s),
            diverging_speed_mps=min(_leg_speed(g, a, b) for a, b in pairs[1:]),
            normal_speed_mps=_leg_speed(g, *pairs[0]),
        )
    for j, i in twin_of.items():
        m, d = found[j], found[i]
        for x in m["legs"]:
            leg = "normal" if bidi[x] == d["legs"][0] else "reverse"
            _set_switch(g.edges[x, m["trunk"]], ids[i], leg)
    return dict(sorted(switches.items()))
