"""The optimiser benchmark (benchmarks/optimizers_000.py): its stand-in fitness is the colleague's MCF rollout +
J^(DMPC) to rounding error, and a small run prints a well-formed equal-budget JSON report."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "optimizers_000.py"


def _load():
    spec = importlib.util.spec_from_file_location("optimizers_000", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_standin_fitness_equals_the_mcf_rollout_cost():
    pytest.importorskip("controllers.mcf_dmpc.rollout")
    pytest.importorskip("controllers.mcf_dmpc.cost")
    bench = _load()
    seqs = np.vstack(
        [np.random.default_rng(0).integers(0, 3, (40, bench.NP)), np.repeat(np.arange(3)[:, None], bench.NP, axis=1)]
    )
    np.testing.assert_allclose(bench._standin_fitness()(seqs), bench._colleague_fitness()(seqs), rtol=1e-12)


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
