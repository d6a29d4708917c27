"""The compiled OPO (:mod:`controllers.mcf_dmpc.opo_jit`) is :func:`controllers.mcf_dmpc.opo.opo_step` with the MCF
fitness, compiled: from the same warm start it returns the same Θ, costs and counts bit for bit, on
random predecessors, states and warm starts (inside, on and outside the box), with the paper's box and with fixed
parameters (zero-width bounds).
"""

from __future__ import annotations

import numpy as np
import pytest

from controllers.mcf_dmpc import kernels
from controllers.mcf_dmpc.cf_models import THETA_BOUNDS, THETA_TRAIN2, THETA_TRAIN3
from controllers.mcf_dmpc.cost import TABLE_II, sequence_costs
from controllers.mcf_dmpc.opo import OpoSettings, opo_step
from controllers.mcf_dmpc.opo_jit import opo_step_compiled
from controllers.mcf_dmpc.rollout import PredecessorHorizon
from controllers.mcf_dmpc.spacing import TABLE_I

pytestmark = pytest.mark.skipif(not kernels.NUMBA_AVAILABLE, reason="numba not importable")


def _settings(rng: np.random.Generator, trial: int) -> OpoSettings:
    bounds = THETA_BOUNDS.copy()
    if trial % 3 == 1:
        bounds[7:] = 0.0  # the paper's reading: the control offsets fixed at 0
    if trial % 3 == 2:
        bounds[rng.integers(0, 7)] = [0.05, 0.05]  # one law parameter fixed
    iterations = int(rng.integers(0, 12))
    initial = float(rng.uniform(0.02, 0.5))
    return OpoSettings(iterations, initial, float(rng.uniform(1e-4, initial)), bounds)


@pytest.mark.parametrize("steps", [12, 60])
def test_compiled_opo_equals_the_python_search(steps: int) -> None:
    rng = np.random.default_rng(300 + steps)
    for trial in range(24):
        ap = rng.normal(0.0, 0.15, steps)
        vp = np.concatenate([[rng.uniform(30.0, 70.0)], np.zeros(steps)])
        vp[1:] = vp[0] + np.cumsum(ap)
        xp = np.concatenate([[0.0], np.cumsum(0.5 * (vp[:-1] + vp[1:]))]) + rng.uniform(200.0, 3000.0)
        hz = PredecessorHorizon(xp, vp, ap, 203.0, 1.0, "plan")
        x0, v0, u_prev, ff = 0.0, float(rng.uniform(30.0, 70.0)), float(rng.uniform(-0.5, 0.5)), trial % 2 == 1
        theta = (THETA_TRAIN2 if trial % 2 else THETA_TRAIN3).as_array()
        theta += rng.normal(0.0, 0.3, theta.size) * (THETA_BOUNDS[:, 1] - THETA_BOUNDS[:, 0])  # some outside the box
        settings = _settings(rng, trial)

        def batch(seqs: np.ndarray, thetas: np.ndarray, hz=hz, x0=x0, v0=v0, u_prev=u_prev, ff=ff) -> np.ndarray:
            return sequence_costs(seqs, x0, v0, hz, thetas, TABLE_I, u_prev, TABLE_II, resistance_feedforward=ff)

        ref = opo_step(theta, batch, steps, settings)
        args = (x0, v0, xp, vp, ap, 203.0, 1.0, kernels.train_vector(TABLE_I), kernels.weight_vector(TABLE_II),
                u_prev, ff, steps)  # fmt: skip
        got = opo_step_compiled(theta, args, settings)
        np.testing.assert_array_equal(got.theta, ref.theta)
        np.testing.assert_array_equal(got.model_costs, ref.model_costs)
        assert (got.evaluations, got.batches) == (ref.evaluations, ref.batches)
        assert settings.iterations == 0 or got.evaluations > 3  # the search did poll
