"""Paper E's planner couples a Line 3 Bijin-like down pair on the run, before the platform
(``scenarios/line3_bijin_like_planner.yaml``).

The Bijin down merge's numbers (89.4 m units, 50 m turnout at 30 km/h, 15 s throw, 70 km/h line, 30 m target
gap) on the ``y_junction`` world, with the platform 250 m past the switch point (Bijin's starts 141.4 m past it,
where the planner finds no plan: ``docs/model.md``). ``qp_order`` plans the pair with the leader first
(``junction.fixed_order``) for five timings of the follower (1000-1800 m from the merge when the leader is 900 m
from it). Each run is ``railsim run`` in a child process; what is checked comes from the recorded files: the
formation is coupled (5 s in band) while the leader is still running, before its front reaches the platform;
the leader gets the merge switch first and the follower only after the throw; no collision, no switch violation,
both units stop at the platform.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tests.helpers import ROOT, read_csv, read_events, read_summary, run_railsim

SCENARIO = ROOT / "scenarios" / "line3_bijin_like_planner.yaml"
FOLLOWER_M = (1000, 1200, 1400, 1600, 1800)
LEAD_TO_SW1_M, SW1_TO_SW2_M = 700.0, 200.0


@pytest.fixture(scope="module", params=FOLLOWER_M, ids=[f"follower_{d}m" for d in FOLLOWER_M])
def run(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    data = yaml.safe_load(SCENARIO.read_text())
    fol = next(s for s in data["services"] if s["id"] == "fol")
    fol["start"]["distance_m"] = request.param
    tmp = tmp_path_factory.mktemp(f"bijin_like_{request.param}")
    path = tmp / "scenario.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    out = tmp / "out"
    res = run_railsim(["run", str(path), "--out", str(out), "--no-progress"])
    assert res.returncode == 0, res.stderr[-2000:]
    return out, data


def test_the_pair_couples_on_the_run_before_the_platform(run: tuple[Path, dict]) -> None:
    out, data = run
    s = read_summary(out)
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0 and s["switch_violations"] == 0
    assert s["n_arrived"] == 2 and s["n_stops_missed"] == 0
    assert s["junction"]["initial_plan_feasible"] is True and s["junction"]["order"] == ["lead.000", "fol.000"]
    ev = read_events(out)
    (coupled,) = [e for e in ev if e["kind"] == "coupled"]
    inserted = next(e for e in ev if e["kind"] == "train_inserted" and e["subject"] == "lead.000")
    params = data["world"]["params"]
    point_m = inserted["detail"]["chainage_m"] + LEAD_TO_SW1_M + SW1_TO_SW2_M
    platform_m = point_m + params["S5"] + params["platform_offset_m"]
    trace = {float(r["t_s"]): r for r in read_csv(out / "trace.csv") if r["train"] == "lead.000"}
    at = trace[coupled["t_s"]]
    assert point_m < float(at["chainage_m"]) < platform_m  # past the merge, the leader not yet at the platform
    assert float(at["speed_mps"]) > 3.0  # on the run (the plan's coupled speed is ~4.7 m/s)
    stood = next(e["t_s"] for e in ev if e["kind"] == "stop_registered" and e["subject"] == "lead.000")
    assert coupled["t_s"] < stood - 10.0


def test_the_leader_takes_the_merge_first_and_the_follower_after_the_throw(run: tuple[Path, dict]) -> None:
    out, _ = run
    ev = read_events(out)
    grants = [e for e in ev if e["kind"] == "lock_granted" and e["subject"] == "sw2"]
    assert [g["detail"]["holders"] for g in grants] == [["lead.000"], ["fol.000"]]
    thrown = [e for e in ev if e["kind"] == "throw_end" and e["subject"] == "sw2"]
    assert thrown and grants[1]["t_s"] >= thrown[-1]["t_s"] and thrown[-1]["detail"]["throw_s"] == 15.0
