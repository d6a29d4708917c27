"""Paper A controllers: parameters, determinism, OPO bounds, MCF vs single models, closed-loop S-D / S-E runs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import controllers.mcf_dmpc  # noqa: F401  (registers)
from controllers.base import Observation, OwnState, PredecessorState, create
from controllers.mcf_dmpc.cf_models import THETA_BOUNDS, THETA_TRAIN2, THETA_TRAIN3
from controllers.mcf_dmpc.controller import McfDmpc, McfParams
from controllers.mcf_dmpc.cost import dmpc_cost
from controllers.mcf_dmpc.metrics import follower_metrics
from controllers.mcf_dmpc.opo import OpoSettings, opo_step
from controllers.mcf_dmpc.rollout import constant_speed_horizon, rollout_models
from controllers.mcf_dmpc.sim import S_E_SEGMENTS, paper000_leader, run_platoon
from controllers.mcf_dmpc.spacing import TABLE_I, desired_spacing_m, paper000_vehicle

KMH = 1 / 3.6
VEH = paper000_vehicle()


def _obs(x=1500.0, v=200 * KMH, xp=2000.0, vp=220 * KMH):
    pred = PredecessorState("T1", xp, vp, 0.0, 203.0, 0.0, 0.0, 0.8, 1.0)
    return Observation(0.0, 1.0, OwnState("T2", x, v, 0.0, 203.0), VEH, 1e9, predecessor=pred)


def _greedy_standin(fitness, dim, n_values, *, method, population, iterations, rng, init=None):
    """Tiny stand-in optimiser (coordinate descent from the seeds) for tests independent of the optim package."""

    class R:  # noqa: D401
        pass

    starts = np.atleast_2d(init) if init is not None else rng.integers(0, n_values, (1, dim))
    costs = fitness(starts)
    best = starts[int(np.argmin(costs))].copy()
    best_cost = float(np.min(costs))
    for _ in range(2):
        for d in range(dim):
            cand = np.repeat(best[None, :], n_values, axis=0)
            cand[:, d] = np.arange(n_values)
            c = fitness(cand)
            k = int(np.argmin(c))
            if c[k] < best_cost:
                best, best_cost = cand[k].copy(), float(c[k])
    r = R()
    r.best, r.best_cost, r.history, r.evaluations = best, best_cost, [best_cost], 0
    return r


@pytest.mark.parametrize(
    "name,params,field",
    [
        ("cf_idm", {"horizon_steps": 0}, "horizon_steps"),
        ("cf_idm", {"horizon_steps": 2.5}, "horizon_steps"),
        ("cf_cacc", {"theta_preset": "train9"}, "theta_preset"),
        ("cf_fvd", {"theta2": -1.0}, "theta2"),
        ("cf_fvd", {"nonsense": 1.0}, "nonsense"),
        ("mcf_dmpc", {"optimizer": "tabu"}, "optimizer"),
        ("mcf_dmpc", {"decision_dim": 61}, "decision_dim"),
        ("opo_mcf_dmpc", {"theta4_max": 1e-4}, "theta4_max"),
        ("dmpc", {"sqp_iterations": 0}, "sqp_iterations"),
        ("dmpc", {"xi_u": -1.0}, "xi_u"),
        ("dmpc", {"cacc_feedforward": "net"}, "cacc_feedforward"),
    ],
)
def test_invalid_params_name_the_param(name, params, field):
    with pytest.raises(ValueError) as exc:
        create(name, params, VEH)
    assert str(exc.value).startswith(f"{field}:")


def test_theta_presets_and_overrides():
    c = create("cf_idm", {"theta_preset": "train3", "theta1": 2.0}, VEH)
    assert np.allclose(c.theta, np.r_[2.0, THETA_TRAIN3.as_array()[1:]])
    assert np.allclose(create("cf_idm", {}, VEH).theta, THETA_TRAIN2.as_array())


@pytest.mark.parametrize("name", ["cf_idm", "cf_cacc", "cf_fvd", "dmpc"])
def test_commands_carry_plan_and_info(name):
    cmd = create(name, {}, VEH).command(_obs())
    plan = cmd.info["plan"]
    assert plan["dt_s"] == 1.0 and len(plan["position_m"]) == len(plan["speed_mps"]) == len(plan["accel_mps2"]) == 61
    assert plan["position_m"][0] == 1500.0 and plan["accel_mps2"][0] == cmd.accel_mps2
    assert np.isfinite(cmd.info["J"]) and cmd.info["solve_time_s"] > 0 and -0.8 <= cmd.accel_mps2 <= 1.0


def test_no_predecessor_leaves_ato_in_charge():
    obs = Observation(0.0, 1.0, OwnState("T2", 0.0, 50.0, 0.0, 203.0), VEH, 1e9)
    assert create("dmpc", {}, VEH).command(obs).accel_mps2 == 1.0


@given(
    theta=st.lists(st.floats(-100.0, 100.0), min_size=10, max_size=10),
    v=st.floats(30.0, 90.0),
    gap=st.floats(360.0, 3000.0),
    vp=st.floats(30.0, 90.0),
)
@settings(max_examples=25, deadline=None)
def test_opo_keeps_theta_in_bounds_and_never_worsens(theta, v, gap, vp):
    n = 20
    hz = constant_speed_horizon(gap, vp, n, 1.0, 203.0, 1.0)

    def batch(seqs, thetas):
        return dmpc_cost(rollout_models(seqs, 0.0, v, hz, thetas, TABLE_I), hz, 0.0, TABLE_I)

    s = OpoSettings(iterations=4)
    res = opo_step(np.array(theta), batch, n, s)
    lo, hi = THETA_BOUNDS.T
    assert np.all(res.theta >= lo) and np.all(res.theta <= hi)
    start = np.clip(np.array(theta), lo, hi)
    start_costs = batch(np.repeat(np.arange(3)[:, None], n, axis=1), np.tile(start, (3, 1)))
    assert np.all(res.model_costs <= start_costs + 1e-9)


def test_mcf_never_worse_than_best_single_model_and_deterministic():
    params = McfParams(horizon_steps=20, population=6, iterations=2, seed=3)
    obs = _obs()
    a = McfDmpc(params, VEH, _greedy_standin)
    b = McfDmpc(params, VEH, _greedy_standin)
    ca, cb = a.command(obs), b.command(obs)
    assert ca.accel_mps2 == cb.accel_mps2 and ca.info["model_sequence"] == cb.info["model_sequence"]
    singles = [create(n, {"horizon_steps": 20}, VEH).command(obs).info["J"] for n in ("cf_idm", "cf_cacc", "cf_fvd")]
    assert ca.info["J"] <= min(singles) + 1e-9


def test_registered_mcf_and_opo_deterministic_with_real_optimizer():
    pytest.importorskip("controllers.mcf_dmpc.optim")
    for name in ("mcf_dmpc", "opo_mcf_dmpc"):
        p = {"horizon_steps": 15, "population": 6, "iterations": 2, "seed": 7}
        c1, c2 = create(name, p, VEH), create(name, p, VEH)
        for obs in (_obs(), _obs(x=1520.0, v=56.0)):
            r1, r2 = c1.command(obs), c2.command(obs)
            assert r1.accel_mps2 == r2.accel_mps2 and r1.info["model_sequence"] == r2.info["model_sequence"]
        if name == "opo_mcf_dmpc":
            lo, hi = THETA_BOUNDS.T
            assert np.all(np.array(r1.info["theta"]) >= lo) and np.all(np.array(r1.info["theta"]) <= hi)


@pytest.mark.parametrize(
    "name,theta,ff,expected",
    [
        ("cf_idm", "train2", "net", lambda w, de: de * ((1 - w) ** (-1 / 12.1) - 1)),
        ("cf_idm", "train3", "net", lambda w, de: de * ((1 - w) ** (-1 / 16.7) - 1)),
        ("cf_cacc", "train2", "net", lambda w, de: w / 0.011),
        ("cf_fvd", "train2", "net", lambda w, de: w / 0.012),
    ],
)
def test_steady_state_offset_under_resistance(name, theta, ff, expected):
    """A9 reading: the law's output is u, so at equilibrium it must equal ω(v) -> a closed-form spacing offset."""
    v0 = 220 * KMH
    de = float(desired_spacing_m(v0, v0))
    run = run_platoon(
        [create(name, {"theta_preset": theta, "cacc_feedforward": ff}, VEH)],
        [de, 0.0],
        [v0, v0],
        1200,
        noise_sd_mps2=0.0,
    )
    err = run.spacing_m[-1, 0] - run.desired_m[-1, 0]
    omega = float(TABLE_I.resistance_mps2(v0))
    assert abs(run.speed_error_mps[-1, 0]) < 1e-3
    assert err == pytest.approx(expected(omega, de), abs=0.05)


