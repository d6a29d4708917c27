"""Improved and plain PSO: bounds always respected, seeded determinism, mutation trigger, and it optimises."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings, strategies as st

from controllers.junction.pso import PSOParams, improved_pso_params, plain_pso_params, run_pso


def _recording(objective, seen):
    def wrapped(X):
        seen.append(np.array(X, copy=True))
        return objective(X)

    return wrapped


def sphere_with_constraint(X):
    """f = Σ x², constraint x_0 ≥ 0.5 (violation 0.5 − x_0)."""
    return np.sum(X**2, axis=1), np.maximum(0.5 - X[:, 0], 0.0)


@settings(max_examples=25)
@given(
    lo=st.floats(-5.0, 0.0),
    width=st.floats(0.1, 5.0),
    dim=st.integers(1, 12),
    seed=st.integers(0, 2**32 - 1),
    improved=st.booleans(),
    scope=st.sampled_from(["particle", "dimension"]),
)
def test_every_evaluated_particle_is_inside_the_box(lo, width, dim, seed, improved, scope):
    hi = lo + width
    seen: list[np.ndarray] = []
    base = improved_pso_params if improved else plain_pso_params
    params = base(swarm_size=8, max_iterations=25, no_update_scope=scope, variance_threshold=1e9)
    res = run_pso(
        _recording(sphere_with_constraint, seen),
        dim,
        (lo, hi),
        params,
        np.random.default_rng(seed),
        initial=np.full((2, dim), hi + 10.0),
    )  # out-of-box seeds are clipped
    allx = np.vstack(seen)
    assert np.all(allx >= lo) and np.all(allx <= hi)
    assert np.all(res.x >= lo) and np.all(res.x <= hi)


@settings(max_examples=10)
@given(seed=st.integers(0, 2**32 - 1), improved=st.booleans())
def test_same_seed_same_result(seed, improved):
    params = (improved_pso_params if improved else plain_pso_params)(swarm_size=10, max_iterations=40)
    a = run_pso(sphere_with_constraint, 6, (-2.0, 2.0), params, np.random.default_rng(seed))
    b = run_pso(sphere_with_constraint, 6, (-2.0, 2.0), params, np.random.default_rng(seed))
    assert np.array_equal(a.x, b.x) and a.cost == b.cost and a.iterations == b.iterations
    assert a.history == b.history


def test_finds_the_constrained_optimum():
    res = run_pso(
        sphere_with_constraint,
        5,
        (-2.0, 2.0),
        improved_pso_params(swarm_size=30, max_iterations=300),
        np.random.default_rng(1),
    )
    assert res.feasible
    assert abs(res.cost - 0.25) < 0.02  # optimum x = (0.5, 0, 0, 0, 0), f = 0.25


def test_mutation_fires_only_when_the_swarm_collapses():
    params = improved_pso_params(swarm_size=10, max_iterations=200, stall_loops=10**6)
    never = run_pso(
        sphere_with_constraint,
        4,
        (-2.0, 2.0),
        PSOParams(**{**params.__dict__, "variance_threshold": 0.0}),
        np.random.default_rng(3),
    )
    always = run_pso(
        sphere_with_constraint,
        4,
        (-2.0, 2.0),
        PSOParams(**{**params.__dict__, "variance_threshold": 1e12}),
        np.random.default_rng(3),
    )
    assert never.mutations == 0
    # triggered every loop with P_m ∈ [0.1, 0.3]: roughly 20 % of 200 loops
    assert 15 <= always.mutations <= 70


def test_adaptive_penalty_and_inertia_follow_eqs_42_46():
    params = improved_pso_params(swarm_size=12, max_iterations=50, stall_loops=10**6)
    res = run_pso(sphere_with_constraint, 3, (-2.0, 2.0), params, np.random.default_rng(0))
    beta = np.array(res.history["beta"])
    eps = np.array(res.history["epsilon"])
    assert np.allclose(eps, 10.0 ** (params.penalty_alpha * (1.0 - beta)))
    omega = np.array(res.history["omega"])
    assert np.isclose(omega[-1], params.inertia_max - 50 * (params.inertia_max - params.inertia_min) / 50)
    assert np.all(np.diff(omega) <= 1e-12)


def test_wall_time_budget_stops_the_run():
    params = improved_pso_params(
        swarm_size=10, max_iterations=10**6, max_loops=10**7, stall_loops=10**7, wall_time_s=0.05
    )
    res = run_pso(sphere_with_constraint, 3, (-2.0, 2.0), params, np.random.default_rng(0))
    assert res.wall_time_s < 1.0 and res.loops < 10**6
