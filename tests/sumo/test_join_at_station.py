"""Joining at a station (``couple: {at_station: X}``) and formations that cannot couple where they asked.

Real SUMO runs of the mini line (:file:`tests/data/scenarios/mini_line.yaml`, 220 m platforms, 89.4 m units):

* the leader ``lead.000`` (A → E) stops at C; its follower ``fol.000`` leaves A later and is due at C 60 s after
  the leader's dwell there ends. The leader stays at C (``departure_held_for_follower``), the follower runs in
  behind it and halts the target gap behind it, the pair couples standing and leaves C together; it keeps the
  coupled controller's gap after that;
* the same with the follower 400 s late and a 120 s coupling timeout: the leader waits 120 s, leaves alone, and a
  ``coupling_failed`` event says ``timeout``; the summary's ``formations_asked`` block says where it was asked and
  why it did not couple;
* the follower at C before its leader: ``wrong_order``, and the leader does not wait there;
* a train of its own between the two: the join is given up (``blocked``, naming it) and the leader does not wait;
* ``couple: {after_switch: c_down}`` with the follower (the branch unit) reaching the merge long before its
  leader: it waits there one coupling timeout (``merge_wait_for_leader``, ``merge_wait_ended``), then goes first
  and a ``coupling_failed`` event says ``wrong_order``;
* a platform too short for the pair is refused before the run, naming the field and the lengths.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from tests.helpers import mini_line, read_csv, read_summary, run_mapping

DT_S = 0.5
DWELL_S = 20.0
GAP_M = 30.0
LEADER, FOLLOWER = "lead.000", "fol.000"


def _join_world(follower_depart_s: float, timeout_s: float | None = None) -> dict[str, Any]:
    """Two trips A → E, both stopping at C; the follower joins its leader at C."""
    data = mini_line()
    data["services"] = [
        {"id": "lead", "from": "a", "to": "e", "vehicle": "cq6", "departures": {"times": [0]}, "dwell_s": DWELL_S},
        {
            "id": "fol",
            "from": "a",
            "to": "e",
            "vehicle": "cq6",
            "departures": {"times": [follower_depart_s]},
            "dwell_s": DWELL_S,
        },
    ]
    formation: dict[str, Any] = {
        "id": "join",
        "leader": {"service": "lead", "trip": 0},
        "follower": {"service": "fol", "trip": 0},
        "target_gap_m": GAP_M,
        "couple": {"at_station": "c"},
    }
    if timeout_s is not None:
        formation["coupling_timeout_s"] = timeout_s
    data["formations"] = [formation]
    return data


def _run(tmp_path: Path, name: str, data: dict[str, Any]) -> tuple[Path, list[dict[str, str]]]:
    res, out = run_mapping(tmp_path, data, name)
    assert res.returncode == 0, res.stderr
    summary = read_summary(out)
    assert summary["collisions"] == 0 and summary["n_arrived"] == summary["n_trains"]
    return out, read_csv(out / "events.csv")


def _at(out: Path, station: str) -> dict[str, dict[str, str]]:
    return {r["trip_id"]: r for r in read_csv(out / "stops.csv") if r["station"] == station}


def _kinds(events: list[dict[str, str]], kind: str, subject: str) -> list[dict[str, Any]]:
    return [json.loads(e["detail"] or "{}") for e in events if e["kind"] == kind and e["subject"] == subject]


def test_a_leader_waits_at_the_station_and_the_pair_leaves_together(tmp_path: Path) -> None:
    # the follower leaves A 80 s after the leader: due at C 80 s after the leader, 60 s after its dwell there ends
    out, events = _run(tmp_path, "late60", _join_world(80.0))
    at_c = _at(out, "c")
    lead, fol = at_c[LEADER], at_c[FOLLOWER]
    lead_dwell_end_s = float(lead["arrival_s"]) + DWELL_S
    assert float(fol["arrival_s"]) - lead_dwell_end_s == pytest.approx(60.0, abs=15.0)
    held = _kinds(events, "departure_held_for_follower", LEADER)
    assert len(held) == 1 and held[0]["station"] == "c"
    assert len(_kinds(events, "coupled", "join")) == 1
    assert not _kinds(events, "coupling_failed", "join")
    # they leave C together (the leader in the follower's step or the next) after the follower's own dwell
    dep_lead, dep_fol = float(lead["departure_s"]), float(fol["departure_s"])
    assert abs(dep_lead - dep_fol) <= DT_S
    assert dep_fol - float(fol["arrival_s"]) >= DWELL_S
    # the follower halted the target gap behind the leader: the coupled gap at C, and on the line after it
    trace = [r for r in read_csv(out / "trace.csv") if r["train"] == FOLLOWER]
    standing = [float(r["gap_m"]) for r in trace if dep_fol - 10.0 <= float(r["t_s"]) <= dep_fol - 1.0]
    assert standing and all(abs(g - GAP_M) <= 2.0 for g in standing)
    # leaving C the pair stays together: the gap grows only to the coupled controller's gap policy at line speed
    # (relative braking distance + 2 m, ~46 m at 70 km/h) — a unit left behind at the points ran ~200 m back
    after = [r for r in trace if dep_fol <= float(r["t_s"]) <= dep_fol + 90.0]
    assert after and all(r["formation_state"] == "coupled" for r in after)
    assert all(GAP_M - 2.0 <= float(r["gap_m"]) <= 55.0 for r in after)
    summary = read_summary(out)
    row = summary["formations"]["join"]
    assert row["final_state"] == "coupled" and row["min_gap_m"] >= GAP_M - 2.0
    assert summary["formations_asked"] == [
        {"id": "join", "asked": "at_station c", "coupled": True, "where": "at_station c", "reason": None}
    ]


def test_a_follower_too_late_ends_the_wait_after_the_timeout_and_says_why(tmp_path: Path) -> None:
    timeout_s = 120.0
    out, events = _run(tmp_path, "late400", _join_world(420.0, timeout_s=timeout_s))
    at_c = _at(out, "c")
    lead, fol = at_c[LEADER], at_c[FOLLOWER]
    lead_dwell_end_s = float(lead["arrival_s"]) + DWELL_S
    assert float(fol["arrival_s"]) - lead_dwell_end_s == pytest.approx(400.0, abs=15.0)
    # the leader waits one coupling timeout after its dwell, then leaves alone
    assert float(lead["departure_s"]) == pytest.approx(lead_dwell_end_s + timeout_s, abs=3.0)
    failed = _kinds(events, "coupling_failed", "join")
    assert len(failed) == 1 and failed[0]["reason"] == "timeout" and failed[0]["station"] == "c"
    assert not _kinds(events, "coupled", "join")
    summary = read_summary(out)
    assert summary["formations_asked"] == [
        {"id": "join", "asked": "at_station c", "coupled": False, "where": None, "reason": "timeout"}
    ]


def test_a_follower_at_the_station_before_its_leader_is_a_wrong_order(tmp_path: Path) -> None:
    data = _join_world(0.0)
    data["services"][0]["departures"] = {"times": [80]}  # the leader leaves A 80 s after its follower
    out, events = _run(tmp_path, "reversed", data)
    failed = _kinds(events, "coupling_failed", "join")
    assert len(failed) == 1 and failed[0]["reason"] == "wrong_order" and failed[0]["station"] == "c"
    assert not _kinds(events, "departure_held_for_follower", LEADER)
    assert read_summary(out)["formations_asked"][0]["reason"] == "wrong_order"


def test_a_train_between_leader_and_follower_ends_the_wait_and_says_why(tmp_path: Path) -> None:
    data = _join_world(120.0)
    # a train of its own (no formation) leaves A between the two: it, not the follower, comes up behind the leader
    data["services"].insert(
        1, {"id": "mid", "from": "a", "to": "e", "vehicle": "cq6", "departures": {"times": [60]}, "dwell_s": DWELL_S}
    )
    out, events = _run(tmp_path, "between", data)
    failed = _kinds(events, "coupling_failed", "join")
    assert len(failed) == 1 and failed[0]["reason"] == "blocked" and failed[0]["by"] == "mid.000"
    assert not _kinds(events, "coupled", "join")
    # the leader does not keep the train between them waiting: it leaves C on its own dwell
    lead = _at(out, "c")[LEADER]
    assert float(lead["departure_s"]) <= float(lead["arrival_s"]) + DWELL_S + 3.0
    assert read_summary(out)["formations_asked"][0]["reason"] == "blocked"


def test_a_follower_first_at_the_merge_is_a_reason_not_silence(tmp_path: Path) -> None:
    data = mini_line()
    # down trains: the branch unit br_down.000 (from G at 60 s, over c_down onto the main line) reaches the merge
    # long before main_down.001 (from E at 150 s), the leader it asks to couple behind after the merge. It waits
    # for its leader at the merge, but no longer than its 60 s coupling timeout: then it goes first
    data["formations"] = [
        {
            "id": "merge",
            "leader": {"service": "main_down", "trip": 1},
            "follower": {"service": "br_down", "trip": 0},
            "target_gap_m": GAP_M,
            "couple": {"after_switch": "c_down"},
            "coupling_timeout_s": 60,
        }
    ]
    res, out = run_mapping(tmp_path, data, "merge_first")
    assert res.returncode == 0, res.stderr
    events = read_csv(out / "events.csv")
    (wait,) = _kinds(events, "merge_wait_for_leader", "br_down.000")
    assert wait["leader"] == "main_down.001" and wait["limit_s"] == 60.0
    (ended,) = _kinds(events, "merge_wait_ended", "br_down.000")
    assert ended["reason"] == "timeout" and ended["waited_s"] == pytest.approx(60.0, abs=0.6)
    failed = _kinds(events, "coupling_failed", "merge")
    assert len(failed) == 1 and failed[0]["reason"] == "wrong_order" and failed[0]["switch"] == "c_down"
    summary = read_summary(out)
    assert summary["formations_asked"][0]["reason"] == "wrong_order"
    assert "formations coupled where asked: 0/1, 1 wrong_order" in res.stdout


def test_a_platform_too_short_for_the_pair_is_refused_before_the_run(tmp_path: Path) -> None:
    data = _join_world(80.0)
    data["formations"][0]["target_gap_m"] = 60.0  # 89.4 + 60 + 89.4 + 1 m > the 220 m platform
    res, out = run_mapping(tmp_path, data, "short")
    assert res.returncode == 2, res.stderr
    assert "formations[0].couple.at_station: expected a platform the pair fits on, got 220.0 m" in res.stderr
    assert "the pair needs 239.8 m" in res.stderr
    assert not (out / "summary.json").exists()
