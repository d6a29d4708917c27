"""The dynamic communication graph of Paper C (spec 002 §7.1): oriented edge data, queries, events, d-consistency."""

from __future__ import annotations

from dataclasses import replace

import pytest

from controllers.distributed import (
    CommGraph,
    Edge,
    EdgeAdd,
    EdgeData,
    EdgeRemove,
    PreconditionError,
    TrainJoin,
    TrainLeave,
    apply_event,
    check_assumptions,
    simulate,
    zhang2024_fig1,
    zhang2024_train,
)
from controllers.distributed.graph import sort_events

E = EdgeData(5000.0, 100.0, 10000.0)


def test_oriented_views_and_queries() -> None:
    g = CommGraph.build("abc", [Edge("a", "b", E), Edge("c", "b", E)])
    assert g.neighbours("b") == ("a", "c") and g.degree("b") == 2 and g.neighbours("a") == ("b",)
    assert g.oriented("a", "b") == E
    assert g.oriented("b", "a") == EdgeData(-5000.0, -10000.0, -100.0)  # d_ji = −d_ij, γ̲_ji = −γ̄_ij
    assert g.oriented("b", "c") == E.reversed() and E.reversed().reversed() == E
    assert g.is_connected() and not g.has_edge("a", "c")
    with pytest.raises(ValueError, match="stated twice"):
        CommGraph.build("ab", [Edge("a", "b", E), Edge("b", "a", E.reversed())])
    with pytest.raises(ValueError, match="self-loops"):
        CommGraph.build("a", [Edge("a", "a", E)])
    with pytest.raises(ValueError, match="not in the graph"):
        CommGraph.build("a", [Edge("a", "z", E)])


def test_d_consistency_around_cycles() -> None:
    ok = CommGraph.build("abc", [Edge("a", "b", E), Edge("b", "c", E), Edge("a", "c", EdgeData(1e4, 5100.0, 15000.0))])
    offsets, mismatches = ok.node_offsets()
    assert mismatches == [] and offsets["a"] - offsets["c"] == 1e4
    bad = CommGraph.build(
        "abc", [Edge("a", "b", E), Edge("b", "c", E), Edge("c", "a", EdgeData(-9990.0, -15000.0, -5100.0))]
    )
    _, mismatches = bad.node_offsets()
    assert len(mismatches) == 1 and abs(mismatches[0][2]) == 10.0
    p = zhang2024_train()
    viol = check_assumptions(bad, {n: p for n in "abc"}, 1.0, 80.0)
    assert [(v.assumption, v.field) for v in viol] == [("Assumption 2.2", viol[0].field)]
    assert viol[0].field.endswith(".d_m") and "sums to 10 m" in viol[0].message


def test_events_apply_in_a_fixed_order() -> None:
    p = zhang2024_train()
    g = CommGraph.build("abc", [Edge("a", "b", E), Edge("b", "c", E)])
    events = sort_events(
        [
            EdgeAdd(3, Edge("a", "c", EdgeData(1e4, 5100.0, 15000.0))),
            TrainLeave(3, "b"),
            TrainJoin(5, "d", 0.0, 80.0, p, (Edge("c", "d", E),)),
            EdgeRemove(7, "c", "d"),
        ]
    )
    assert [type(e).__name__ for e in events] == ["TrainLeave", "EdgeAdd", "TrainJoin", "EdgeRemove"]
    for e in events[:2]:
        g = apply_event(g, e)
    assert g.nodes == {"a", "c"} and g.neighbours("a") == ("c",)
    g = apply_event(g, events[2])
    assert g.neighbours("c") == ("a", "d")
    g = apply_event(g, events[3])
    assert not g.is_connected() and len(g.components()) == 2
    with pytest.raises(ValueError, match="does not touch"):
        apply_event(g, TrainJoin(9, "e", 0.0, 80.0, p, (Edge("a", "c", E),)))


def test_a_leave_that_disconnects_the_graph_is_rejected_before_running() -> None:
    s = zhang2024_fig1("path")
    # path reading without the added 1-3 edge: train 1 is cut off when train 2 leaves
    events = tuple(e for e in s.events if not isinstance(e, EdgeAdd))
    with pytest.raises(PreconditionError) as err:
        simulate(replace(s, events=events))
    v = err.value.violations[0]
    assert (
        v.assumption == "Assumption 2.1" and "after the events of k = 1000" in v.message and "1 | 3,4,5,6" in v.message
    )
    log = simulate(replace(s, events=events, horizon_k=999))  # never reached: the run is fine
    assert log.violations() == []
