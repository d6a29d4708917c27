"""Paper D's coupling and collision-avoidance scenarios through the engine in SUMO (Chongqing Line 3, Qilong →
Bagongli), empty and loaded: scenarios/paper003_{in_station,track_accel,track_decel,ca_departure,ca_arrival}[_loaded].yaml
and the obstacle case (scenarios/paper003_obstacle_ca.yaml with a loaded override).

What must hold in every run (read back with railsim.analysis.paper003):

* no collision (engine truth and the per-pair gap);
* the gap is never below the follower's CA safety distance (recomputed per sample from the resolved scenario)
  unless the CA of that follower is triggered (one step of detection latency allowed): ``unguarded_s == 0``;
* coupling scenarios couple (formations.csv) and end at d_c = 5 m with matched speeds;
* the coupling scenarios never fire CA nor the emergency brake;
* the departure CA scenario is designed to cross the 28 m trigger: the trigger fires at a gap ≤ 28 m, emergency
  braking starts in the same step, the CA releases later at a gap above the trigger, and the gap recovers above it;
  the arrival case adds the CA's braking to the service braking (A27) and holds it for a long, gentle interval;
* a communication fault injected through ``faults.comm`` (1 s t2t delay, 10 % loss, a 3 s outage of F1) shows in
  the comm statistics and leaves the formation collision-free and guarded.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from railsim.analysis.paper003 import metrics
from tests.helpers import ROOT, read_csv, read_summary, run_railsim

SCEN = ROOT / "scenarios"
COUPLING = ("in_station", "track_accel", "track_decel")
CA = ("ca_departure",)
D_C_M = 5.0
S_SAFE_M = 28.0


def _run(tmp_path: Path, path: Path, raw: dict | None = None) -> Path:
    if raw is not None:
        tmp_path.mkdir(parents=True, exist_ok=True)
        path = tmp_path / "s.yaml"
        path.write_text(yaml.safe_dump(raw, sort_keys=False))
    out = tmp_path / "out"
    res = run_railsim(["run", str(path), "--out", str(out), "--no-progress"])
    assert res.returncode in (0, 1), res.stderr[-2000:]  # 1 = collision: reported by the assertions below
    return out


def _events(out: Path) -> list[tuple[float, str, str, dict]]:
    return [
        (float(e["t_s"]), e["kind"], e["subject"], json.loads(e["detail"] or "{}"))
        for e in read_csv(out / "events.csv")
    ]


def _common_safety(m: dict) -> None:
    assert m["collisions"] == 0 and not m["collision"]
    for pair, p in m["pairs"].items():
        assert p["min_gap_m"] > 0.0, pair
        if p["unguarded_s"] is not None:
            assert p["unguarded_s"] == 0.0, (pair, p)


@pytest.mark.parametrize("load", ["", "_loaded"])
@pytest.mark.parametrize("name", COUPLING)
def test_coupling_scenarios_couple_without_collision(tmp_path: Path, name: str, load: str) -> None:
    out = _run(tmp_path, SCEN / f"paper003_{name}{load}.yaml")
    m = metrics(out)
    _common_safety(m)
    forms = read_csv(out / "formations.csv")
    assert len(forms) == 2 and all(int(f["couple_successes"]) >= 1 for f in forms)
    assert all(m["coupled"].values())
    for pair, p in m["pairs"].items():
        assert abs(p["final_gap_m"] - D_C_M) < 0.5 and abs(p["final_speed_diff_mps"]) < 0.1, (pair, p)
        assert p["min_gap_m"] > D_C_M - 0.5, (pair, p)  # no undershoot of d_c worth the name
    # normal coupling never fires collision avoidance nor the emergency brake (the bare trigger fired them 5 / 21
    # times in accelerated coupling, empty / loaded)
    assert not [e for e in _events(out) if e[1] in ("ca_trigger", "emergency_brake_on")]


@pytest.mark.parametrize("load", ["", "_loaded"])
@pytest.mark.parametrize("name", CA)
def test_ca_scenarios_trigger_brake_release_and_recover(tmp_path: Path, name: str, load: str) -> None:
    out = _run(tmp_path, SCEN / f"paper003_{name}{load}.yaml")
    m = metrics(out)
    _common_safety(m)
    ev = _events(out)
    for pair, p in m["pairs"].items():
        fol = pair.split("-", 1)[1]
        assert p["min_gap_m"] < S_SAFE_M, (pair, p)  # the scenario is designed to cross the trigger ...
        trig = [(t, d) for t, k, s, d in ev if k == "ca_trigger" and s == fol]
        rel = [(t, d) for t, k, s, d in ev if k == "ca_release" and s == fol]
        brake = [t for t, k, s, _ in ev if k == "emergency_brake_on" and s == fol]
        assert trig and rel and brake, (pair, ev)
        t0, d0 = trig[0]
        assert d0["gap_m"] <= S_SAFE_M and brake[0] == t0  # ... the trigger fires there and brakes at once ...
        assert rel[0][0] > t0 and rel[0][1]["gap_m"] > S_SAFE_M  # ... and releases once the gap is back
        assert p["final_gap_m"] > S_SAFE_M  # the gap recovers
        assert p["min_gap_m"] > S_SAFE_M - 5.0  # never into the 5 m buffer of S_safe = 23 + 5 m


@pytest.mark.parametrize("load", ["", "_loaded"])
def test_arrival_ca_brakes_on_top_of_the_service_braking(tmp_path: Path, load: str) -> None:
    """Spec 003 §3.3.2 / A27 in SUMO: F1 and F2 brake with the faulty 0.15 m/s² (the lead 0.28 m/s²); each CA fires
    at ≤ 28 m and *adds* a gentle increment (the engine's additive arbitration): F1 decelerates harder than its
    service braking while the CA holds, for > 20 s, and is released above 28 m at a low speed; no collision, gaps
    above the CA's s_min of 5 m."""
    out = _run(tmp_path, SCEN / f"paper003_ca_arrival{load}.yaml")
    m = metrics(out)
    _common_safety(m)
    ev = _events(out)
    trig = [(t, d) for t, k, s, d in ev if k == "ca_trigger" and s == "F1.000"]
    rel = [(t, d) for t, k, s, d in ev if k == "ca_release" and s == "F1.000"]
    assert trig and rel and trig[0][1]["gap_m"] <= S_SAFE_M and rel[0][1]["gap_m"] > S_SAFE_M
    assert rel[0][0] - trig[0][0] > 20.0
    rows = [r for r in read_csv(out / "trace.csv") if r["train"] == "F1.000"]
    during = [r for r in rows if trig[0][0] + 1.0 <= float(r["t_s"]) < rel[0][0]]
    assert during and all(r["role"] == "ca" for r in during)  # the added command is the applied one
    assert min(float(r["command_mps2"]) for r in during) < -0.3  # harder than the 0.15 service braking
    release = min(rows, key=lambda r: abs(float(r["t_s"]) - rel[0][0]))
    assert float(release["speed_mps"]) < 2.0
    for pair, p in m["pairs"].items():
        assert 5.0 < p["min_gap_m"] < S_SAFE_M, (pair, p)


def test_obstacle_loaded_stops_before_the_obstacle(tmp_path: Path) -> None:
    raw = yaml.safe_load((SCEN / "paper003_obstacle_ca.yaml").read_text())
    raw["vehicles"]["cq6_25"] = {"preset": "cq3_mc_full", "max_speed_kmh": 25}  # loaded: full Mc car, weaker brake
    raw["vehicles"]["cq6"] = {"preset": "cq3_mc_overloaded"}
    raw["outputs"]["trace_stride_s"] = 0.1
    out = _run(tmp_path, SCEN / "unused.yaml", raw)
    m = metrics(out)
    _common_safety(m)
    obstacle = next(p for pair, p in m["pairs"].items() if pair.startswith("obstacle"))
    assert 0.0 < obstacle["min_gap_m"] < S_SAFE_M and obstacle["unguarded_s"] == 0.0
    ev = _events(out)
    trig = next(d for t, k, s, d in ev if k == "ca_trigger" and s == "lead.000")
    assert trig["gap_m"] <= S_SAFE_M


def test_comm_fault_through_faults_comm(tmp_path: Path) -> None:
    raw = yaml.safe_load((SCEN / "paper003_track_accel.yaml").read_text())
    raw["faults"]["comm"]["t2t"] = {
        "delay_s": {"dist": "constant", "value": 1.0},
        "loss_prob": 0.1,
        "outages": [{"start_s": 20.0, "end_s": 23.0, "trains": ["F1.000"]}],
    }
    out = _run(tmp_path, SCEN / "unused.yaml", raw)
    t2t = read_summary(out)["comm"]["t2t"]
    assert t2t["delay_mean_s"] == pytest.approx(1.0) and t2t["lost_random"] > 0 and t2t["lost_outage"] > 0
    ev = _events(out)
    # the 3 s outage exceeds the engine's 2 s message age: F1 degrades to separation, and recovers afterwards
    degraded = [t for t, k, s, _ in ev if k == "vc_degraded" and s == "F1.000"]
    restored = [t for t, k, s, _ in ev if k == "vc_restored" and s == "F1.000"]
    assert degraded and 20.0 < degraded[0] <= 23.0 + 1.0 and restored and restored[0] > degraded[0]
    m = metrics(out)
    _common_safety(m)
    assert all(m["coupled"].values())
    assert all(p["min_gap_m"] > 0.5 * D_C_M for p in m["pairs"].values())
