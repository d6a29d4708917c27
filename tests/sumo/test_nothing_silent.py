"""A controller that falls back leaves an event with its reason and a WARNING line.

The forced case is Paper A's DMPC baseline (``scenarios/paper000_sd_comparison_dmpc.yaml``) with OSQP allowed
one ADMM iteration (``max_iter: 1``): no solve converges, so both followers brake on their fallback at every
step. In a real SUMO run (child process) every fallback is a ``controller_fallback`` event naming the train,
the role, the controller class and the solver's status; the counts in ``events.csv``, ``trips.csv`` and
``summary.json`` agree; the WARNING lines are rate-limited (one per train per simulated minute).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import yaml

from railsim.engine.fallbacks import LOG_INTERVAL_S
from tests.helpers import ROOT, read_csv, read_summary, run_python, run_railsim

DURATION_S = 90


def _forced_dmpc(tmp_path: Path) -> Path:
    raw = yaml.safe_load((ROOT / "scenarios" / "paper000_sd_comparison_dmpc.yaml").read_text())
    for name in ("vc2", "vc3"):
        raw["controllers"][name]["params"]["max_iter"] = 1
    raw["simulation"]["duration_s"] = DURATION_S
    path = tmp_path / "forced.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def test_forced_solver_failure_is_an_event_with_its_reason_and_a_rate_limited_warning(tmp_path: Path) -> None:
    out = tmp_path / "out"
    res = run_railsim(["run", str(_forced_dmpc(tmp_path)), "--out", str(out), "--no-progress"])
    assert res.returncode == 0, res.stderr[-2000:]
    summary = read_summary(out)
    events = [e for e in read_csv(out / "events.csv") if e["kind"] == "controller_fallback"]
    assert summary["fallbacks"] > 0
    assert len(events) == summary["fallbacks"]
    per_trip = {r["trip_id"]: int(r["fallbacks"]) for r in read_csv(out / "trips.csv")}
    assert {e["subject"] for e in events} == {"t2.000", "t3.000"}  # the two DMPC followers, never the leader
    for trip, n in per_trip.items():
        assert n == sum(1 for e in events if e["subject"] == trip)
    for e in events:
        detail = json.loads(e["detail"])
        assert detail["role"] == "coupled" and detail["controller"] == "DmpcController"
        assert detail["reason"].startswith("SQP not solved (maximum iterations reached)")
    warnings = [ln for ln in res.stderr.splitlines() if ln.startswith("WARNING") and "fell back" in ln]
    # one line per follower per LOG_INTERVAL_S of simulated time, however many fallbacks the interval held
    assert 2 <= len(warnings) <= 2 * math.ceil((DURATION_S + 1) / LOG_INTERVAL_S)
    assert len(warnings) < len(events)
    assert any("more since" in ln for ln in warnings)  # the suppressed ones are counted on the next line


def test_numpy_floating_point_warnings_fail_a_child_process(tmp_path: Path) -> None:
    """The children tests start (every SUMO run) turn numpy's floating-point warnings into errors."""
    res = run_python("import numpy as np; np.float64(1.0) / np.float64(0.0)", tmp_path)
    assert res.returncode != 0 and "divide by zero" in res.stderr
    ok = run_python("import numpy as np; print(np.float64(1.0) / np.float64(4.0))", tmp_path)
    assert ok.returncode == 0 and ok.stdout.strip() == "0.25"
