"""Down Jurenba units couple behind an Airport unit at the Bijin merge (``chongqing_line3_peak_merge``).

One pair of the scenario, cut short (both end at Huixing, two stations past Bijin), runs in SUMO in a child
process. What is checked comes from the recorded files: the Airport unit takes the ``bijin_down`` lock first and
the Jurenba unit only after the switch was thrown; the couple request comes once the Jurenba unit is past the
switch (``couple: {after_switch: bijin_down}``); the pair couples while standing at Bijin, leaves Bijin together
and arrives coupled; no collision, no switch violation. The run says why it couples standing and not on the run
(``coupling_on_run_infeasible``: its follower may pass the merge only after its leader must already hold the
coupled state before standing at Bijin), in the events, the summary and the terminal. A misspelt switch in the
trigger is refused (exit 2).
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tests.helpers import ROOT, read_csv, read_events, read_summary, run_railsim

SCENARIO = ROOT / "scenarios" / "chongqing_line3_peak_merge.yaml"


def _one_pair(tmp: Path, couple: dict[str, str] | None = None) -> Path:
    """The scenario's down pair (its services, offsets, dwell and formation) with one trip each, to Huixing."""
    data = yaml.safe_load(SCENARIO.read_text())
    services = {s["id"]: s for s in data["services"]}
    lead, follow = services["airport_down_vc"], services["jurenba_down"]
    lead.update(to="huixing", departures={"times": [900]})
    follow.update(to="huixing")
    data["services"] = [lead, follow]
    merge = next(f for f in data["formations"] if f["id"] == "merge")
    if couple is not None:
        merge["couple"] = couple
    data["formations"] = [merge]
    data["simulation"]["duration_s"] = 3600
    path = tmp / "pair.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def pair(tmp_path_factory: pytest.TempPathFactory) -> Path:
    tmp = tmp_path_factory.mktemp("bijin_merge")
    out = tmp / "out"
    res = run_railsim(["run", str(_one_pair(tmp)), "--out", str(out), "--no-progress"])
    assert res.returncode == 0, res.stderr[-2000:]
    (tmp / "terminal.txt").write_text(res.stdout + res.stderr)  # what the user sees
    return out


def test_the_pair_couples_at_bijin_without_collision_or_switch_violation(pair: Path) -> None:
    s = read_summary(pair)
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0 and s["switch_violations"] == 0
    assert s["n_arrived"] == 2 and s["n_stops_missed"] == 0
    (row,) = read_csv(pair / "formations.csv")
    assert row["formation"] == "merge0"
    assert int(row["couple_successes"]) == 1 and row["final_state"] == "coupled"
    assert float(row["min_gap_m"]) > 20.0  # the follower stood and ran ~30 m behind, never closer than the guard


def test_locks_in_the_planned_order_and_coupling_after_the_switch(pair: Path) -> None:
    ev = read_events(pair)
    grants = [e for e in ev if e["kind"] == "lock_granted" and e["subject"] == "bijin_down"]
    assert [e["detail"]["holders"] for e in grants] == [["airport_down_vc.000"], ["jurenba_down.000"]]
    thrown = [e for e in ev if e["kind"] == "throw_end" and e["subject"] == "bijin_down"]
    assert thrown and grants[1]["t_s"] >= thrown[0]["t_s"]  # the branch leg only after the throw behind the leader
    (req,) = [e for e in ev if e["kind"] == "couple_requested"]
    assert req["t_s"] > grants[1]["t_s"]  # asked once the Jurenba unit had run over the switch it was granted


def test_the_pair_leaves_bijin_together_and_arrives_together(pair: Path) -> None:
    stops = {(r["trip_id"], r["station"]): r for r in read_csv(pair / "stops.csv")}
    a, j = stops[("airport_down_vc.000", "bijin")], stops[("jurenba_down.000", "bijin")]
    assert float(j["arrival_s"]) > float(a["arrival_s"])  # it came in behind the Airport unit
    assert abs(float(j["departure_s"]) - float(a["departure_s"])) <= 5.0
    a_end, j_end = stops[("airport_down_vc.000", "huixing")], stops[("jurenba_down.000", "huixing")]
    assert abs(float(j_end["arrival_s"]) - float(a_end["arrival_s"])) <= 10.0


def test_the_run_says_why_the_pair_cannot_couple_on_the_run(pair: Path) -> None:
    ev = read_events(pair)
    (why,) = [e for e in ev if e["kind"] == "coupling_on_run_infeasible"]
    d = why["detail"]
    assert why["subject"] == "merge0" and d["switch"] == "bijin_down" and d["leader"] == "airport_down_vc.000"
    # the engine's numbers: the leader stands 24.9 s after passing the point (271 m on, 19.1 m/s, braking at
    # 0.89 m/s²); the follower may pass 20.3 s after it (rear clear 5.3 s + 15 s throw) > 24.9 - 5 s of hold
    assert d["leader_to_halt_s"] == pytest.approx(24.9, abs=0.2) and d["halt_m"] == pytest.approx(271.0, abs=1.0)
    assert d["switch_interval_s"] == pytest.approx(20.3, abs=0.2) and d["throw_s"] == 15.0
    assert d["switch_interval_s"] > d["leader_to_halt_s"] - d["hold_s"] and d["least_gap_m"] is None
    # the recorded run agrees: the lock was released (the leader's rear clear) release_s after the leader passed
    # the point, and the leader stood at Bijin leader_to_halt_s after it; the pair coupled standing there
    released = next(e["t_s"] for e in ev if e["kind"] == "lock_released" and e["subject"] == "bijin_down")
    stood = next(e["t_s"] for e in ev if e["kind"] == "stop_registered" and e["subject"] == "airport_down_vc.000")
    assert stood - released == pytest.approx(d["leader_to_halt_s"] - d["release_s"], abs=2.0)
    (coupled,) = [e for e in ev if e["kind"] == "coupled"]
    assert coupled["t_s"] > stood
    (row,) = read_summary(pair)["formations_asked"]
    assert row["coupled"] is True and row["on_run"]["feasible"] is False
    assert row["on_run"]["switch_interval_s"] == d["switch_interval_s"]
    terminal = (pair.parent / "terminal.txt").read_text()
    assert "formation merge0 cannot couple on the run after its merge" in terminal
    assert "it couples standing" in terminal


def test_a_misspelt_merge_switch_is_refused(tmp_path: Path) -> None:
    res = run_railsim(["validate", str(_one_pair(tmp_path, {"after_switch": "bijin_dwn"}))])
    assert res.returncode == 2
    assert "formations[0].couple.after_switch" in res.stderr and "bijin_down" in res.stderr
    assert "Traceback" not in res.stderr
