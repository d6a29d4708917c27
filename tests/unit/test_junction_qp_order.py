"""``qp_order`` (controllers/junction/qp.py): deterministic order enumeration + SCP over OSQP QPs, rollout-verified.

The checks are invariants, not pinned numbers: a plan reported feasible must be feasible under the planner's own
model *and* in an independent time-stepped simulation (passing order, switch interval, coupled state at F); the
same inputs give the identical plan; a frozen order is kept; an impossible input ends as ``feasible=False`` with
the violations named, not as an exception. The guard formula shared with the CACC is checked against the
dead-time stopping model it is built from.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from controllers import line_kernels
from controllers.braking import relative_braking_distance_m, stopping_distance_m
from controllers.junction.model import JunctionParams, SwitchState, sumo_corrected_params
from controllers.junction.planner import TrainState, YJunctionLayout, build_problem, plan, replan
from controllers.junction.qp import order_estimates, solve_qp_order
from controllers.junction.simulate import measure, simulate_plan
from tests.helpers import interpreted

LAYOUT = YJunctionLayout(S5_m=300.0)


def _x(problem, p):
    return np.concatenate([np.array([a for _, _, a in p.train(t.train_id).segments]) for t in problem.trains])


@pytest.mark.parametrize(
    "v_f, v_l, a0, T", [(15.0, 10.0, 0.0, 0.2), (8.0, 12.0, 0.5, 1.0), (3.0, 0.0, -1.0, 5.0), (0.0, 4.0, 0.3, 0.7)]
)
def test_guard_formula_is_the_dead_time_stop_minus_the_leaders_stop(v_f, v_l, a0, T):
    b_f, b_l, margin = 1.5, 1.2, 10.0
    expected = stopping_distance_m(v_f, b_f, T, a0) - v_l * v_l / (2.0 * b_l) + margin
    assert relative_braking_distance_m(v_f, v_l, b_f, b_l, T, a0, margin) == pytest.approx(expected, abs=1e-12)
    # vectorised: the same numbers element-wise
    arr = relative_braking_distance_m(np.array([v_f, v_f]), np.array([v_l, v_l]), b_f, b_l, T, a0, margin)
    assert np.allclose(arr, expected)


def test_guard_on_arrays_is_the_law_element_by_element():
    """Arrays (broadcast against scalars) go through the compiled loop: on random inputs (negative speeds, hard
    braking inside the dead time, zero delay included) every element has the bits of the law's interpreted form
    (:func:`controllers.line_kernels.relative_braking_distance_m` with the JIT off), and so has a call on floats."""
    reference = interpreted(line_kernels).relative_braking_distance_m
    rng = np.random.default_rng(7)
    n = 2000
    v_f, v_l = rng.uniform(-1.0, 30.0, n), rng.uniform(-1.0, 30.0, n)
    b_f = rng.uniform(0.05, 2.0, n)
    delay, a0, margin = rng.uniform(0.0, 3.0, n), rng.uniform(-3.0, 1.5, n), rng.uniform(0.0, 50.0, n)
    delay[:50] = 0.0
    arr = relative_braking_distance_m(v_f, v_l, b_f, 1.2, delay, a0, margin)
    assert arr.shape == (n,)
    for k in range(n):
        args = (float(v_f[k]), float(v_l[k]), float(b_f[k]), 1.2, float(delay[k]), float(a0[k]), float(margin[k]))
        expected = reference(*args)
        assert arr[k] == expected and float(arr[k]).hex() == float(expected).hex()
        if k % 100 == 0:
            one = relative_braking_distance_m(*args)
            assert type(one) is float and one == expected
    grid = relative_braking_distance_m(v_f[:6].reshape(2, 3), 5.0, 1.0, 1.2, 0.5, 0.0, 0.0)
    assert grid.shape == (2, 3)


def test_two_trains_paper_model_feasible_order_interval_and_coupling_hold_in_simulation():
    """Train a on the branch 150 m from sw2, b on the trunk 500 m away, both at 10 m/s: a is first (b cannot reach
    sw2 before a without exceeding the limits, and a closing order would need the reverse throw anyway)."""
    trains = [TrainState("a", "entry1", 150.0, 10.0), TrainState("b", "trunk", 500.0, 10.0)]
    params = JunctionParams()
    p = plan(trains, (), LAYOUT, params, method="qp_order")
    assert p.feasible, p.violations
    assert p.order == ("a", "b")
    problem = build_problem(trains, (), LAYOUT, params)
    out = measure(problem, *simulate_plan(problem, _x(problem, p), dt_s=0.05))
    assert out.order == ("a", "b")
    assert out.headway_shortfall_s <= 1e-6  # ≥ t_ls between the two legs at sw2
    assert out.switch_speed_excess_mps <= 1e-6
    assert out.min_separation_m > 0.0
    assert out.coupled_at_F, out  # Eqs. 2-3 at the leader's arrival at F
    assert sum(p.shapley.values()) == pytest.approx(p.cost, rel=1e-9)


def test_same_inputs_give_the_identical_plan():
    trains = [TrainState("a", "entry1", 150.0, 10.0), TrainState("b", "trunk", 500.0, 10.0)]
    p1 = plan(trains, (), LAYOUT, JunctionParams(), method="qp_order")
    p2 = plan(trains, (), LAYOUT, JunctionParams(), method="qp_order")
    assert p1.order == p2.order
    assert [t.segments for t in p1.trains] == [t.segments for t in p2.trains]
    assert p1.cost == p2.cost and p1.feasible == p2.feasible


def test_keep_order_is_respected_on_replan():
    trains = [TrainState("a", "entry1", 150.0, 10.0), TrainState("b", "trunk", 500.0, 10.0)]
    first = plan(trains, (), LAYOUT, JunctionParams(), method="qp_order")
    forced = dataclasses.replace(first, order=tuple(reversed(first.order)))
    again = replan(forced, trains, (), LAYOUT, JunctionParams(), method="qp_order", keep_order=True)
    assert again.frozen_order
    assert again.order == forced.order


def test_impossible_switch_interval_is_reported_not_raised():
    """A 300 s switch interval cannot be met while both trains keep moving (v ≥ v_eps) within the horizon."""
    trains = [TrainState("a", "entry1", 100.0, 15.0), TrainState("b", "trunk", 120.0, 15.0)]
    params = sumo_corrected_params(throw_time_s=300.0)
    p = plan(trains, (), LAYOUT, params, method="qp_order")
    assert not p.feasible
    assert p.violation > 0.0 and any(v > 0.0 for v in p.violations.values())


def test_time_along_a_profile_and_its_gradient_match_closed_forms():
    """Constant speed: t(y) = y/v exactly; the gradient of t in E = v² matches central differences everywhere."""
    from controllers.junction.qp_kinematics import Kinematics as _Kinematics

    bp = np.array([0.0, 15.0, 40.0, 60.0])
    k = _Kinematics(bp, np.full(4, 100.0))
    t, _, _, ey, _ = k.at(np.array([0.0, 7.5, 40.0, 59.0, 90.0]))
    assert np.allclose(t, np.array([0.0, 7.5, 40.0, 59.0, 90.0]) / 10.0)
    assert np.allclose(ey, 100.0)
    E = np.array([100.0, 64.0, 90.0, 49.0])
    ys = np.array([5.0, 15.0, 33.0, 60.0, 75.0])
    # the full gradient: local rows (t at the segment start + the run inside) chained through the breakpoint times
    kin = _Kinematics(bp, E)
    _, Jt, JE, _, _ = kin.at(ys)
    _, al, be = kin.segment_rows()
    G = np.zeros((bp.size, bp.size))  # d t_bp / dE
    for j in range(bp.size - 1):
        G[j + 1] = G[j]
        G[j + 1, j] += al[j]
        G[j + 1, j + 1] += be[j]
    grad = JE + Jt @ G
    h = 1e-5
    for i in range(bp.size):
        Ep, Em = E.copy(), E.copy()
        Ep[i] += h
        Em[i] -= h
        fd = (_Kinematics(bp, Ep).at(ys)[0] - _Kinematics(bp, Em).at(ys)[0]) / (2 * h)
        assert np.allclose(grad[:, i], fd, atol=1e-7)


def _corrected_table3(sc: int):
    from controllers.junction.qp import InterlockingModel, QpOrderParams
    from controllers.junction.simulate import table3_scenario

    params = sumo_corrected_params(switch_speed_margin_mps=0.3)
    il = InterlockingModel(release_after_m=40.0, throw_s=10.0, grant_before_m=17.0, brake_decel_mps2=0.96)
    trains, layout = table3_scenario(sc)
    return trains, layout, params, QpOrderParams(zone_m=30.0, interlocking=il)


@pytest.mark.parametrize("sc", [1, 2, 3])
def test_table3_under_the_corrected_model_couples_and_keeps_guard_and_interlocking_in_simulation(sc):
    """The model SUMO flies (t_ls 21.6 s, 20 m trains, the RBD guard, the engine's interlocking rule): the plan is
    feasible, and an independent time-stepped run of it (Δt = 0.05 s) couples at F, keeps the turnout limit over
    the whole zone, never lets a follower inside the guard's spacing and never needs a switch before the
    interlocking could have released and thrown it."""
    trains, layout, params, qp = _corrected_table3(sc)
    p = plan(trains, (), layout, params, method="qp_order", qp=qp)
    assert p.feasible, p.violations
    problem = build_problem(trains, (), layout, params)
    t, s, v = simulate_plan(problem, _x(problem, p), dt_s=0.05)
    out = measure(problem, t, s, v)
    assert out.coupled_at_F, out
    assert out.switch_speed_excess_mps <= 1e-6 and out.headway_shortfall_s <= 1e-6
    il = qp.interlocking
    L = params.pred_length_m
    for k, tr in enumerate(problem.trains):
        for sw in tr.switches:  # the turnout limit from the switch point until the rear has cleared the turnout
            inside = (s[:, k] >= sw.distance_m) & (s[:, k] <= sw.distance_m + qp.zone_m)
            assert np.all(v[inside, k] <= params.limit_speed_mps(sw.leg) - 0.3 + 0.05)
    idx = {tid: i for i, tid in enumerate(tr.train_id for tr in problem.trains)}
    order = [idx[tid] for tid in p.order]
    s_tilde = s - problem.merge_distance_m[None, :]
    for a, b in zip(order, order[1:]):  # the guard on shared track (both past the merge switch)
        both = (s_tilde[:, a] >= 0.0) & (s_tilde[:, b] >= 0.0) & (t <= out.coupling_time_s)
        gap = s_tilde[both, a] - s_tilde[both, b] - L
        acc = np.gradient(v[:, b], t)[both]
        need = relative_braking_distance_m(v[both, b], v[both, a], 1.5, 1.5, 0.2, acc, 10.0)
        assert np.all(gap >= need - 0.5), float(np.min(gap - need))
    for sid in ("sw1", "sw2"):  # interlocking: release behind the leader, throw, grant before the braking point
        users = [k for k in order if any(sw.switch_id == sid for sw in problem.trains[k].switches)]
        for a, b in zip(users, users[1:]):
            xa = next(sw for sw in problem.trains[a].switches if sw.switch_id == sid)
            xb = next(sw for sw in problem.trains[b].switches if sw.switch_id == sid)
            if xa.leg == xb.leg:
                continue
            t_rel = float(np.interp(xa.distance_m + il.release_after_m, s[:, a], t))
            brake_at = xb.distance_m - il.grant_before_m - v[:, b] ** 2 / (2.0 * il.brake_decel_mps2)
            t_brake = float(t[np.argmax(s[:, b] >= brake_at)])
            assert t_brake >= t_rel + il.throw_s, (sid, t_brake, t_rel)


def test_replan_from_the_previous_plan_keeps_its_order_and_stays_feasible():
    trains, layout, params, qp = _corrected_table3(1)
    first = plan(trains, (), layout, params, method="qp_order", qp=qp)
    problem = build_problem(trains, (), layout, params)
    t, s, v = simulate_plan(problem, _x(problem, first), dt_s=0.1, horizon_s=4.0)
    moved = [
        TrainState(tr.train_id, tr.track, tr.distance_to_switch_m - float(s[-1, k]), float(v[-1, k]))
        for k, tr in enumerate(trains)
    ]
    again = replan(first, moved, (), layout, params, method="qp_order", qp=qp)
    assert again.feasible, again.violations
    assert again.order == first.order
    assert abs((again.coupling_time_s + 4.0) - first.coupling_time_s) < 3.0  # the same plan, seen 4 s later


@pytest.mark.parametrize("sc", [1, 2, 3])
def test_first_plan_tries_at_most_two_orders_within_its_qp_budget_and_polishing_lowers_its_cost(sc):
    """The online first plan: the two orders of the earliest estimated coupling, ``first_iterations`` QPs each,
    feasible here without the full order search; warm re-plans from the same state (what the coordinator does
    while a plan has not converged) keep the order and feasibility and never raise the cost, and end converged."""
    trains, layout, params, qp = _corrected_table3(sc)
    problem = build_problem(trains, (), layout, params)
    r = solve_qp_order(problem, qp)
    assert r.feasible, r.violations
    assert r.orders_solved <= qp.first_orders and r.iterations <= qp.first_orders * qp.first_iterations
    current = plan(trains, (), layout, params, method="qp_order", qp=qp)
    assert current.order == tuple(problem.trains[k].train_id for k in r.order)
    for _ in range(20):
        if current.converged:
            break
        again = replan(current, trains, (), layout, params, method="qp_order", qp=qp)
        assert again.feasible and again.order == current.order
        assert again.cost <= current.cost + 1e-6
        current = again
    assert current.converged


def test_order_estimates_charge_the_throw_of_a_switch_not_set_for_the_first_train():
    """Two orders that differ only in which sw1 train goes first: with sw1 set normal, the order whose first sw1
    train takes the normal leg needs one throw fewer and is estimated to couple earlier; set reverse, the other."""
    trains, layout, params, qp = _corrected_table3(1)
    problem = build_problem(trains, (), layout, params)
    legs = {tr.train_id: {sw.switch_id: sw.leg for sw in tr.switches} for tr in problem.trains}
    k_normal = next(k for k, tr in enumerate(problem.trains) if legs[tr.train_id].get("sw1") == "normal")
    k_reverse = next(k for k, tr in enumerate(problem.trains) if legs[tr.train_id].get("sw1") == "reverse")
    k_other = ({0, 1, 2} - {k_normal, k_reverse}).pop()
    orders = [(k_other, k_normal, k_reverse), (k_other, k_reverse, k_normal)]
    for position, earlier in (("normal", 0), ("reverse", 1)):
        sw = [SwitchState("sw1", position), SwitchState("sw2", "normal")]
        est = order_estimates(build_problem(trains, sw, layout, params), qp, orders)
        assert est[earlier] < est[1 - earlier], (position, est)


# a state met on the benchmark's trajectory in scenario 1 (corrected model): the order with the earliest estimated
# coupling cannot meet its switch interval (it keeps ~17 s of violation), the runner-up can
_HARD_STATE = [
    TrainState("train1", "entry1", 260.904, 16.9207),
    TrainState("train2", "entry2", 94.3443, 12.0144),
    TrainState("train3", "entry3", 78.3804, 5.5364),
]


@pytest.mark.parametrize("first_iterations", [8, 2])
def test_first_plan_budget_in_qp_solves_holds_when_the_first_order_fails(first_iterations):
    """The first plan never exceeds ``first_orders·first_iterations + rescue_iterations`` QPs, tries at most
    ``first_orders`` orders, and is deterministic. With the default budget the runner-up order is solved and
    feasible; starved to 2 QPs per order neither is, and the rescue continues the less violating one (a plan that
    is still infeasible is reported so, its violations named — never an exception, never an unbounded search)."""
    _, layout, params, qp = _corrected_table3(1)
    # the engine's settings for these scenarios (the junction coordinator): turnouts approached inside the ATO's envelope
    qp = dataclasses.replace(
        qp, approach_decel_mps2=0.48, approach_hold_m=20.0, line_speed_margin_mps=3.0, first_iterations=first_iterations
    )
    problem = build_problem(_HARD_STATE, (), layout, params)
    r = solve_qp_order(problem, qp)
    assert r.iterations <= qp.first_orders * qp.first_iterations + qp.rescue_iterations
    assert r.orders_solved <= qp.first_orders
    if first_iterations == 8:
        assert r.orders_solved == 2 and r.feasible, r.violations
        assert r.iterations <= qp.first_orders * qp.first_iterations  # no rescue needed
    else:
        assert r.iterations > qp.first_orders * qp.first_iterations  # the rescue ran
        assert r.feasible or (r.violation > 0.0 and any(v > 0.0 for v in r.violations.values()))
    again = solve_qp_order(build_problem(_HARD_STATE, (), layout, params), qp)
    assert again.order == r.order and np.array_equal(again.x, r.x) and again.iterations == r.iterations


def test_replan_budget_in_qp_solves():
    """A warm re-plan solves at most ``replan_iterations`` QPs in one order, from any state along the plan."""
    trains, layout, params, qp = _corrected_table3(2)
    current = plan(trains, (), layout, params, method="qp_order", qp=qp)
    problem = build_problem(trains, (), layout, params)
    t, s, v = simulate_plan(problem, _x(problem, current), dt_s=0.1, horizon_s=12.0)
    for i in range(20, t.size, 20):  # every 2 s
        moved = [
            TrainState(tr.train_id, tr.track, tr.distance_to_switch_m - float(s[i, k]), float(v[i, k]))
            for k, tr in enumerate(trains)
        ]
        again = replan(current, moved, (), layout, params, method="qp_order", qp=qp)
        assert again.iterations <= qp.replan_iterations
        assert again.order == current.order


def test_soft_rows_jacobian_matches_finite_differences():
    """The sparse Jacobian the QPs are built from (rows over ``[E…, t…]``, the breakpoint times chained through
    the segment times) against central differences of the exact constraint values, for the rows whose value
    depends on ``E`` only through the rows' own entries: switch intervals and the coupling conditions."""
    from controllers.junction.qp import _OrderSCP, _Structure
    from controllers.junction.qp_kinematics import Kinematics
    from controllers.junction.qp_timetable import timetable_E

    trains, layout, params, qp = _corrected_table3(1)
    problem = build_problem(trains, (), layout, params)
    scp = _OrderSCP(_Structure(problem, qp), (0, 1, 2))
    z = timetable_E(scp)
    c, jac, kinds = scp.soft(z)
    J = np.zeros((jac.m, 2 * scp.nE))
    np.add.at(J, (jac.rows, jac.cols), jac.vals)
    G = np.zeros((scp.nE, scp.nE))  # d t_bp / d E, block per train
    for k, E in enumerate(scp.split(z)):
        _, al, be = Kinematics(scp.bp[k], E).segment_rows()
        o = scp.off[k]
        for j in range(al.size):
            G[o + j + 1] = G[o + j]
            G[o + j + 1, o + j] += al[j]
            G[o + j + 1, o + j + 1] += be[j]
    total = J[:, : scp.nE] + J[:, scp.nE :] @ G
    rows = [i for i, kd in enumerate(kinds) if kd in ("switch_headway", "coupling_gap", "coupling_speed")]
    assert len(rows) >= 6
    h = 1e-4
    for i in range(scp.nE):
        if scp.ub[i] - scp.lb[i] < 1e-6:  # the initial speed is fixed
            continue
        if i == scp.off[scp.lead + 1] - 1:  # the leader's E at F also scales the coupling tolerances (held fixed)
            continue
        zp, zm = z.copy(), z.copy()
        zp[i] += h
        zm[i] -= h
        fd = (scp._soft(zp)[0] - scp._soft(zm)[0]) / (2 * h)
        assert np.allclose(total[rows, i], fd[rows], atol=1e-6, rtol=1e-4), i
