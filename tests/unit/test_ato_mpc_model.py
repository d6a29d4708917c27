"""Paper B controller model and QP: spec §8 matrix tests, linearisation, prediction, QP vs brute force, terminal P."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.optimize

from controllers.ato_mpc.model import (
    affine_map,
    affine_term,
    build_model,
    continuous_model,
    discretise,
    prediction_matrices,
)
from controllers.ato_mpc.qp import CondensedMpc, MpcSettings, ReferenceWindow, stage_weight, terminal_ingredients
from railsim.physics.multipoint import (
    G_MPS2,
    MultipointParams,
    accelerations_mps2,
    initial_state,
    state_from_relative,
    step,
)

P = MultipointParams()
M, K, L = P.car_mass_kg, P.coupler_stiffness_n_per_m, P.coupler_length_m


def test_matrices_match_the_spec_for_six_carriages():
    vr = 20.0
    w = np.array([1.0, -2.0, 3.0, 0.5, -1.5, 2.5])  # permille
    a, b, d = continuous_model(P, vr, w)
    n = 6
    assert np.allclose(a[:n, :n], 0.0) and np.allclose(a[:n, n:], np.eye(n))
    a21 = (
        np.array(
            [
                [0, 1, 0, 0, 0, 0],
                [0, -2, 1, 0, 0, 0],
                [0, 1, -2, 1, 0, 0],
                [0, 0, 1, -2, 1, 0],
                [0, 0, 0, 1, -2, 1],
                [0, 0, 0, 0, 1, -2],
            ],
            dtype=float,
        )
        * K
        / M
    )
    assert np.allclose(a[n:, :n], a21, rtol=1e-12, atol=1e-9)
    assert np.allclose(a[n:, n:], -(P.c1_per_s + 2 * P.c2_per_m * vr) * np.eye(n), atol=1e-15)
    lower = (np.eye(n) - np.eye(n, k=-1)) / M
    assert np.allclose(b[:n], 0.0) and np.allclose(b[n:], lower)
    wi = G_MPS2 * w * 1e-3
    expect = np.zeros(2 * n)
    expect[n] = -P.c0_mps2 + P.c2_per_m * vr**2 + K * L / M - wi[0]
    expect[n + 1] = wi[0] - wi[1] - K * L / M
    expect[n + 2 : 2 * n - 1] = wi[1 : n - 2] - wi[2 : n - 1]  # the corrected middle rows: no spring constant
    expect[2 * n - 1] = wi[n - 2] - wi[n - 1] - K * L / M
    assert np.allclose(d, expect, rtol=1e-12, atol=1e-9)
    assert np.allclose(affine_term(P, vr, w), d, atol=1e-9)
    assert K * L / M == pytest.approx(185.185, abs=1e-3)


def test_spring_equilibrium_gives_zero_relative_acceleration():
    n = 6
    vr = 15.0
    a, b, d = continuous_model(P, vr, np.zeros(n))
    x = np.concatenate(([123.0], np.full(n - 1, -L), [vr], np.zeros(n - 1)))
    xdot = a @ x + d
    assert np.allclose(xdot[n + 1 :], 0.0, atol=1e-9)  # no relative acceleration
    assert xdot[n] == pytest.approx(-(P.c0_mps2 + P.c1_per_s * vr + P.c2_per_m * vr**2), rel=1e-9)


def test_linearisation_error_shrinks_quadratically_with_the_perturbation():
    """Linear vector field vs Eq. (1)–(3) at v_r + δ: the only nonlinearity is c2·v², so the error is c2·δ²."""
    vr = 20.0
    a, b, d = continuous_model(P, vr, np.zeros(6))
    u = np.full(6, 3e4)
    rng = np.random.default_rng(1)
    shape = rng.normal(size=6)
    errs = []
    for delta in (2.0, 1.0, 0.5):
        s0 = initial_state(P, 0.0, vr)
        v = vr + delta * shape / np.max(np.abs(shape))
        x = s0.positions_m + 1e-4 * shape
        truth_abs = accelerations_mps2(P, x, v, u, np.zeros(6))
        rel = np.concatenate(([x[0]], np.diff(x), [v[0]], np.diff(v)))
        lin = (a @ rel + b @ u + d)[6:]
        truth_rel = np.concatenate(([truth_abs[0]], np.diff(truth_abs)))
        errs.append(np.max(np.abs(lin - truth_rel)))
    assert errs[0] < 1e-5
    assert errs[0] / errs[1] == pytest.approx(4.0, rel=1e-3) and errs[1] / errs[2] == pytest.approx(4.0, rel=1e-3)


@pytest.mark.parametrize("method", ["zoh", "euler"])
def test_discrete_model_vs_plant_one_step(method):
    """One control period of the discrete model vs the RK4 plant near the reference: ZOH is exact up to c2δ²."""
    vr, period = 20.0, 0.1
    mdl = build_model(P, vr, np.zeros(6), period, method)
    u = np.full(6, 2e4)
    errs = []
    for delta in (0.4, 0.2):
        s = initial_state(P, 0.0, vr + delta)
        nxt = step(P, s, u, period)
        pred = mdl.ad @ s.relative() + mdl.bd @ u + mdl.dd
        errs.append(np.max(np.abs(pred - nxt.relative())))
    if method == "zoh":
        assert errs[0] < 1e-6 and errs[1] < errs[0]
    else:  # Euler drops the ½aT² of the position: error ≈ ½·a·T² with a ≈ 0.3 m/s²
        assert 1e-4 < errs[0] < 5e-3


def test_zoh_affine_map_matches_discretise():
    a, b, d = continuous_model(P, 10.0, np.full(6, 5.0))
    _, _, dd = discretise(a, b, d, 0.1, "zoh")
    assert np.allclose(affine_map(a, 0.1, "zoh") @ d, dd, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("n_p,n_c", [(3, 3), (4, 2)])
def test_prediction_matrices_vs_brute_force_simulation(n_p, n_c):
    mdl = build_model(P, 12.0, np.full(6, 3.0), 0.1)
    f, g, dvec = prediction_matrices(mdl.at, mdl.bt, mdl.dt, n_p, n_c)
    rng = np.random.default_rng(2)
    xi = np.concatenate([initial_state(P, 7.0, 11.0).relative(), rng.normal(scale=1e4, size=6)])
    du = rng.normal(scale=3e3, size=6 * n_c)
    pred = f @ xi + g @ du + dvec
    x = xi.copy()
    for i in range(n_p):
        step_du = du[6 * i : 6 * i + 6] if i < n_c else np.zeros(6)
        x = mdl.at @ x + mdl.bt @ step_du + mdl.dt
        assert np.allclose(pred[18 * i : 18 * i + 18], x, rtol=1e-10, atol=1e-6)


def _window(x0: float, v0: float, dv: float = 0.0) -> ReferenceWindow:
    vr = v0 + dv * np.arange(1, 4)
    xr = x0 + 0.1 * np.cumsum(vr)
    return ReferenceWindow(xr, vr, v0, 1e4, 45.8, np.zeros(6))


def _brute_cost(mpc: CondensedMpc, rel, u_prev, ref, du):
    """Σ stage costs by simulating the augmented model (terminal weight on the last step)."""
    mdl = build_model(P, ref.v_lin_mps, ref.gradient_permille, mpc.s.period_s, mpc.s.discretisation)
    refs = mpc.reference_stack(ref).reshape(mpc.s.horizon_p, -1)
    x = np.concatenate([rel, u_prev])
    total = 0.0
    for i in range(mpc.s.horizon_p):
        d_i = du[6 * i : 6 * i + 6]
        x = mdl.at @ x + mdl.bt @ d_i + mdl.dt
        e = x - refs[i]
        w = mpc.q_bar[18 * i : 18 * i + 18, 18 * i : 18 * i + 18]
        total += e @ w @ e + d_i @ mpc.r_step @ d_i
    return total


@pytest.mark.parametrize("terminal", ["none", "dare"])
def test_condensed_cost_equals_brute_force(terminal):
    mpc = CondensedMpc(P, MpcSettings(terminal=terminal))
    rel = initial_state(P, 100.0, 10.0).relative()
    u_prev = np.full(6, 1e4)
    ref = _window(100.0, 10.5)
    dp = mpc.dense_problem(rel, u_prev, ref)
    rng = np.random.default_rng(3)
    for _ in range(5):
        du = rng.normal(scale=2e3, size=18)
        condensed = 0.5 * du @ dp["h"] @ du + dp["g"] @ du + dp["const"]
        assert condensed == pytest.approx(_brute_cost(mpc, rel, u_prev, ref, du), rel=1e-9)


def test_osqp_matches_the_unconstrained_dense_solution_when_no_limit_is_active():
    mpc = CondensedMpc(P, MpcSettings(terminal="dare", eps=1e-8))
    rel = initial_state(P, 100.0, 10.0).relative()
    u_prev = np.full(6, P.car_mass_kg * (P.c0_mps2 + P.c1_per_s * 10 + P.c2_per_m * 100))
    ref = _window(100.0, 10.0, dv=1e-4)
    dp = mpc.dense_problem(rel, u_prev, ref)
    du_dense = -np.linalg.solve(dp["h"], dp["g"])
    assert np.max(np.abs(du_dense)) < 0.5 * P.force_rate_max_n_per_s * 0.1  # really unconstrained
    u, info = mpc.solve(rel, u_prev, ref)
    assert info.status == "solved" and not info.fallback
    assert np.allclose(u - u_prev, du_dense[:6], atol=1.0)


@pytest.mark.parametrize("terminal", ["none", "dare"])
def test_osqp_matches_scipy_on_a_box_constrained_step(terminal):
    """Large speed error: the Δu box is active. Compare with scipy on the brute-force cost (scaled variables)."""
    mpc = CondensedMpc(P, MpcSettings(terminal=terminal, eps=1e-8))
    rel = initial_state(P, 100.0, 10.0).relative()
    u_prev = np.zeros(6)
    ref = _window(100.0, 10.8, dv=0.05)
    u, info = mpc.solve(rel, u_prev, ref)
    assert not info.fallback
    sc = P.force_rate_max_n_per_s * 0.1
    dp = mpc.dense_problem(rel, u_prev, ref)
    h, g = dp["h"] * sc * sc, dp["g"] * sc
    norm = np.max(np.abs(h))
    res = scipy.optimize.minimize(
        lambda z: (0.5 * z @ h @ z + g @ z) / norm,
        np.zeros(18),
        jac=lambda z: (h @ z + g) / norm,
        bounds=[(-1.0, 1.0)] * 18,
        method="L-BFGS-B",
        options={"ftol": 1e-15, "gtol": 1e-12, "maxiter": 5000},
    )
    assert np.allclose((u - u_prev) / sc, res.x[:6], atol=2e-3)
    assert np.any(np.isclose(np.abs(u - u_prev), sc))  # a bound is active


@pytest.mark.parametrize("method", ["dare", "lyapunov"])
@pytest.mark.parametrize("disc", ["zoh", "euler"])
def test_terminal_ingredients_are_stabilising_and_positive_definite(method, disc):
    s = MpcSettings()
    mdl = build_model(P, 20.0, np.zeros(6), s.period_s, disc)
    q = stage_weight(P, s)
    r = s.r_du * np.eye(6)
    ti = terminal_ingredients(mdl.at, mdl.bt, q, r, method, 6000.0)
    assert ti.spectral_radius < 1.0 and ti.min_eig_p > 0.0 and ti.lyapunov_residual < 1e-8
    acl = mdl.at + mdl.bt @ ti.k
    assert np.max(np.abs(np.linalg.eigvals(acl))) < 1.0


def test_terminal_cost_decreases_along_the_closed_loop():
    """Nominal cruise, small initial error: V = eᵀPe (full P, feed-forward u-ref) decreases every step.

    Checked on the controller's own (ZOH) model as the plant — the setting of the paper's derivation — and on
    the nonlinear RK4 plant, where it must decrease down to a floor set by the c2·δ² model error.
    """
    period, vr = 0.1, 20.0
    s = MpcSettings(terminal="dare", terminal_blocks="full", eps=1e-9)
    mdl = build_model(P, vr, np.zeros(6), period, "zoh")
    u_ff = np.full(6, P.car_mass_kg * (P.c0_mps2 + P.c1_per_s * vr + P.c2_per_m * vr**2))
    for plant in ("model", "nonlinear"):
        mpc = CondensedMpc(P, s, nominal_speed_mps=vr)
        pm = mpc.terminal.p
        x0 = initial_state(P, 0.0, vr).relative()
        x0[6] += 0.002  # 2 mm/s speed error
        x0[2] += 2e-5  # 20 µm coupler deflection
        rel, u_prev = x0, u_ff.copy()
        values = []
        for k in range(60):
            xr = vr * period * (k + np.arange(1, 4))
            ref = ReferenceWindow(xr, np.full(3, vr), vr, 1e6, 45.8, np.zeros(6))
            e = np.concatenate([rel, u_prev]) - np.concatenate(
                ([vr * period * k], np.full(5, -L), [vr], np.zeros(5), u_ff)
            )
            values.append(e @ pm @ e)
            u, info = mpc.solve(rel, u_prev, ref)
            assert not info.fallback and np.all(np.abs(u - u_prev) < 0.5 * 6000.0)
            if plant == "model":
                rel = mdl.ad @ rel + mdl.bd @ u + mdl.dd
            else:
                rel = step(P, state_from_relative(rel), u, period).relative()
            u_prev = u
        v = np.array(values)
        assert v[-1] < 1e-3 * v[0]
        if plant == "model":
            assert np.all(np.diff(v) <= 1e-9 * v[0])
        else:
            assert np.all(np.diff(v) <= 1e-4 * v[0])
