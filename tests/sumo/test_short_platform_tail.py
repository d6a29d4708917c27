"""A train is not put on into the tail of a train standing at (or just leaving) a platform shorter than itself.

SUMO puts a train on at a short platform with its tail on the track before the platform's edge, which is not on
the train's route. Another train put on at a platform on that track used to be checked only against the
trains whose *routes* hold its spot, so it was put on 25 m into that tail (SUMO's ``tools/game/bs3d`` OSM net in
``benchmarks/external_nets_survey.py``: a ``collision`` event, which SUMO — knowing no tail off the route —
did not report). The dispatcher now also maps the standing train's body onto the new train's route.

The world: a 60 m platform P1 and right behind it a 30 m platform P2 (OSM-style short platforms), an 89.4 m
train leaving P2 at 0 s and one due at P1 at 5 s, when the first one's tail still covers P1: it used to be put on
at once, its front 56 m deep in that tail; now it waits until the tail is clear.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import read_csv, read_summary, run_railsim
from tests.sumo.test_external_net import _COMMON, _edge, _netconvert, _service, _stops, _write


def test_a_train_waits_for_the_tail_of_a_train_leaving_the_next_short_platform(tmp_path: Path) -> None:
    nodes = "\n".join(
        f'<node id="{n}" x="{x}" y="0"/>' for n, x in (("A", 0), ("J1", 400), ("J2", 460), ("J3", 490), ("B", 2500))
    )
    edges = [_edge("X", "A", "J1"), _edge("P1", "J1", "J2"), _edge("P2", "J2", "J3"), _edge("Y", "J3", "B")]
    net = _netconvert(tmp_path, "tail", nodes, "\n".join(edges))
    stops = _stops(
        tmp_path,
        "tail",
        [("p1", "P1_0", 0, 59, "One"), ("p2", "P2_0", 0, 29, "Two"), ("b", "Y_0", 1700, 1950, "Bravo")],
    )
    raw = {"name": "tail", "world": {"net": str(net), "additional": [str(stops)]}, **_COMMON}
    raw["services"] = [_service("first", "two", "bravo", 0), _service("second", "one", "bravo", 5)]
    scn = _write(tmp_path, "tail.yaml", yaml.safe_dump(raw, sort_keys=False))
    out = tmp_path / "out"
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], cache_dir=tmp_path / "c")
    events = read_csv(out / "events.csv") if (out / "events.csv").exists() else []
    assert not [e for e in events if e["kind"] == "collision"], [e for e in events if e["kind"] == "collision"]
    assert res.returncode == 0, res.stderr
    s = read_summary(out)
    assert s["collisions"] == 0 and s["n_arrived"] == 2
    # where the first train was when the second one was put on: its rear (89.4 m behind its front, in its route's
    # frame where P2 begins at 0) must lie beyond the second one's front (2 m before P2, the end of P1)
    (put_on,) = [float(e["t_s"]) for e in events if e["kind"] == "train_inserted" and e["subject"] == "second.000"]
    first = [r for r in read_csv(out / "trace.csv") if r["train"] == "first.000" and float(r["t_s"]) <= put_on]
    rear_m = float(first[-1]["chainage_m"]) - 89.4
    assert rear_m > -2.0, (
        f"the second train was put on at {put_on} s into the first one's tail (its rear at {rear_m:.1f} m)"
    )
    held = [e for e in events if e["kind"] == "departure_held" and e["subject"] == "second.000"]
    assert held and "first.000" in held[0]["detail"], held


def test_a_pair_that_cannot_start_at_a_dead_end_platform_is_refused_with_the_way_past(tmp_path: Path) -> None:
    """A leader and follower coupled from their origin need 89.4 + 30 + 89.4 m; at a 99 m platform at a dead end
    the follower's rear would lie before its route: refused before the run, naming what the user can do."""
    nodes = '<node id="A" x="0" y="0"/>\n<node id="B" x="100" y="0"/>\n<node id="C" x="2500" y="0"/>'
    net = _netconvert(tmp_path, "end", nodes, "\n".join([_edge("AB", "A", "B"), _edge("BC", "B", "C")]))
    stops = _stops(tmp_path, "end", [("a", "AB_0", 0, 99, "Alpha"), ("c", "BC_0", 2000, 2300, "Charlie")])
    raw = {"name": "end", "world": {"net": str(net), "additional": [str(stops)]}, **_COMMON}
    raw["services"] = [_service("lead", "alpha", "charlie", 0), _service("follow", "alpha", "charlie", 0)]
    raw["formations"] = [
        {
            "id": "pair",
            "leader": {"service": "lead", "trip": 0},
            "follower": {"service": "follow", "trip": 0},
            "target_gap_m": 30,
            "couple": {"on_departure": True},
        }
    ]
    scn = _write(tmp_path, "end.yaml", yaml.safe_dump(raw, sort_keys=False))
    res = run_railsim(["validate", str(scn)], cache_dir=tmp_path / "c")
    assert res.returncode == 2, res.stderr
    assert "cannot start 30 m behind" in res.stderr and "couple it later" in res.stderr, res.stderr
