"""The compiled MCF rollout/cost of :mod:`controllers.mcf_dmpc.kernels` equals the scalar reference.

The reference is the plain-float rollout ``rollout._rollout_scalar`` (itself pinned to the numpy laws of
:mod:`controllers.mcf_dmpc.cf_models` in test_paper000_models) scored by ``cost.cost_terms``. Random states, plans,
sequences and per-row Θ inside and outside the A29 box, including predecessors placed behind the follower
(ΔS ≤ 0: the IDM guard) and predicted speeds that go negative (penalty terms non-zero).
"""

from __future__ import annotations

import numpy as np
import pytest

from controllers.mcf_dmpc import kernels
from controllers.mcf_dmpc.cf_models import THETA_BOUNDS
from controllers.mcf_dmpc.cost import TABLE_II, CostWeights, cost_terms, sequence_costs
from controllers.mcf_dmpc.rollout import PredecessorHorizon, _rollout_scalar
from controllers.mcf_dmpc.spacing import TABLE_I

RTOL = 1e-12


def _random_case(rng: np.random.Generator, steps: int, pop: int) -> tuple:
    vp0 = rng.uniform(0.0, 97.0)
    ap = rng.uniform(-0.8, 1.0, steps)
    vp = np.concatenate([[vp0], vp0 + np.cumsum(ap)])
    xp = np.concatenate([[0.0], np.cumsum(0.5 * (vp[:-1] + vp[1:]))]) + rng.uniform(-50.0, 3000.0)
    hz = PredecessorHorizon(xp, vp, ap, float(rng.uniform(100.0, 300.0)), float(rng.uniform(0.5, 1.5)))
    seq = rng.integers(0, 3, size=(pop, steps))
    lo, hi = THETA_BOUNDS.T
    thetas = lo + rng.random((pop, len(lo))) * (hi - lo) * 1.5  # some rows beyond the box: the laws must not care
    return hz, seq, thetas, rng.uniform(-10.0, 10.0), rng.uniform(0.0, 97.0), rng.uniform(-0.8, 1.0)


@pytest.mark.parametrize("feedforward", [False, True])
def test_kernel_rollout_and_cost_equal_scalar_reference(feedforward: bool) -> None:
    rng = np.random.default_rng(19)
    weights = CostWeights(1.0, 0.05, 200.0, 400.0, 10.0, 1e6)
    hit_penalty = False
    for _ in range(40):
        steps = int(rng.integers(1, 61))
        hz, seq, thetas, x0, v0, u_prev = _random_case(rng, steps, int(rng.integers(1, 9)))
        ref = _rollout_scalar(seq, x0, v0, hz, thetas, TABLE_I, feedforward)
        u, v, s = kernels.rollout_rows(
            seq,
            thetas,
            x0,
            v0,
            hz.position_m,
            hz.speed_mps,
            hz.accel_mps2,
            hz.length_m,
            hz.emergency_decel_mps2,
            kernels.train_vector(TABLE_I),
            feedforward,
        )
        np.testing.assert_allclose(u, ref.u, rtol=RTOL, atol=1e-12)
        np.testing.assert_allclose(v, ref.v, rtol=RTOL, atol=1e-12)
        np.testing.assert_allclose(s, ref.s, rtol=RTOL, atol=1e-9)  # positions ~1e3 m: 1e-12 relative
        terms = cost_terms(ref, hz, u_prev, TABLE_I, weights)
        got = kernels.population_costs(
            seq,
            thetas,
            x0,
            v0,
            hz.position_m,
            hz.speed_mps,
            hz.accel_mps2,
            hz.length_m,
            hz.emergency_decel_mps2,
            kernels.train_vector(TABLE_I),
            kernels.weight_vector(weights),
            u_prev,
            feedforward,
        )
        np.testing.assert_allclose(got, terms["J"], rtol=RTOL)
        hit_penalty |= bool(np.any(terms["penalty"] > 0.0))
    assert hit_penalty  # the random cases reach the constraint penalty, so that part is compared too