def test_cacc_feedforward_reading_changes_offset_train3():
    """A13: θ3·a_pred with the predecessor's applied control ω instead of its net acceleration 0."""
    v0 = 220 * KMH
    de = float(desired_spacing_m(v0, v0))
    leader = create("cf_cacc", {"theta_preset": "train2"}, VEH)  # a follower that itself cruises at u = ω
    follower = create("cf_cacc", {"theta_preset": "train3", "cacc_feedforward": "applied"}, VEH)
    off2 = 0.096568 / 0.011
    run = run_platoon([leader, follower], [2 * de + off2, de + off2, 0.0], [v0, v0, v0], 1200, noise_sd_mps2=0.0)
    omega = float(TABLE_I.resistance_mps2(v0))
    err3 = run.spacing_m[-1, 1] - run.desired_m[-1, 1]
    assert err3 == pytest.approx((omega - 0.35 * omega) / 0.012, abs=0.1)


@pytest.mark.parametrize("name", ["cf_idm", "dmpc"])
def test_scenario_sd_establishes_vc_safely(name):
    f = [
        create(name, {} if name == "dmpc" else {"theta_preset": "train2"}, VEH),
        create(name, {} if name == "dmpc" else {"theta_preset": "train3"}, VEH),
    ]
    run = run_platoon(f, [2000.0, 1500.0, 0.0], [220 * KMH, 200 * KMH, 180 * KMH], 500, seed=1)
    for m in follower_metrics(run):
        assert m.min_safety_margin_m >= 0.0
        assert np.isfinite(m.vc_first_s) and m.fallbacks == 0
        assert m.late_mean_abs_spacing_error_m < 10.0 and m.late_mean_abs_dv_mps < 0.1


