"""Junction planner core: input validation (the documented errors), plan ↔ simulator agreement, re-planning."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from controllers.junction.model import JunctionParams, SwitchState, rollout
from controllers.junction.planner import (
    PlannerError,
    TrainState,
    YJunctionLayout,
    build_problem,
    decode,
    past_point_of_no_return,
    plan,
    replan,
    solve,
)
from controllers.junction.pso import improved_pso_params
from controllers.junction.simulate import measure, simulate_plan, table3_scenario

FAST = improved_pso_params(max_iterations=150)


def test_train_past_its_switch_is_named():
    trains, layout = table3_scenario(1)
    trains[1] = TrainState("train2", "entry2", -5.0, 15.0)
    with pytest.raises(PlannerError, match=r"train2: already past switch sw1"):
        build_problem(trains, (), layout)
    trains[1] = TrainState("train2", "trunk", -1.0, 15.0)
    with pytest.raises(PlannerError, match=r"train2: already past switch sw2"):
        build_problem(trains, (), layout)


def test_switch_locked_for_another_train_is_named():
    trains, layout = table3_scenario(1)
    with pytest.raises(PlannerError, match=r"switch sw2: locked for freight7 .* no release time"):
        build_problem(trains, (SwitchState("sw2", "normal", math.inf, "freight7"),), layout)


def test_other_bad_inputs():
    trains, layout = table3_scenario(1)
    with pytest.raises(PlannerError, match="at least 2 trains"):
        build_problem(trains[:1], (), layout)
    with pytest.raises(PlannerError, match=r"train1: speed 0 m/s outside"):
        build_problem([TrainState("train1", "entry1", 400.0, 0.0)] + trains[1:], (), layout)
    with pytest.raises(PlannerError, match=r"switch 'sw9'"):
        build_problem(trains, (SwitchState("sw9"),), layout)
    with pytest.raises(PlannerError, match="unknown track"):
        build_problem([TrainState("x", "siding", 100.0, 5.0)] + trains[1:], (), layout)


def test_finite_lock_is_a_constraint_not_an_error():
    trains, layout = table3_scenario(1)
    lock = SwitchState("sw2", "normal", 40.0, "freight7")
    p = plan(trains, (lock,), layout, pso=FAST, rng=np.random.default_rng(0))
    first = min(c.pass_time_s for c in p.switch_schedule if c.switch_id == "sw2")
    if p.feasible:
        leg_first = next(c for c in p.switch_schedule if c.switch_id == "sw2" and c.pass_time_s == first).leg
        need = 40.0 + (10.0 if leg_first != "normal" else 0.0)
        assert first >= need - 1e-6
    else:
        assert p.violations["switch_state"] > 0.0 or p.violation > 0.0


def test_plan_prediction_matches_independent_simulation():
    trains, layout = table3_scenario(2)
    problem = build_problem(trains, (), layout)
    res = solve(problem, "improved_pso", FAST, np.random.default_rng(4))
    p = decode(problem, res.x)
    out = measure(problem, *simulate_plan(problem, res.x, dt_s=0.05))
    assert out.order == p.order
    assert abs(out.coupling_time_s - p.coupling_time_s) < 0.05
    for tp in p.trains:
        for ps in tp.passages:
            assert ps.speed_mps <= JunctionParams().limit_speed_mps(ps.leg) + 1e-9 or not p.feasible
    assert math.isclose(sum(p.shapley.values()), p.cost, rel_tol=1e-9)
    if p.feasible:
        assert out.coupled_at_F
        # switch schedule: consecutive trains on different legs are ≥ t_ls apart
        for sid in ("sw1", "sw2"):
            cmds = [c for c in p.switch_schedule if c.switch_id == sid]
            for a, b in zip(cmds, cmds[1:]):
                if a.leg != b.leg:
                    assert b.pass_time_s - a.pass_time_s >= 10.0 - 1e-6


def test_rollout_of_constant_speed_is_exact():
    trains = [TrainState("a", "entry1", 300.0, 10.0), TrainState("b", "trunk", 100.0, 10.0)]
    problem = build_problem(trains, (), YJunctionLayout())
    r = rollout(problem, np.zeros((1, problem.dimension)))
    # b reaches sw2 at 10 s, a at 30 s: b leads; T_c = b at F = (100 + 200)/10
    assert tuple(r.order[0]) == (1, 0)
    assert math.isclose(r.coupling_time_s[0], 30.0)
    assert math.isclose(r.gap_m[0, 0], 200.0)


def test_replan_freezes_order_past_point_of_no_return():
    trains, layout = table3_scenario(1)
    first = plan(trains, (), layout, pso=FAST, rng=np.random.default_rng(1))
    # 2 s later, every train has run on at its initial speed; train1 (20 m/s, 360 m) is not yet at its PNR
    later = [TrainState(t.train_id, t.track, t.distance_to_switch_m - 2.0 * t.speed_mps, t.speed_mps) for t in trains]
    assert past_point_of_no_return(later) == []
    free = replan(first, later, (), layout, pso=FAST, rng=np.random.default_rng(2))
    assert not free.frozen_order
    # put train3 at 30 m from sw1 at 15 m/s: braking distance 93.75 m > 30 m -> order frozen
    near = list(later)
    near[2] = TrainState("train3", "entry3", 30.0, 15.0)
    assert past_point_of_no_return(near) == ["train3"]
    frozen = replan(first, near, (), layout, pso=FAST, rng=np.random.default_rng(3))
    assert frozen.frozen_order and frozen.order == first.order
    with pytest.raises(PlannerError, match="order is frozen"):
        replan(first, near[:2] + [TrainState("train9", "entry3", 30.0, 15.0)], (), layout, pso=FAST)


def test_plan_is_deterministic_for_a_seed():
    trains, layout = table3_scenario(3)
    a = plan(trains, (), layout, pso=FAST, rng=np.random.default_rng(11))
    b = plan(trains, (), layout, pso=FAST, rng=np.random.default_rng(11))
    assert a.order == b.order and a.cost == b.cost
    assert [t.segments for t in a.trains] == [t.segments for t in b.trains]


@settings(max_examples=40)
@given(d1=st.floats(1.0, 800.0), d2=st.floats(1.0, 800.0), d3=st.floats(1.0, 800.0), v=st.floats(0.5, 20.0))
def test_segment_grid_covers_start_switches_and_F(d1, d2, d3, v):
    trains = [TrainState("a", "entry1", d1, v), TrainState("b", "entry2", d2, v), TrainState("c", "entry3", d3, v)]
    problem = build_problem(trains, (), YJunctionLayout())
    for k, tr in enumerate(problem.trains):
        edges = problem.breakpoints_m[k, : problem.n_segments[k] + 1]
        assert edges[0] == 0.0 and edges[-1] == tr.distance_to_F_m
        assert np.all(np.diff(edges) > 0.0) and np.all(np.diff(edges) <= problem.params.segment_m + 2e-3)
        for sw in tr.switches:
            assert np.min(np.abs(edges - sw.distance_m)) < 1e-6


def test_relative_braking_term_matches_closed_form_at_constant_speeds() -> None:
    """The optional RBD spacing term (``rbd_reaction_s`` > 0): two trains holding their speeds (all accelerations
    0) on the trunk. The leader's rear is at ``v_l·t − m_l − L`` in merge coordinates, the follower passes shared
    point ``x`` at ``t = (x + m_f)/v_f``; the term is the worst ``need − gap`` over the shared points."""
    import numpy as np

    from controllers.junction.model import JunctionParams, rollout
    from controllers.junction.planner import TrainState, YJunctionLayout, build_problem

    params = JunctionParams(pred_length_m=20.0, rbd_reaction_s=1.0, rbd_decel_mps2=1.5, rbd_margin_m=10.0)
    trains = [TrainState("lead", "entry2", 100.0, 8.0), TrainState("fol", "entry3", 150.0, 10.0)]
    problem = build_problem(trains, (), YJunctionLayout(), params)
    x = np.zeros((1, problem.dimension))
    r = rollout(problem, x)
    ((i, j, ii, jj),) = problem.shared_pairs
    lead, fol = (i, j) if problem.trains[i].train_id == "lead" else (j, i)
    jf = jj if fol == j else ii
    m_l, m_f = problem.merge_distance_m[lead], problem.merge_distance_m[fol]
    pts = problem.breakpoints_m[fol, jf] - m_f  # shared points, merge coordinates
    t_f = (pts + m_f) / 10.0
    gap = (8.0 * t_f - m_l) - pts - 20.0
    need = 10.0 * 1.0 + (10.0**2 - 8.0**2) / (2 * 1.5) + 10.0
    expected = max(float(np.max(need - gap)), 0.0)
    assert expected > 0.0  # the follower closes in: the spacing is violated somewhere
    assert r.terms["relative_braking"][0] == pytest.approx(expected, rel=1e-9, abs=1e-9)
    # off by default (the paper): no such term
    plain = build_problem(trains, (), YJunctionLayout(), JunctionParams(pred_length_m=20.0))
    assert "relative_braking" not in rollout(plain, x).terms
