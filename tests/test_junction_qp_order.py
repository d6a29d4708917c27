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

from controllers.braking import relative_braking_distance_m, stopping_distance_m
from controllers.junction.model import JunctionParams, sumo_corrected_params
from controllers.junction.planner import TrainState, YJunctionLayout, build_problem, plan, replan
from controllers.junction.simulate import measure, simulate_plan

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