@pytest.mark.parametrize("name", ["cf_idm", "dmpc"])
def test_scenario_se_tracks_variable_speed_safely(name):
    v0 = 220 * KMH
    de = float(desired_spacing_m(v0, v0))
    run = run_platoon(
        [create(name, {}, VEH)],
        [de, 0.0],
        [v0, v0],
        380,
        seed=1,
        leader=paper000_leader(220.0, S_E_SEGMENTS),
    )
    m = follower_metrics(run, late_start_s=0.0, late_end_s=1e9)[0]
    assert m.min_safety_margin_m >= 0.0 and m.fallbacks == 0
    assert m.mean_abs_spacing_error_m < 20.0
    assert run.v[:, 0].min() == pytest.approx(180 * KMH, abs=0.1)  # speed_profile undershoots a ramp end 0.09 m/s


def test_runner_is_seeded():
    f = lambda: [create("cf_fvd", {}, VEH)]  # noqa: E731
    a = run_platoon(f(), [800.0, 0.0], [60.0, 60.0], 30, seed=5)
    b = run_platoon(f(), [800.0, 0.0], [60.0, 60.0], 30, seed=5)
    c = run_platoon(f(), [800.0, 0.0], [60.0, 60.0], 30, seed=6)
    assert np.array_equal(a.x, b.x) and not np.array_equal(a.x, c.x)
