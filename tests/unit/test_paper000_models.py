"""Paper A spacing laws, CF laws, rollout and cost: closed forms, equilibria, invariants (spec 000 §2, §7)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from controllers.base import PredecessorState
from controllers.mcf_dmpc.cf_models import (
    THETA_BOUNDS,
    THETA_TRAIN2,
    THETA_TRAIN3,
    enhanced_cacc,
    enhanced_fvd,
    enhanced_idm,
    original_idm,
)
from controllers.mcf_dmpc.cost import TABLE_II, cost_terms
from controllers.mcf_dmpc.rollout import (
    constant_speed_horizon,
    predecessor_horizon,
    rollout_controls,
    rollout_models,
)
from controllers.mcf_dmpc.spacing import TABLE_I, desired_spacing_m, paper000_vehicle, safe_spacing_m
from railsim.physics.dynamics import PlantState, step

KMH = 1 / 3.6


def test_spacing_closed_forms_table_i():
    v = np.array([0.0, 50.0, 220 * KMH, 97.0])
    assert np.allclose(desired_spacing_m(v, v), 145.8333333 + 203 + v * v * (1 / 1.6 - 1 / 2.0))
    assert np.allclose(safe_spacing_m(v, v), 145.8333333 + 203)
    assert desired_spacing_m(220 * KMH, 220 * KMH) == pytest.approx(815.654, abs=1e-3)
    # spec §2.3: S-A initial conditions, train 2 behind the leader
    assert desired_spacing_m(200 * KMH, 220 * KMH) == pytest.approx(410.56, abs=0.01)
    assert safe_spacing_m(200 * KMH, 220 * KMH) == pytest.approx(24.76, abs=0.01)


def test_resistance_values_and_vehicle():
    assert TABLE_I.resistance_mps2(50.0) == pytest.approx(0.0756, abs=1e-5)
    assert TABLE_I.resistance_mps2(0.0) == 0.0
    veh = paper000_vehicle()
    assert veh.mass_kg == 1.0 and veh.actuator_time_constant_s == 0.0
    assert veh.resistance_n(61.0) == pytest.approx(float(TABLE_I.resistance_mps2(61.0)))


@given(v0=st.floats(1.0, 95.0), u=st.floats(-0.8, 1.0))
@settings(max_examples=50, deadline=None)
def test_plant_ballistic_step_is_eq2(v0, u):
    """railsim's plant with the Paper A vehicle and the ballistic update is Eq. (2)."""
    res = step(paper000_vehicle(), PlantState(v0), u, 1.0, step_method="ballistic")
    a = u - float(TABLE_I.resistance_mps2(v0))
    assert res.v_next_mps == pytest.approx(v0 + a, abs=1e-12)
    assert res.advance_m == pytest.approx(v0 + 0.5 * a, abs=1e-9)
    traj = rollout_controls(np.array([[u]]), 0.0, v0, TABLE_I)
    assert traj.v[0, 1] == pytest.approx(res.v_next_mps, abs=1e-12)
    assert traj.s[0, 1] == pytest.approx(res.advance_m, abs=1e-9)


THETAS = st.tuples(*(st.floats(float(lo), float(hi)) for lo, hi in THETA_BOUNDS[:7]))  # θ1 … θ7 (not the offsets)


@given(v=st.floats(1.0, 97.0), theta=THETAS)
@settings(max_examples=100, deadline=None)
def test_enhanced_laws_vanish_at_equilibrium(v, theta):
    """v = v_pred and ΔS = D^(e) is an equilibrium of all three enhanced laws, for any Θ in the box."""
    de = float(desired_spacing_m(v, v))
    t1, t2, t3, t4, t5, t6, t7 = theta
    assert enhanced_idm(v, v, de, de, t1, t2) == pytest.approx(0.0, abs=1e-12)
    assert enhanced_cacc(v, v, de, de, 0.0, t3, t4, t5) == pytest.approx(0.0, abs=1e-12)
    assert enhanced_fvd(v, v, de, de, t6, t7) == pytest.approx(0.0, abs=1e-9)
    # the flaw of the original IDM (Eq. 7) the paper fixes: −a_m at the same point
    assert original_idm(v, v, de, de, a_max=1.0, u_min=None) == pytest.approx(-1.0, abs=1e-12)


@given(
    v=st.floats(0.0, 97.0), vp=st.floats(0.0, 97.0), gap=st.floats(-50.0, 5000.0), theta=THETAS, ap=st.floats(-1.0, 1.0)
)
@settings(max_examples=200, deadline=None)
def test_laws_saturated_and_finite(v, vp, gap, theta, ap):
    de = desired_spacing_m(v, vp)
    t1, t2, t3, t4, t5, t6, t7 = theta
    for a in (
        enhanced_idm(v, vp, gap, de, t1, t2),
        enhanced_cacc(v, vp, gap, de, ap, t3, t4, t5),
        enhanced_fvd(v, vp, gap, de, t6, t7),
    ):
        assert np.isfinite(a) and -0.8 <= a <= 1.0


