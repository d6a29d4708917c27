"""``railsim robustness``: Monte-Carlo runs on the sweep machinery, KPIs with 95 % intervals, resumable.

Real SUMO runs of :file:`tests/data/scenarios/disturbed_headway.yaml` (six trains, dwell/departure/running-time
disturbances), two seeds at two headways, plus the undisturbed baseline.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from tests.helpers import ROOT, run_railsim

SCENARIO = ROOT / "tests" / "data" / "scenarios" / "disturbed_headway.yaml"


def test_robustness_runs_aggregates_and_resumes(tmp_path: Path) -> None:
    args = ["robustness", str(SCENARIO), "--runs", "2", "--headways", "75,150", "--out", str(tmp_path)]
    args += ["--workers", "2", "--no-progress"]
    res = run_railsim(args, timeout=900)
    assert res.returncode == 0, res.stderr
    result = json.loads((tmp_path / "robustness.json").read_text(encoding="utf-8"))
    groups = {g["headway_s"]: g for g in result["groups"]}
    assert set(groups) == {75.0, 150.0}
    rows = {}
    for p in (tmp_path / "runs" / "rows").glob("*.json"):
        row = json.loads(p.read_text(encoding="utf-8"))
        rows.setdefault(row["services[0].departures.headway_s"], []).append(row)
    for h, g in groups.items():
        assert g["n_ok"] == 2 and g["collisions"] == 0
        vals = [r["robustness.within_3min"] for r in rows[h]]
        assert math.isclose(g["kpis"]["robustness.within_3min"]["mean"], sum(vals) / 2)
        base = json.loads(next((tmp_path / "baseline" / "rows").glob("*.json")).read_text(encoding="utf-8"))
        assert base["disturbances.intensity"] == 0.0 and base["robustness.primary_min"] == 0.0
        assert g["kpis"]["robustness.primary_min"]["mean"] > 0.0
    # tighter headway, more knock-on
    assert groups[75.0]["kpis"]["knock_on_min"]["mean"] > groups[150.0]["kpis"]["knock_on_min"]["mean"]
    for name in ("robustness_delay_cdf.png", "robustness_stability.png", "robustness_by_station.png"):
        assert (tmp_path / name).stat().st_size > 1000
    assert "| 75 |" in (tmp_path / "robustness.md").read_text(encoding="utf-8")
    before = sorted(p.stat().st_mtime_ns for p in (tmp_path / "runs" / "rows").glob("*.json"))
    res = run_railsim(args, timeout=900)  # resumed: nothing runs again
    assert res.returncode == 0, res.stderr
    assert sorted(p.stat().st_mtime_ns for p in (tmp_path / "runs" / "rows").glob("*.json")) == before


def test_bad_options_are_one_line_exit_2(tmp_path: Path) -> None:
    res = run_railsim(["robustness", str(SCENARIO), "--runs", "1", "--out", str(tmp_path)])
    assert res.returncode == 2 and "--runs" in res.stderr and "Traceback" not in res.stderr
    res = run_railsim(["robustness", str(SCENARIO), "--runs", "3", "--headways", "9x", "--out", str(tmp_path)])
    assert res.returncode == 2 and "--headways" in res.stderr and "Traceback" not in res.stderr


def test_same_scenario_in_both_regimes_pairs_to_zero(tmp_path: Path) -> None:
    """Common random numbers, end to end: the VC-vs-MB robustness comparison with the same scenario on both sides
    runs the same seeds with the same draws, so every paired difference is exactly zero."""
    import yaml

    from railsim.studies.vc_robustness import compare_robustness

    disturbances = yaml.safe_load(SCENARIO.read_text(encoding="utf-8"))["disturbances"]
    text = compare_robustness(
        tmp_path, SCENARIO, SCENARIO, disturbances, [75.0], ["a"], runs=2, workers=2, progress=False
    )
    result = json.loads((tmp_path / "robustness" / "vc_vs_mb_robustness.json").read_text(encoding="utf-8"))
    from railsim.studies.vc_robustness import paired_differences

    (row,) = paired_differences(*result.values())
    assert row["n_pairs"] == 2
    for key in ("knock_on_min", "robustness.mean_delay_s", "robustness.within_3min"):
        assert row[key]["mean"] == 0.0 and row[key]["vc_higher"] == 0 and row[key]["n"] == 2
    assert "Paired on the same seeds" in text and "| 75 | 1 | 2 |" in text