def test_sequence_costs_uses_kernel_and_agrees_with_numpy_path() -> None:
    """The optimisers' fitness (``sequence_costs``) against the large-batch numpy rollout (> SCALAR_MAX_ROWS)."""
    rng = np.random.default_rng(7)
    hz, _, _, x0, v0, u_prev = _random_case(rng, 60, 1)
    seq = rng.integers(0, 3, size=(80, 60))
    theta = np.array([1.2, 12.1, 0.0, 0.011, 0.013, 0.012, 4.2e-4])
    got = sequence_costs(seq, x0, v0, hz, theta, TABLE_I, u_prev, TABLE_II)
    from controllers.mcf_dmpc.rollout import rollout_models  # numpy path for 80 rows

    ref = cost_terms(rollout_models(seq, x0, v0, hz, theta, TABLE_I), hz, u_prev, TABLE_I, TABLE_II)["J"]
    np.testing.assert_allclose(got, ref, rtol=1e-9)  # numpy's vectorised pow may differ in the last bits
    assert kernels.NUMBA_AVAILABLE  # the project declares numba; without it this path would be ~100x slower


def test_a_rows_cost_does_not_depend_on_its_batch() -> None:
    """batch_costs scores rows in pairs; a row's cost is bit for bit the same alone, in an odd or even batch, at any
    position, and with one shared Θ row or its own copy (the compiled searches rely on it)."""
    rng = np.random.default_rng(23)
    for _ in range(12):
        steps = int(rng.integers(1, 61))
        hz, seq, thetas, x0, v0, u_prev = _random_case(rng, steps, int(rng.integers(2, 10)))
        ctx = kernels.batch_context(
            x0, v0, hz.position_m, hz.speed_mps, hz.accel_mps2, hz.length_m, hz.emergency_decel_mps2,
            kernels.train_vector(TABLE_I), kernels.weight_vector(TABLE_II), u_prev, bool(rng.random() < 0.5),
        )  # fmt: skip
        whole = np.empty(len(seq))
        kernels.batch_costs(seq, thetas, *ctx, whole, kernels.NO_PREFIX, 0)
        for r in range(len(seq)):
            alone = np.empty(1)
            kernels.batch_costs(seq[r : r + 1], thetas[r : r + 1], *ctx, alone, kernels.NO_PREFIX, 0)
            shared = np.empty(3)  # the row in the middle of an odd batch, one Θ row for all
            kernels.batch_costs(seq[[0, r, -1]], thetas[r : r + 1], *ctx, shared, kernels.NO_PREFIX, 0)
            assert alone[0] == whole[r] == shared[1]


def test_rows_resumed_from_prefix_states_cost_the_same() -> None:
    """The compiled MSMFO starts every row after its first ``depth`` models from :func:`kernels.prefix_states`:
    the cost is bit for bit the one of the full rollout, for every depth up to the horizon minus one,
    in pairs and alone; a table of the wrong depth would give other costs (checked, so the test can fail)."""
    rng = np.random.default_rng(29)
    for _ in range(10):
        steps = int(rng.integers(2, 40))
        hz, seq, thetas, x0, v0, u_prev = _random_case(rng, steps, int(rng.integers(2, 12)))
        theta = thetas[:1]  # the searches' case: one Θ for every row
        ff = bool(rng.random() < 0.5)
        ctx = kernels.batch_context(
            x0, v0, hz.position_m, hz.speed_mps, hz.accel_mps2, hz.length_m, hz.emergency_decel_mps2,
            kernels.train_vector(TABLE_I), kernels.weight_vector(TABLE_II), u_prev, ff,
        )  # fmt: skip
        full = np.empty(len(seq))
        kernels.batch_costs(seq, theta, *ctx, full, kernels.NO_PREFIX, 0)
        x0c, v0c, xp, vp, ap, base, lp, bp, tr, _, _, _ = ctx
        for depth in sorted({1, min(2, steps - 1), int(rng.integers(1, min(7, steps - 1) + 1)), min(7, steps - 1)}):
            pre = kernels.prefix_states(theta[0], x0c, v0c, xp, vp, ap, base, lp, bp, tr, ff, depth)
            assert pre.shape == (kernels.N_MODELS**depth, 9)
            resumed = np.empty(len(seq))
            kernels.batch_costs(seq, theta, *ctx, resumed, pre, depth)
            np.testing.assert_array_equal(resumed, full)
            alone = np.empty(1)
            kernels.batch_costs(seq[-1:], theta, *ctx, alone, pre, depth)
            assert alone[0] == full[-1]
            if depth > 1:  # a table one level short is read with the wrong rows: not the same costs
                short = kernels.prefix_states(theta[0], x0c, v0c, xp, vp, ap, base, lp, bp, tr, ff, depth - 1)
                wrong = np.empty(len(seq))
                kernels.batch_costs(seq, theta, *ctx, wrong, np.tile(short, (kernels.N_MODELS, 1)), depth)
                assert not np.array_equal(wrong, full)
