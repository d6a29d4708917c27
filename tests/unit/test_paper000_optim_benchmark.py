"""The optimiser benchmark (benchmarks/optimizers_000.py): its stand-in fitness is the colleague's MCF rollout +
J^(DMPC) to rounding error, and a small run prints a well-formed equal-budget JSON report."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
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
