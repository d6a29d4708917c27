"""A unit that arrives at the very platform its next trip leaves from departs where it stands.

A tram terminus with one platform on a turning loop (Jena's Winzerla and Lobeda-West): the trams arrive at the
platform and leave from it the same way, round the loop. The unit needs no turning move, yet the turnback path
was searched from the platform's edge to itself: where a reversal was in reach, the unit ran out along the line to
it and back (at Winzerla 7.9 km, after which SUMO had no stop left for it at its platform and the peak stalled);
where none was, the two trips could not be chained at all. Generated world: a double-track line Aston-Bury whose
Bury end is a loop with the platform on its first edge.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import read_csv, read_summary
from tests.sumo.test_external_net import _edge, _netconvert, _stops
from tests.sumo.test_turnback import STEP_S, _events, _invoke, _service


def build_loop_terminus(folder: Path) -> tuple[Path, Path]:
    """Double track Aston-Bury (3 km); at Bury the up track runs onto the loop ``P`` (platform), round and back
    onto the down track."""
    nodes = "\n".join(
        [
            '<node id="A" x="0" y="0"/>',
            '<node id="B" x="3000" y="0"/>',
            '<node id="C" x="3400" y="0"/>',
            '<node id="D" x="3400" y="-300"/>',
        ]
    )
    edges = [
        _edge("u1", "A", "B", spread="right"),
        _edge("d1", "B", "A", spread="right"),
        _edge("P", "B", "C"),
        _edge("CD", "C", "D"),
        _edge("DB", "D", "B"),
    ]
    cons = "\n".join(
        [
            '<connection from="u1" to="P"/>',
            '<connection from="P" to="CD"/>',
            '<connection from="CD" to="DB"/>',
            '<connection from="DB" to="d1"/>',
        ]
    )
    net = _netconvert(folder, "loopterm", nodes, "\n".join(edges), cons)
    stops = _stops(
        folder,
        "loopterm",
        [("a_out", "u1_0", 100, 400, "Aston"), ("bury", "P_0", 50, 350, "Bury"), ("a_in", "d1_0", 2600, 2900, "Aston")],
    )
    return net, stops


def test_a_unit_at_its_departure_platform_departs_where_it_stands(tmp_path: Path) -> None:
    net, stops = build_loop_terminus(tmp_path)
    services = [_service("out", "Aston", "Bury", [0]), _service("back", "Bury", "Aston", [600])]
    out, res = _invoke(tmp_path, net, stops, services, {"units": "auto", "turnback_min_s": 120})
    assert res.returncode == 0, res.stderr + res.stdout  # type: ignore[attr-defined]
    assert "no unit can turn at bury" not in res.stderr + res.stdout  # type: ignore[attr-defined]
    fleet = read_summary(out)["fleet"]
    assert fleet["units_used"] == 1 and fleet["trips_per_unit"] == {"unit01": 2}
    (turn,) = _events(out, "unit_turnback")
    assert yaml.safe_load(turn["detail"])["in_place"] is True
    assert not _events(out, "reversed") and not _events(out, "reversal_halt")
    (row,) = fleet["turnbacks"]
    assert row["achieved_s"] >= row["min_s"] and abs(row["departed_s"] - 600.0) <= STEP_S + 1e-9
    trips = {r["trip_id"]: r for r in read_csv(out / "trips.csv")}
    assert all(r["arrival_s"] != "" for r in trips.values())
    assert read_summary(out)["collisions"] == 0
