"""The optimiser benchmark (benchmarks/optimizers_000.py): its stand-in fitness is the colleague's MCF rollout +
J^(DMPC) to rounding error, and a small run prints a well-formed equal-budget JSON report.

Here: the tests of it that run SUMO or a railsim child process; the others are in ``tests/unit/test_paper000_optim_benchmark.py``.
"""

from __future__ import annotations

import json
import subprocess
import sys

from tests.unit.test_paper000_optim_benchmark import ROOT, SCRIPT


def test_small_benchmark_run_reports_equal_budgets():
    out = subprocess.run(
        [sys.executable, str(SCRIPT), "--seeds", "2", "--budget", "300"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=ROOT,
    )
    assert out.returncode == 0, out.stderr
    report = json.loads(out.stdout)
    methods = report["methods"]
    assert set(methods) == {"msmfo", "mfo", "ga", "pso", "sa"}
    for name, m in methods.items():
        assert m["evaluations_mean"] <= 300
        if name != "msmfo":
            assert m["evaluations_mean"] == 300
        assert m["best_J_min"] <= m["best_J_mean"]
        curve = m["normalised_best_every_5pct_budget"]
        assert len(curve) == 20 and all(a >= b for a, b in zip(curve, curve[1:]))
    assert set(report["msmfo_improvement"]) == {"mfo", "ga", "pso", "sa"}
