"""Formations that couple after a merge of two lines (``couple: {after_switch: c_down}``), real SUMO runs.

The world is a generated Y (:file:`tests/data/lines/merge_y.yaml`): down trains from E on the main line and from G
on the branch merge at ``c_down`` (km 5.2; the branch leg is the switch's ``reverse`` leg, 30 km/h, 15 s throw)
and serve C (1.2 km past the merge), B and A. A formation's leader comes from E, its follower from G. Checked from
the recorded files, each case failing on the engine that granted the merge first come, first served:

* **in order** (the leader is first at the merge): the interlocking grants ``c_down`` to the leader, then to the
  follower; the follower asks to couple once close behind its leader, which waits at C; the pair couples and
  leaves C together;
* **reverse order** (the follower would be first): the follower waits before the merge for its leader
  (``merge_wait_for_leader``, ``merge_wait_ended`` with ``leader_asked``), passes it right after it and couples;
* **a third train between them**: an unrelated train from E, behind the leader, would take the merge before the
  follower (first come, first served: the formation was ``blocked``); it is held back until the follower asked
  and passes the merge after the pair;
* **two formations and unrelated trains sharing the merge**: both formations couple in their own order;
* **two formations crossed at the merge** (each leader ahead of the other's follower on its leg): at most one can
  couple; the one whose leader waited first keeps its order, the other gives way at once (``merge_crossed``) and
  fails as ``blocked`` — on the engine before, each leader waited for the other until the wait limit (270 s).

Every case: 0 collisions, 0 switch violations, every train arrived, ``formations_asked`` says coupled where asked.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tests.helpers import merge_world, read_csv, read_summary, run_clean

SWITCH = "c_down"
GAP_M = 30.0


def _run(tmp_path: Path, name: str, data: dict[str, Any]) -> tuple[Path, list[dict[str, Any]]]:
    return run_clean(tmp_path, data, name)


def _grants(events: list[dict[str, Any]]) -> list[str]:
    return [h for e in events if e["kind"] == "lock_granted" and e["subject"] == SWITCH for h in e["detail"]["holders"]]


def _coupled_where_asked(out: Path) -> dict[str, bool]:
    rows = read_summary(out)["formations_asked"]
    assert all(r["asked"] == f"after_switch {SWITCH}" for r in rows)
    return {r["id"]: r["coupled"] and r["where"] == f"after_switch {SWITCH}" for r in rows}


def _kinds(events: list[dict[str, Any]], kind: str) -> list[dict[str, Any]]:
    return [e for e in events if e["kind"] == kind]


def _left_together(out: Path, station: str, a: str, b: str) -> bool:
    stops = {(r["trip_id"], r["station"]): r for r in read_csv(out / "stops.csv")}
    return abs(float(stops[(a, station)]["departure_s"]) - float(stops[(b, station)]["departure_s"])) <= 0.5


def test_a_formation_in_order_couples_after_the_merge(tmp_path: Path) -> None:
    out, events = _run(tmp_path, "in_order", merge_world([(0.0, 40.0)]))
    assert _grants(events) == ["lead.000", "fol.000"]
    (req,) = _kinds(events, "couple_requested")
    first_grant_to_follower = next(
        e
        for e in events
        if e["kind"] == "lock_granted" and e["subject"] == SWITCH and e["detail"]["holders"] == ["fol.000"]
    )
    assert req["t_s"] > first_grant_to_follower["t_s"]  # asked past the merge
    assert len(_kinds(events, "coupled")) == 1 and not _kinds(events, "coupling_failed")
    assert _coupled_where_asked(out) == {"m0": True}
    assert _left_together(out, "c", "lead.000", "fol.000")
    # coupled from C on: the follower keeps the coupled gap policy behind its leader (relative braking distance)
    trace = [r for r in read_csv(out / "trace.csv") if r["train"] == "fol.000" and r["formation_state"] == "coupled"]
    assert trace and all(GAP_M - 2.0 <= float(r["gap_m"]) <= 60.0 for r in trace if r["gap_m"])


def test_a_follower_first_at_the_merge_waits_for_its_leader_and_couples(tmp_path: Path) -> None:
    out, events = _run(tmp_path, "reverse", merge_world([(60.0, 0.0)]))
    (wait,) = [e for e in _kinds(events, "merge_wait_for_leader") if e["subject"] == "fol.000"]
    assert wait["detail"]["leader"] == "lead.000" and wait["detail"]["switch"] == SWITCH
    (ended,) = _kinds(events, "merge_wait_ended")
    assert ended["detail"]["reason"] == "leader_asked" and ended["t_s"] > wait["t_s"]
    assert _grants(events) == ["lead.000", "fol.000"]
    assert len(_kinds(events, "coupled")) == 1 and not _kinds(events, "coupling_failed")
    assert _coupled_where_asked(out) == {"m0": True}
    assert _left_together(out, "c", "lead.000", "fol.000")


def test_a_third_train_behind_the_leader_is_held_until_the_follower_asked(tmp_path: Path) -> None:
    # mid.000 leaves E 60 s after the leader; first come, first served it asked for c_down as the leader's rear
    # passed, before the follower (which asks when it leaves F), and ran between them: "blocked"
    out, events = _run(tmp_path, "third", merge_world([(0.0, 140.0)], others=[("mid", "e", 60.0)]))
    assert _grants(events) == ["lead.000", "fol.000", "mid.000"]
    assert len(_kinds(events, "coupled")) == 1 and not _kinds(events, "coupling_failed")
    assert _coupled_where_asked(out) == {"m0": True}
    assert not _kinds(events, "merge_priority_lapsed")


def test_two_formations_and_unrelated_trains_share_the_merge(tmp_path: Path) -> None:
    # m0 in order, m1 in reverse order; an unrelated train on each leg between the two formations
    data = merge_world(
        [(0.0, 40.0), (420.0, 330.0)], others=[("main_x", "e", 200.0), ("br_x", "g", 230.0)], duration_s=2400.0
    )
    out, events = _run(tmp_path, "shared", data)
    assert _coupled_where_asked(out) == {"m0": True, "m1": True}
    assert len(_kinds(events, "coupled")) == 2 and not _kinds(events, "coupling_failed")
    grants = _grants(events)
    for lead, fol in (("lead.000", "fol.000"), ("lead.001", "fol.001")):
        assert grants.index(fol) == grants.index(lead) + 1  # nobody between a leader and its follower
    assert {"main_x.000", "br_x.000"} <= set(grants)


def test_two_crossed_formations_one_gives_way_at_once_and_the_other_couples(tmp_path: Path) -> None:
    # m0: leader from E, follower from G; x1 the other way round: leader from G, follower from E. x1's leader is
    # ahead of m0's follower on G and m0's leader ahead of x1's follower on E, so one pair must be split
    data = merge_world([(0.0, 40.0)], duration_s=2400.0)
    data["services"] += [
        {"id": "lead_g", "from": "g", "to": "a", "vehicle": "cq6", "departures": {"times": [20.0]}, "dwell_s": 20},
        {"id": "fol_e", "from": "e", "to": "a", "vehicle": "cq6", "departures": {"times": [30.0]}, "dwell_s": 20},
    ]
    data["formations"].append(
        {
            "id": "x1",
            "leader": {"service": "lead_g", "trip": 0},
            "follower": {"service": "fol_e", "trip": 0},
            "target_gap_m": GAP_M,
            "couple": {"after_switch": SWITCH},
        }
    )
    out, events = _run(tmp_path, "crossed", data)
    (yields,) = _kinds(events, "merge_leader_yields")
    (crossed,) = _kinds(events, "merge_crossed")
    assert yields["detail"]["formation"] == "x1"  # x1's leader waited first: x1 keeps its order
    assert crossed["detail"] == {"formation": "m0", "gives_way_to": "x1", "switch": SWITCH}
    assert crossed["t_s"] - yields["t_s"] < 30.0  # decided as soon as both leaders are near, not after a wait limit
    assert _grants(events) == ["lead.000", "lead_g.000", "fol_e.000", "fol.000"]
    assert _coupled_where_asked(out) == {"m0": False, "x1": True}
    (failed,) = _kinds(events, "coupling_failed")
    assert failed["subject"] == "m0" and failed["detail"]["reason"] == "blocked"
    assert not _kinds(events, "merge_wait_for_leader") and not _kinds(events, "merge_priority_lapsed")
