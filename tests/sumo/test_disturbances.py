"""Primary delays (``disturbances:``), their injection, and the primary/secondary split of ``delays.csv``.

* A single incident on the first of four trains propagates to the followers as the closed-form queue
  argument predicts (real SUMO run, :file:`tests/data/scenarios/disturbed_line.yaml`).
* A section at intensity 0 gives the same bytes as no section (the golden test covers "no section" itself).
* Common random numbers: the Line 3 moving-block and virtual-coupling study scenarios draw the same primary
  delays for every trip.
* The validator names the file and field of every bad value.
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

import pytest
import yaml

from tests.helpers import ROOT, read_csv, read_summary, run_python, run_railsim

LINE = ROOT / "tests" / "data" / "scenarios" / "disturbed_line.yaml"
DT_S = 0.5


def _rows(out: Path, station: str) -> dict[str, dict[str, float]]:
    rows = [r for r in read_csv(out / "delays.csv") if r["station"] == station]
    return {
        r["trip_id"]: {k: float(v) for k, v in r.items() if k not in ("trip_id", "service", "station", "missed") and v}
        for r in rows
    }


def test_single_incident_propagates_as_the_queue_argument_predicts(tmp_path: Path) -> None:
    """Trains planned every H = 120 s; a.000 is held 300 s at s2. Platforms (150 m) hold one 119 m unit, so
    each follower waits before s2 until the train in front has left, then needs the same re-occupation time τ
    to reach its mark (same geometry every time). Queued trains therefore leave s2 every h = τ + planned
    platform time apart, and train k's departure delay is D_k = D_0 − k·(H − h) while positive. τ is measured on
    the pair (a.000, a.001); the prediction is checked on a.002 and a.003, within one step."""
    res = run_railsim(["run", str(LINE), "--out", str(tmp_path), "--no-progress"])
    assert res.returncode == 0, res.stderr
    s2 = _rows(tmp_path, "s2")
    headway_s = 120.0
    tau_s = s2["a.001"]["arrival_s"] - s2["a.000"]["departure_s"]
    platform_s = s2["a.001"]["planned_departure_s"] - s2["a.001"]["planned_arrival_s"]  # dwell + registration
    h_s = tau_s + platform_s
    d0 = s2["a.000"]["departure_delay_s"]
    assert d0 >= 300.0  # the hold itself, plus at most the plan's step rounding
    for k, tid in ((2, "a.002"), (3, "a.003")):
        predicted = d0 - k * (headway_s - h_s)
        assert predicted > 0.0  # still queued: the argument applies
        assert abs(s2[tid]["departure_delay_s"] - predicted) <= DT_S, (tid, predicted, s2[tid])
    # the split: the held train's delay is primary, the followers' is all secondary (they had no disturbance)
    s4 = _rows(tmp_path, "s4")
    assert s4["a.000"]["primary_s"] == 300.0 and abs(s4["a.000"]["secondary_s"]) <= DT_S
    for tid in ("a.001", "a.002", "a.003"):
        assert s4[tid]["primary_s"] == 0.0 and s4[tid]["secondary_s"] == s4[tid]["arrival_delay_s"] > 100.0
    rob = read_summary(tmp_path)["robustness"]
    secondary_min = sum(max(s4[t]["secondary_s"], 0.0) for t in s4) / 60.0
    assert math.isclose(rob["secondary_min"], secondary_min) and rob["primary_min"] == 5.0
    assert math.isclose(rob["propagation_factor"], secondary_min / 5.0)
    assert rob["within_5min"] < 1.0 and rob["recovery_s"][0] > 0.0
    res = run_railsim(["report", str(tmp_path)])  # the run report shows the robustness section and its figures
    assert res.returncode == 0, res.stderr
    text = (tmp_path / "report.md").read_text(encoding="utf-8")
    assert "## Robustness" in text and "| propagation factor (secondary ÷ primary) |" in text
    assert (tmp_path / "report_figures" / "delay_cdf.png").stat().st_size > 1000


def _write(tmp_path: Path, name: str, data: dict[str, Any]) -> Path:
    p = tmp_path / f"{name}.yaml"
    p.write_text(yaml.safe_dump(data), encoding="utf-8")
    return p


def test_intensity_zero_gives_the_same_bytes_as_no_section(tmp_path: Path) -> None:
    base = yaml.safe_load(LINE.read_text(encoding="utf-8"))
    base.pop("disturbances")
    zero = copy.deepcopy(base)
    zero["disturbances"] = {
        "intensity": 0.0,
        "dwell": [{"dist": "lognormal", "mean_s": 20, "sd_s": 10}],
        "departure": [{"dist": "exponential", "mean_s": 30}],
        "running_time": {"low": 0.9, "high": 1.0},
        "incidents": [{"rate_per_h": 6, "hold_s": 60}],
    }
    outs = []
    for name, data in (("none", base), ("zero", zero)):
        out = tmp_path / name
        res = run_railsim(["run", str(_write(tmp_path, name, data)), "--out", str(out), "--no-progress"])
        assert res.returncode == 0, res.stderr
        outs.append(out)
    for f in ("trips.csv", "stops.csv", "events.csv", "trace.csv", "formations.csv"):
        assert (outs[0] / f).read_bytes() == (outs[1] / f).read_bytes(), f
    assert not (outs[0] / "delays.csv").exists() and (outs[1] / "delays.csv").exists()
    rob = read_summary(outs[1])["robustness"]
    assert rob["primary_min"] == 0.0 and rob["propagation_factor"] is None


def test_disturbed_run_is_deterministic_and_injects_what_it_reports(tmp_path: Path) -> None:
    data = yaml.safe_load(LINE.read_text(encoding="utf-8"))
    data["disturbances"] = {
        "dwell": [{"dist": "exponential", "mean_s": 20, "stations": ["s2", "s3"]}],
        "departure": [{"dist": "empirical", "values_s": [0, 40], "weights": [1, 1]}],
        "running_time": {"low": 0.9, "high": 1.0},
    }
    path = _write(tmp_path, "d", data)
    outs = [tmp_path / "r1", tmp_path / "r2"]
    for out in outs:
        res = run_railsim(["run", str(path), "--out", str(out), "--no-progress"])
        assert res.returncode == 0, res.stderr
    for f in ("trips.csv", "stops.csv", "events.csv", "delays.csv"):
        assert (outs[0] / f).read_bytes() == (outs[1] / f).read_bytes(), f
    rows = read_csv(outs[0] / "delays.csv")
    trips = {r["trip_id"]: r for r in read_csv(outs[0] / "trips.csv")}
    inj = read_summary(outs[0])["disturbances"]
    assert inj["injected_dwell_s"] > 0.0 and inj["trips_slowed"] > 0
    assert math.isclose(sum(float(r["dwell_extra_s"]) for r in rows), inj["injected_dwell_s"], abs_tol=1e-3)
    late_starts = [float(t["departure_s"]) - float(t["planned_departure_s"]) for t in trips.values()]
    assert math.isclose(sum(late_starts), inj["injected_departure_s"], abs_tol=4 * DT_S)
    # the leading train meets nobody: its delay is its primary delay alone, to a step
    first = [r for r in rows if r["trip_id"] == "a.000"]
    assert all(abs(float(r["secondary_s"])) <= 2 * DT_S for r in first), first


_CRN = """
import json, sys
from railsim import scenario as S
from railsim.engine.loop import Simulation
dist = {"dwell": [{"dist": "lognormal", "mean_s": 15, "sd_s": 10, "prob": 0.5}],
        "departure": [{"dist": "exponential", "mean_s": 20}],
        "running_time": {"low": 0.95, "high": 1.0},
        "incidents": [{"rate_per_h": 3, "hold_s": 90}]}
