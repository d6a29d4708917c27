"""In SUMO: Paper B's train integrated carriage by carriage (railsim.physics.multipoint) and driven by SEMPC.

``scenarios/paper001_single_section.yaml`` runs in a child process: the stop at s2 is within ±0.3 m of the mark,
and the total applied force seen in the trace never leaves the per-carriage envelope (6 × 70 kN traction,
6 × 65 kN braking) nor its rate limit (6 × 60 kN/s) at any 0.1 s step. A multipoint vehicle with a step method
other than Euler is refused (SUMO is handed the step's mean speed, which only Euler moves exactly).
"""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import ROOT, read_csv, read_summary, run_railsim

SCENARIO = ROOT / "scenarios" / "paper001_single_section.yaml"
MASS_KG = 6 * 64_800.0


def test_sempc_on_the_carriage_model_stops_at_the_mark_within_limits(tmp_path: Path) -> None:
    res = run_railsim(["run", str(SCENARIO), "--out", str(tmp_path), "--no-progress"])
    assert res.returncode == 0, res.stderr[-2000:]
    s = read_summary(tmp_path)
    assert s["n_arrived"] == 1 and s["n_stops_served"] == 1 and s["fallbacks"] == 0
    assert s["max_stopping_error_m"] <= 0.3
    rows = read_csv(tmp_path / "trace.csv")
    acc = [float(r["applied_accel_mps2"]) for r in rows]
    assert max(acc) <= 6 * 70e3 / MASS_KG + 1e-9
    assert min(acc) >= -6 * 65e3 / MASS_KG - 1e-9
    rate = max(abs(b - a) / 0.1 for a, b in zip(acc, acc[1:]))
    assert rate <= 6 * 60e3 / MASS_KG + 2 * 5e-7 / 0.1, rate  # at most the limit (CSV keeps 6 decimals)
    assert max(float(r["speed_mps"]) for r in rows) <= 45.8 + 1e-6  # the ATP limit


def test_multipoint_needs_euler_steps(tmp_path: Path) -> None:
    raw = yaml.safe_load(SCENARIO.read_text())
    raw["simulation"]["step_method"] = "ballistic"
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    res = run_railsim(["run", str(path), "--out", str(tmp_path / "o"), "--no-progress"])
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert "simulation.step_method" in res.stderr and "multipoint" in res.stderr