def test_law_signs_follow_errors():
    v = 60.0
    de = float(desired_spacing_m(v, v))
    th = THETA_TRAIN2
    # too far behind -> accelerate; too close -> brake
    assert (
        enhanced_idm(v, v, de + 50, de, th.theta1, th.theta2)
        > 0
        > enhanced_idm(v, v, de - 50, de, th.theta1, th.theta2)
    )
    assert enhanced_cacc(v, v, de + 50, de, 0, th.theta3, th.theta4, th.theta5) == pytest.approx(50 * th.theta4)
    # FVD close-range term (Eq. 12) only acts when ΔS <= D^(e)
    far = enhanced_fvd(v, v + 1, de + 1, de, 0.0, 0.01, u_min=None)
    near = enhanced_fvd(v, v + 1, de - 1, de, 0.0, 0.01, u_min=None)
    assert far == 0.0 and near == pytest.approx(0.01)


def test_vectorised_rollout_matches_scalar_laws():
    hz = constant_speed_horizon(2000.0, 61.1, 10, 1.0, 203.0, 1.0)
    seqs = np.array([[0] * 10, [1] * 10, [2] * 10, [0, 1, 2, 0, 1, 2, 0, 1, 2, 0]])
    theta = THETA_TRAIN3.as_array()
    traj = rollout_models(seqs, 1500.0, 55.0, hz, theta, TABLE_I)
    de = desired_spacing_m(55.0, 61.1)
    t = theta
    first = [
        enhanced_idm(55.0, 61.1, 500.0, de, t[0], t[1]),
        enhanced_cacc(55.0, 61.1, 500.0, de, 0.0, *t[2:5]),
        enhanced_fvd(55.0, 61.1, 500.0, de, t[5], t[6]),
    ]
    assert np.allclose(traj.u[:3, 0], first)
    # each row is its own closed loop: re-simulating its controls reproduces its states
    again = rollout_controls(traj.u, 1500.0, 55.0, TABLE_I)
    assert np.allclose(again.v, traj.v) and np.allclose(again.s, traj.s)
    # mixed row: step j uses model seq[j] on the predicted state of that step
    j = 4
    de_j = desired_spacing_m(traj.v[3, j], hz.speed_mps[j])
    gap_j = hz.position_m[j] - traj.s[3, j]
    assert traj.u[3, j] == pytest.approx(float(enhanced_cacc(traj.v[3, j], hz.speed_mps[j], gap_j, de_j, 0.0, *t[2:5])))


def test_cost_terms_closed_form():
    """Eq. (14)-(19) on a hand-made trajectory (A18 terminal weights, A19 previous-control term once)."""
    n = 3
    hz = constant_speed_horizon(1000.0, 50.0, n, 1.0, 203.0, 1.0)
    u = np.array([[0.1, 0.2, -0.1]])
    traj = rollout_controls(u, 0.0, 49.0, TABLE_I)
    terms = cost_terms(traj, hz, 0.05, TABLE_I)
    v, s = traj.v[0, 1:], traj.s[0, 1:]
    e = hz.position_m[1:] - s - desired_spacing_m(v, 50.0)
    w = TABLE_II
    expect = (
        w.xi_v * np.sum((v - 50) ** 2)
        + w.xi_s * np.sum(e**2)
        + w.xi_u * np.sum(u**2)
        + w.xi_du * ((0.1 - 0.05) ** 2 + 0.1**2 + 0.3**2)
        + w.xi_term * (w.xi_v * (v[-1] - 50) ** 2 + w.xi_s * e[-1] ** 2)
    )
    assert terms["penalty"][0] == 0.0
    assert terms["J"][0] == pytest.approx(expect, rel=1e-12)
    # a trajectory that runs into the safe spacing is penalised per metre of violation
    close = constant_speed_horizon(300.0, 50.0, n, 1.0, 203.0, 1.0)
    bad = cost_terms(traj, close, 0.05, TABLE_I)
    viol = np.sum(np.maximum(safe_spacing_m(v, 50.0) - (close.position_m[1:] - s), 0.0))
    assert bad["penalty"][0] == pytest.approx(1e6 * viol)


def test_predecessor_horizon_shifts_plan_by_age():
    plan_x = tuple(100.0 + 50.0 * j + 0.1 * j * j for j in range(6))
    plan_v = tuple(50.0 + 0.2 * j for j in range(6))
    pred = PredecessorState(
        "T1",
        plan_x[0],
        plan_v[0],
        0.2,
        203.0,
        stamp_s=10.0,
        age_s=1.0,
        planned_position_m=plan_x,
        planned_speed_mps=plan_v,
        planned_accel_mps2=(0.3,) * 6,
        plan_dt_s=1.0,
    )
    hz = predecessor_horizon(pred, 6, 1.0)
    assert np.allclose(hz.position_m[:5], plan_x[1:])
    assert np.allclose(hz.speed_mps[:5], plan_v[1:])
    # past the plan's end: constant speed from its last sample
    assert hz.position_m[6] == pytest.approx(plan_x[-1] + 2 * plan_v[-1])
    assert hz.speed_mps[6] == plan_v[-1]
    assert np.allclose(hz.accel_mps2[:4], 0.2)  # net acceleration from the planned speeds (A13 default)
    assert np.allclose(predecessor_horizon(pred, 6, 1.0, "applied").accel_mps2, 0.3)
    # no plan: constant-speed extrapolation from the (aged) report
    bare = PredecessorState("T1", 100.0, 50.0, 0.0, 203.0, stamp_s=10.0, age_s=1.0)
    hz2 = predecessor_horizon(bare, 3, 1.0)
    assert np.allclose(hz2.position_m, [150, 200, 250, 300]) and np.all(hz2.accel_mps2 == 0)
