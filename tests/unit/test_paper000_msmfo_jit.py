"""The compiled MSMFO (:mod:`controllers.mcf_dmpc.msmfo_jit`) is the Python MSMFO with the MCF fitness, compiled:
from the same generator state it returns the same sequence, cost and evaluation count, and leaves the generator in
the same state. So the controllers' fast path changes nothing but the time.
"""

from __future__ import annotations

import numpy as np
import pytest

from controllers import create
from controllers.mcf_dmpc import kernels, msmfo_jit
from controllers.mcf_dmpc.cf_models import THETA_TRAIN2, THETA_TRAIN3
from controllers.mcf_dmpc.cost import TABLE_II, sequence_costs
from controllers.mcf_dmpc.msmfo_jit import msmfo_mcf
from controllers.mcf_dmpc.optim import minimize_sequence
from controllers.mcf_dmpc.rollout import PredecessorHorizon, expand_sequence
from controllers.mcf_dmpc.sim import run_platoon
from controllers.mcf_dmpc.spacing import TABLE_I, paper000_vehicle

pytestmark = pytest.mark.skipif(not kernels.NUMBA_AVAILABLE, reason="numba not importable")


def _problem(rng: np.random.Generator, steps: int):
    v0p = rng.uniform(40.0, 70.0)
    ap = rng.normal(0.0, 0.1, steps)
    vp = np.concatenate([[v0p], v0p + np.cumsum(ap)])
    xp = np.concatenate([[0.0], np.cumsum(0.5 * (vp[:-1] + vp[1:]))]) + rng.uniform(300.0, 2500.0)
    hz = PredecessorHorizon(xp, vp, ap, 203.0, 1.0, "plan")
    theta = (THETA_TRAIN2 if rng.random() < 0.5 else THETA_TRAIN3).as_array()
    theta[7:] = rng.uniform(-0.1, 0.1, 3)  # control offsets too
    return hz, theta, 0.0, rng.uniform(40.0, 70.0), rng.uniform(-0.5, 0.5)


@pytest.mark.parametrize(
    "steps, dim, pop, iters",
    [(20, 20, 10, 8), (30, 30, 16, 20), (25, 6, 12, 10), (60, 60, 50, 100), (170, 170, 8, 4)],
    ids=["small", "medium", "move_blocking", "table_ii", "five_key_words"],
)
def test_compiled_msmfo_equals_the_python_optimiser(steps: int, dim: int, pop: int, iters: int) -> None:
    rng = np.random.default_rng(steps * 1000 + dim)
    for trial in range(3 if pop < 50 else 1):
        hz, theta, x0, v0, u_prev = _problem(rng, steps)

        def fitness(seqs: np.ndarray, hz=hz, theta=theta, x0=x0, v0=v0, u_prev=u_prev) -> np.ndarray:
            return sequence_costs(expand_sequence(seqs, steps), x0, v0, hz, theta, TABLE_I, u_prev, TABLE_II)

        init = np.stack([np.full(dim, m) for m in range(3)]) if trial % 2 == 0 else None
        r_py, r_jit = np.random.default_rng(trial), np.random.default_rng(trial)
        ref = minimize_sequence(fitness, dim, 3, population=pop, iterations=iters, rng=r_py, init=init)
        args = (theta, x0, v0, hz.position_m, hz.speed_mps, hz.accel_mps2, 203.0, 1.0,
                kernels.train_vector(TABLE_I), kernels.weight_vector(TABLE_II), u_prev, False, steps)  # fmt: skip
        best, cost, evaluations, rollouts = msmfo_mcf(
            args, dim, 3, population=pop, iterations=iters, rng=r_jit, init=init
        )
        np.testing.assert_array_equal(best, ref.best)
        assert cost == ref.best_cost
        assert evaluations == ref.evaluations
        assert rollouts < evaluations  # repeated rows were looked up, not rolled out again
        assert r_py.random() == r_jit.random()  # the generator advanced by exactly the same draws


def test_cyclic_rounding_equals_the_python_modulo() -> None:
    """Eq. (21) without the integer division on the common path: the same cell as ``(⌊x⌋ − lb) mod n + lb``."""
    rng = np.random.default_rng(21)
    for lb, period in [(1, 3), (1, 2), (1, 7), (0, 5), (-2, 4)]:
        x = np.concatenate([rng.uniform(-3.0 * period, 4.0 * period, 4000), rng.uniform(-1e12, 1e12, 200)])
        x = np.concatenate([x, np.arange(-3 * period, 4 * period + 1, dtype=float)])  # the box edges exactly
        got = [msmfo_jit._cyclic(float(v), lb, period) for v in x]
        assert got == [(int(np.floor(v)) - lb) % period + lb for v in x]
    with pytest.raises(ValueError, match="non-finite"):
        msmfo_jit._cyclic(float("nan"), 1, 3)


@pytest.mark.parametrize("name", ["mcf_dmpc", "opo_mcf_dmpc"])
def test_controllers_decide_the_same_compiled_or_not(name: str) -> None:
    veh = paper000_vehicle()
    runs = []
    for compiled in (True, False):
        params = {"theta_preset": "train2", "population": 12, "iterations": 6, "opo_iterations": 2}
        if name == "mcf_dmpc":
            params.pop("opo_iterations")
        f = create(name, params, veh)
        f._compiled = compiled and f._compiled  # the Python path on demand (what a custom optimiser gets)
        runs.append(run_platoon([f], (1400.0, 0.0), (61.0, 58.0), 8, seed=3))
    a, b = runs
    np.testing.assert_array_equal(a.u_cmd, b.u_cmd)
    assert [i[1]["model_sequence"] for i in a.infos] == [i[1]["model_sequence"] for i in b.infos]
    assert [i[1]["evaluations"] for i in a.infos] == [i[1]["evaluations"] for i in b.infos]
