"""Paper C's own example and the interfaces around the law (spec 002 §3, §7.2 items 9–10, the engine adapter).

* the validator rejects the paper's printed values (A1: γ̄ = 1000 m, A2: b = 7.7616e-2, T = 0.1 s < T_min) with
  messages that name the assumption, the train/edge and the numbers;
* the corrected ``zhang2024_fig1`` scenario: no violation over k = 0…2000, the regression values of spec 002 §4.2
  (self-regression of the spec author's re-implementation, not numbers from the paper), closed forms at k = 0;
* the registered engine controller gives the paper's ``u`` for the same information, and closing the loop through
  railsim's own plant (``step_method="forward"``) reproduces the reference trajectory;
* the figure writer produces the four PNGs.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import controllers
from controllers.base import Observation, OwnState, PredecessorState
from controllers.distributed import (
    CommGraph,
    ConstraintWindowEmpty,
    EdgeData,
    NeighbourMessage,
    PreconditionError,
    TrainController,
    TrainJoin,
    check_assumptions,
    local_windows,
    min_sample_time_s,
    paper_vehicle,
    simulate,
    zhang2024_fig1,
    zhang2024_train,
)
from railsim.errors import ConfigError
from railsim.physics import dynamics

T = 1.0
V_R = 80.0


@pytest.fixture(scope="module")
def logs() -> dict:
    return {topo: simulate(zhang2024_fig1(topo)) for topo in ("union", "path")}


# ------------------------------------------------------------------------------------------- validator (item 9)


def test_printed_gamma_hi_1000_is_rejected() -> None:
    with pytest.raises(PreconditionError) as err:
        simulate(zhang2024_fig1(gamma_hi_adjacent_m=1000.0))
    e = err.value
    assert isinstance(e, ConfigError)
    fields = {v.field for v in e.violations}
    assert {"edges[1-2].gamma_hi_m", "edges[2-3].gamma_hi_m", "edges[3-4].gamma_hi_m"} <= fields
    assert "d = 5000, γ̄ = 1000 m" in str(e) and "Assumption 2.2" in str(e)
    assert str(e).startswith("<distributed>: edges[1-2].gamma_hi_m: ")


def test_printed_b_is_rejected_by_assumption_2_4() -> None:
    with pytest.raises(PreconditionError) as err:
        simulate(zhang2024_fig1(resist_b_per_s=7.7616e-2))
    v = err.value.violations[0]
    assert v.assumption == "Assumption 2.4" and v.field == "sample_time_s"
    # μ̄ − f̄ = 11 − f(85) with the printed b: the numbers in the message are the real ones
    f85 = 1.176e-2 + 7.7616e-2 * 85 + 1.6e-5 * 85**2
    assert f"μ̄ − f̄ = {11 - f85:.6g}" in v.message and "(v_r − ρ̲)/T = 5" in v.message


def test_t_min_and_short_sampling_period() -> None:
    p = zhang2024_train()
    # T_min closed form (spec 002 §2.4): max((ρ̄ − v_r)/(f̲ − μ̲), (v_r − ρ̲)/(μ̄ − f̄)) with f̲ = f(75), f̄ = f(85)
    f = p.resistance_mps2
    assert min_sample_time_s(p, V_R) == pytest.approx(max(5 / (f(75) + 11), 5 / (11 - f(85))), rel=1e-15)
    assert min_sample_time_s(p, V_R) == pytest.approx(0.46268, abs=5e-6)
    with pytest.raises(PreconditionError) as err:
        simulate(zhang2024_fig1(sample_time_s=0.1))
    assert "train 1 needs T > T_min = 0.462677 s, got T = 0.1 s" in str(err.value)
    assert err.value.k == 0 and err.value.violations[0].assumption == "Assumption 2.4"
    w = local_windows(p, 0.1, V_R)
    # η̲ = +0.388 > η̄ = −0.392 (spec 002 §2.4): the input window is empty at T = 0.1 s
    assert w.eta_lo_m == pytest.approx(0.388, abs=5e-4) and w.eta_hi_m == pytest.approx(-0.392, abs=5e-4)
    assert check_assumptions(zhang2024_fig1(sample_time_s=0.47).graph, {i: p for i in "12346"}, 0.47, V_R) == []


def _with_train_3_4(x_34_m: float, v_3: float, v_4: float):
    s = zhang2024_fig1()
    x0, v0 = dict(s.initial_positions_m), dict(s.initial_speeds_mps)
    x0["4"] = x0["3"] - x_34_m
    v0["3"], v0["4"] = v_3, v_4
    return replace(s, initial_positions_m=x0, initial_speeds_mps=v0)


def test_initial_state_violating_13_is_rejected() -> None:
    # x_34(0) = 105 m is inside [100, 10000] but x_34(0) + T·v_34(0) = 105 − 10 = 95 m is not: (13) alone fails
    with pytest.raises(PreconditionError) as err:
        simulate(_with_train_3_4(105.0, 75.0, 85.0))
    assert [(v.assumption, v.field) for v in err.value.violations] == [("condition (13)", "edges[3-4]")]
    assert "x_ij + T·v_ij = 95 m for edge 3-4 (x_ij = 105 m, v_ij = -10 m/s) outside [100, 10000] m" in str(err.value)
    # x_34(0) = 95 m violates O1 at k = 0 although (13) holds (x_34(1) = 105 m): erratum A8
    with pytest.raises(PreconditionError) as err:
        simulate(_with_train_3_4(95.0, 85.0, 75.0))
    assert [(v.assumption, v.field) for v in err.value.violations] == [
        ("objective O1 at the check step (A8)", "edges[3-4]")
    ]
    # both just inside: accepted, and the run keeps the pair inside its band
    log = simulate(replace(_with_train_3_4(105.0, 80.0, 85.0), horizon_k=50))
    c, _ = log.edge_col("3", "4")
    assert np.nanmin(log.x_rel_m[:, c]) >= 100.0
    # the speed bound of (13): v_1(0) = 85 is on the bound (allowed), 85.5 is not
    s = zhang2024_fig1()
    v0 = dict(s.initial_speeds_mps)
    v0["1"] = 85.5
    with pytest.raises(PreconditionError, match=r"state\[1\]\.v_mps: .*v = 85.5 m/s"):
        simulate(replace(s, initial_speeds_mps=v0))


def test_join_violating_13_is_rejected_at_its_step() -> None:
    s = zhang2024_fig1()
    join = s.events[1]
    assert isinstance(join, TrainJoin)
    bad = replace(join, x_m=89000.0 + 1000.0)  # x_45(1000) = 985.689 − 1000 < γ̲ = 100
    with pytest.raises(PreconditionError) as err:
        simulate(replace(s, events=(s.events[0], bad)))
    assert err.value.k == 1000 and err.value.violations[0].field == "edges[4-5]"
    assert "at k = 1000" in str(err.value)


# ----------------------------------------------------------------------------------- paper scenario (item 10)


@pytest.mark.parametrize("topo", ["union", "path"])
def test_paper_scenario_has_no_violation(logs: dict, topo: str) -> None:
    log = logs[topo]
    assert log.k[-1] == 2000 and not log.flagged
    assert log.violations(tol=0.0) == []
    assert log.feasible.all()
    assert np.nanmax(log.delta_lo_m) <= 0.0 <= np.nanmin(log.delta_hi_m)
    present = {k: {i for i, p in zip(log.train_ids, log.present[k]) if p} for k in (0, 999, 1000, 2000)}
    assert present[0] == present[999] == {"1", "2", "3", "4", "6"}
    assert present[1000] == present[2000] == {"1", "3", "4", "5", "6"}


def test_first_step_closed_forms(logs: dict) -> None:
    """u(0): every s(0) sits on a β bound (±5 m), so u = f(v) − (v − v_r)/T + s/T² exactly."""
    log = logs["union"]
    p = zhang2024_train()
    expected_s = {"1": 5.0, "2": -5.0, "3": 5.0, "4": -5.0, "6": 5.0}
    for i, s in expected_s.items():
        v0 = log.v_mps[0, log.col(i)]
        assert log.s_m[0, log.col(i)] == s
        assert log.u_mps2[0, log.col(i)] == pytest.approx(p.resistance_mps2(v0) - (v0 - V_R) / T + s / T**2, abs=1e-12)
        assert log.v_mps[1, log.col(i)] == pytest.approx(V_R + s / T, abs=1e-12)
    reg = [0.193334, -6.817011, 4.179605, -5.820395, 9.163164]  # spec 002 §4.2 (self-regression)
    got = [log.u_mps2[0, log.col(i)] for i in "12346"]
    assert got == pytest.approx(reg, abs=1e-6)
    assert np.array_equal(logs["path"].u_mps2[0], log.u_mps2[0], equal_nan=True)


@pytest.mark.parametrize("topo,x45,consensus", [("union", 985.689, 24985.6892), ("path", 985.531, 24985.5313)])
def test_regression_values(logs: dict, topo: str, x45: float, consensus: float) -> None:
    log = logs[topo]
    c, sign = log.edge_col("4", "5")
    assert sign * log.x_rel_m[1000, c] == pytest.approx(x45, abs=5e-4)
    # consensus ȳ = x_i − d_i − v_r·k·T with d_1 = 0, d_2 = −5000, …, d_6 = −25000 (spec 002 §3.2)
    offsets = {"1": 0.0, "2": -5000.0, "3": -10000.0, "4": -15000.0, "6": -25000.0}
    ybar = [log.x_m[999, log.col(i)] - offsets[i] - V_R * 999 * T for i in offsets]
    assert max(ybar) - min(ybar) < 1e-6
    assert ybar[0] == pytest.approx(consensus, abs=5e-5)


@pytest.mark.parametrize("topo", ["union", "path"])
def test_converged_before_the_switch_and_at_the_end(logs: dict, topo: str) -> None:
    log = logs[topo]
    for k in (999, 2000):
        active = log.edge_active[k]
        assert np.abs(log.x_rel_m[k, active] - log.edge_d_m[k, active]).max() < 1e-6
        here = log.present[k]
        assert np.abs(log.v_mps[k, here] - V_R).max() < 1e-6
        assert np.abs(log.u_mps2[k, here] - zhang2024_train().resistance_mps2(V_R)).max() < 1e-6


# ---------------------------------------------------------------------------------------------- engine adapter


def _observation(log, k: int, i: str, graph: CommGraph, vehicle, age_s: float = 0.0) -> Observation:
    def state(j: str) -> tuple[float, float]:
        return float(log.x_m[k, log.col(j)]), float(log.v_mps[k, log.col(j)])

    x_i, v_i = state(i)
    neighbours = []
    for j in graph.neighbours(i):
        x_j, v_j = state(j)
        neighbours.append(
            PredecessorState(
                train_id=j,
                position_m=x_j - v_j * age_s,
                speed_mps=v_j,
                accel_mps2=0.0,
                length_m=50.0,
                stamp_s=k * T - age_s,
                age_s=age_s,
            )
        )
    edges = {j: graph.oriented(i, j).as_tuple() for j in graph.neighbours(i)}
    return Observation(
        t_s=k * T,
        dt_s=T,
        own=OwnState(i, x_i, v_i, 0.0, 50.0),
        vehicle=vehicle,
        route_length_m=3e5,
        extras={"neighbours": tuple(neighbours), "edges": edges, "k": k},
    )


def test_registered_controller_matches_control_step(logs: dict) -> None:
    log = logs["union"]
    assert "distributed_constrained" in controllers.registered()
    vehicle = paper_vehicle(zhang2024_train())
    ctl = controllers.create("distributed_constrained", {"type": "distributed_constrained"}, vehicle)
    s = zhang2024_fig1()
    graphs = {0: s.graph}
    from controllers.distributed import apply_event

    g = s.graph
    for e in s.events:
        g = apply_event(g, e)
    graphs[1000] = g
    for k in (0, 1, 57, 380, 999, 1000, 1001, 1400, 2000):
        graph = graphs[0] if k < 1000 else graphs[1000]
        for i in sorted(graph.nodes):
            cmd = ctl.command(_observation(log, k, i, graph, vehicle))
            assert cmd.accel_mps2 == log.u_mps2[k, log.col(i)]  # bit for bit: same information, same arithmetic
            assert cmd.info["u_paper_mps2"] == cmd.accel_mps2 and cmd.info["k"] == k and not cmd.fallback
            # a stale message extrapolated by its age at constant speed gives the same prediction up to rounding
            stale = ctl.command(_observation(log, k, i, graph, vehicle, age_s=T))
            assert stale.accel_mps2 == pytest.approx(cmd.accel_mps2, abs=1e-8)


def test_closed_loop_through_railsim_plant_matches_reference(logs: dict) -> None:
    """The adapter's command through railsim.physics.dynamics.step (forward Euler) is the paper's closed loop."""
    log = logs["union"]
    s = zhang2024_fig1(horizon_k=1100)
    vehicle = paper_vehicle(zhang2024_train())
    ctls = {}
    graph = s.graph
    x, v = dict(s.initial_positions_m), dict(s.initial_speeds_mps)
    from controllers.distributed import apply_event

    for k in range(s.horizon_k + 1):
        for e in [e for e in s.events if e.k == k]:
            graph = apply_event(graph, e)
            if isinstance(e, TrainJoin):
                x[e.train_id], v[e.train_id] = e.x_m, e.v_mps
        for i in graph.nodes:
            assert x[i] == log.x_m[k, log.col(i)] and v[i] == log.v_mps[k, log.col(i)], (k, i)
        cmds = {}
        for i in graph.nodes:
            ctl = ctls.setdefault(i, controllers.create("distributed_constrained", {}, vehicle))
            own = OwnState(i, x[i], v[i], 0.0, 50.0)
            nb = tuple(PredecessorState(j, x[j], v[j], 0.0, 50.0, k * T, 0.0) for j in graph.neighbours(i))
            obs = Observation(
                t_s=k * T,
                dt_s=T,
                own=own,
                vehicle=vehicle,
                route_length_m=3e5,
                extras={"neighbours": nb, "edges": {j: graph.oriented(i, j) for j in graph.neighbours(i)}},
            )
            cmds[i] = ctl.command(obs).accel_mps2
        for i in graph.nodes:
            r = dynamics.step(vehicle, dynamics.PlantState(v[i]), cmds[i], T, step_method="forward")
            assert not r.saturations
            x[i], v[i] = x[i] + r.advance_m, r.v_next_mps


def test_engine_adapter_contract_errors() -> None:
    vehicle = paper_vehicle(zhang2024_train())
    with pytest.raises(ValueError, match=r"^sample_time_s: expected T > T_min"):
        controllers.create("distributed_constrained", {"sample_time_s": 0.1}, vehicle)
    with pytest.raises(ValueError, match=r"^v_ref_mps: expected"):
        controllers.create("distributed_constrained", {"v_ref_mps": 90.0}, vehicle)
    with pytest.raises(ValueError, match=r"^gain: expected one of"):
        controllers.create("distributed_constrained", {"gain": 1.0}, vehicle)
    ctl = controllers.create("distributed_constrained", {}, vehicle)
    own = OwnState("1", 0.0, 80.0, 0.0, 50.0)
    obs = Observation(
        t_s=0.0,
        dt_s=T,
        own=own,
        vehicle=vehicle,
        route_length_m=1e5,
        extras={"neighbours": (), "edges": {"2": (5000.0, 100.0, 10000.0)}},
    )
    with pytest.raises(KeyError, match="neighbour '2'"):
        ctl.command(obs)
    from railsim.errors import SimulationError

    with pytest.raises(SimulationError, match="0.5 s"):
        ctl.command(replace(obs, dt_s=0.5, extras={"edges": {}}))
    # isolated train (A9): runs to v_r in one step
    cmd = ctl.command(replace(obs, own=replace(own, speed_mps=83.0), extras={"edges": {}, "neighbours": ()}))
    assert cmd.info["s_m"] == 0.0
    assert 83.0 + T * (cmd.accel_mps2 - zhang2024_train().resistance_mps2(83.0)) == pytest.approx(V_R, abs=1e-12)


def test_empty_window_raises_or_falls_back() -> None:
    p = zhang2024_train()
    ctl = TrainController("1", p, T, V_R)
    edge = EdgeData(5000.0, 100.0, 10000.0)
    msg = [NeighbourMessage("2", 50.0, edge)]  # x_12(k+1) = 50 < γ̲: α̲ = 25 m > β̄ = 5 m
    with pytest.raises(ConstraintWindowEmpty, match="δ̲ = 25 m > δ̄ = 5 m"):
        ctl.control(80.0, msg)
    out = TrainController("1", p, T, V_R, on_empty="fallback").control(80.0, msg)
    assert not out.feasible and out.s_m == 5.0  # the hard velocity limit wins, as close to α as it allows


def test_figures_are_written(logs: dict, tmp_path) -> None:
    from railsim.report.plots.paper002 import write_figures

    paths = write_figures(logs["union"], tmp_path / "figs")
    assert [p.name for p in paths] == [
        "fig3_positions.png",
        "fig4_position_differences.png",
        "fig5_speeds.png",
        "fig6_inputs.png",
    ]
    for p in paths:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 10_000
