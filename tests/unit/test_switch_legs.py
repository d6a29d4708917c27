"""A connection that is a leg of two switches, built without SUMO: out of an edge that diverges, onto an edge that
others merge into. Both switches are on it (the second in ``also``), and a route through it locks both: with the
diverge alone, a tram on that connection and a tram on the merge's other leg were each given their own points and
met in the junction (Jena, node ``1831585450``: a collision).
"""

from __future__ import annotations

import networkx as nx

from network.net_switches import find_switches
from network.topology import make_route


def _junction() -> nx.DiGraph:
    """``a`` diverges onto ``b`` (straight) and ``c``; ``d`` merges onto ``c`` too, all at node ``n``."""
    g = nx.DiGraph()
    headings = {"a": 0.0, "b": 0.0, "c": 30.0, "d": 30.0}
    for e, h in headings.items():
        g.add_node(
            e,
            to_node="n",
            from_node="n",
            bidi=None,
            heading_in=h,
            heading_out=h,
            speed_mps=10.0,
            length_m=100.0,
            line=e,
            design_sign=1.0,
            design_start_m=0.0,
        )
    for a, b in (("a", "b"), ("a", "c"), ("d", "c")):
        g.add_edge(a, b, node="n", via=[[f":n_{a}{b}_0", 10.0, 10.0]], switch=None, leg=None, cost_m=10.0)
    return g


def test_a_connection_on_a_diverge_and_a_merge_carries_both_switches() -> None:
    g = _junction()
    switches = find_switches(g, throw_time_s=0.0)
    assert set(switches) == {"n/a", "n/c"}
    both = [(g.edges["a", "c"]["switch"], g.edges["a", "c"]["leg"]), *g.edges["a", "c"].get("also", [])]
    assert sorted(sid for sid, _ in both) == ["n/a", "n/c"], "the connection lost one of its two switches"
    merge_legs = {dict(both)["n/c"], g.edges["d", "c"]["leg"]}
    assert merge_legs == {"normal", "reverse"}, "the two ways into c are not told apart at the merge"


def test_a_route_through_it_locks_both() -> None:
    g = _junction()
    find_switches(g, throw_time_s=0.0)
    route = make_route(g, "r", ["a", "c"])
    assert sorted(s.switch_id for s in route.switches) == ["n/a", "n/c"]
    assert {s.point_m for s in route.switches} == {100.0}