out = {}
for regime in ("mb", "vc"):
    scn = S.load(f"scenarios/chongqing_line3_peak_{regime}.yaml")
    scn = S.from_mapping({**scn.raw, "disturbances": dist}, source=str(scn.source))
    sim = Simulation(scn, None, seed=7, progress=False)
    out[regime] = {tid: [tp.departure_s, tp.dwell_extra_s, tp.incident_s, tp.factor, tp.primary_arrival_s()]
                   for tid, tp in sim.primary.trips.items()}
json.dump(out, sys.stdout)
"""


def test_common_random_numbers_same_primary_delays_in_both_regimes() -> None:
    res = run_python(_CRN, timeout=900)
    assert res.returncode == 0, res.stderr
    out = json.loads(res.stdout)
    mb, vc = out["mb"], out["vc"]
    assert set(mb) == set(vc) and len(mb) > 50
    for tid in mb:  # Jurenba up units couple on departure under VC: they leave with their leader, no late start
        if tid.startswith("jurenba_up"):
            assert vc[tid][0] == 0.0
            late_s = mb[tid][0]
            mb[tid][0] = 0.0
            mb[tid][4] = {st: p - late_s for st, p in mb[tid][4].items()}
            vc[tid][4] = {st: pytest.approx(p, abs=1e-9) for st, p in vc[tid][4].items()}
    assert mb == vc
    assert sum(1 for v in mb.values() if v[1]) > 20 and any(v[2] for v in mb.values())


def _with(section: Any) -> dict[str, Any]:
    data = yaml.safe_load(LINE.read_text(encoding="utf-8"))
    data["disturbances"] = section
    return data


def test_unknown_station_is_a_config_error_exit_2(tmp_path: Path) -> None:
    path = _write(tmp_path, "bad", _with({"dwell": [{"dist": "exponential", "mean_s": 3, "stations": ["s9"]}]}))
    res = run_railsim(["run", str(path), "--out", str(tmp_path / "o"), "--no-progress"])
    assert res.returncode == 2 and "disturbances.dwell[0].stations" in res.stderr and "Traceback" not in res.stderr


def test_knock_on_through_a_rotation_is_secondary_delay(tmp_path: Path) -> None:
    """The shuttle's first trip leaves 400 s late (an incident at its origin); its unit needs 60 s to turn, so
    the return trip scheduled at 400 s cannot leave before arrival + 60 s: that late start is the return trip's
    secondary delay (it had no disturbance of its own) on top of its undisturbed delay, to a step or two, and the
    fleet block counts it."""
    from tests.sumo.test_single_track import build_single_line
    from tests.sumo.test_turnback import SHUTTLE, _run

    net, stops = build_single_line(tmp_path)
    services = copy.deepcopy(SHUTTLE)
    out = _run(tmp_path, net, stops, services, {"units": "auto", "turnback_min_s": 60})  # undisturbed reference
    free = {r["trip_id"]: r for r in read_csv(out / "trips.csv")}
    assert abs(float(free["back.000"]["departure_s"]) - 400.0) <= DT_S  # on time without the incident

    from tests.sumo.test_external_net import _COMMON, _write

    raw = {
        "name": "rotation_knock_on",
        "world": {"net": str(net), "additional": [str(stops)]},
        **_COMMON,
        "services": services,
        "rotations": {"units": "auto", "turnback_min_s": 60},
        "disturbances": {"incidents": [{"trip": "out.000", "station": "Aston", "hold_s": 400}]},
    }
    raw["simulation"] = {**raw["simulation"], "duration_s": 2500}  # type: ignore[dict-item]
    scn = _write(tmp_path, "disturbed.yaml", yaml.safe_dump(raw, sort_keys=False))
    out2 = tmp_path / "disturbed"
    res = run_railsim(["run", str(scn), "--out", str(out2), "--no-progress"], timeout=300)
    assert res.returncode == 0, res.stderr
    trips = {r["trip_id"]: r for r in read_csv(out2 / "trips.csv")}
    assert abs(float(trips["out.000"]["departure_s"]) - 400.0) <= DT_S  # the primary late start
    late_start_s = float(trips["out.000"]["arrival_s"]) + 60.0 - 400.0  # what the unit lacks for back.000
    assert late_start_s > 200.0  # the unit is late for its next trip: the knock-on regime
    back = [r for r in read_csv(out2 / "delays.csv") if r["trip_id"] == "back.000"]
    assert back and all(float(r["primary_s"]) == 0.0 for r in back)
    last = back[-1]
    # on top of what the return trip is late without any disturbance (its unit starts off the plan's mark)
    structural_s = float(free["back.000"]["delay_s"])
    assert abs(float(last["secondary_s"]) - structural_s - late_start_s) <= 2 * DT_S, (last, late_start_s)
    assert read_summary(out2)["fleet"]["late_starts_from_incoming_unit"] >= 1
