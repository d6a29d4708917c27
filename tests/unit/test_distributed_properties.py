"""Property tests of Paper C's distributed constrained law (spec 002 §7.2 items 1–9, 12) on random instances.

Instances are built *constructively* so every one satisfies Assumptions 2.1–2.4 and condition (13) and hypothesis
rejects none:

* a random spanning tree plus random extra edges (connected, with cycles);
* node offsets ``d_i`` (so ``d_ij = d_i − d_j`` is consistent around every cycle);
* per train: ``ρ̲ = v_r − m_lo``, ``ρ̄ = v_r + m_hi``, Davis ``b`` of either sign (the vertex of ``f`` may lie in
  ``[ρ̲, ρ̄]``), and input bounds ``μ̲ = f̲ − (ρ̄ − v_r)/T − e_lo``, ``μ̄ = f̄ + (v_r − ρ̲)/T + e_hi`` — which makes
  Assumption 2.4 hold with ``η̲ = −e_lo·T²``, ``η̄ = e_hi·T²`` (so the input window is sometimes the binding one);
* the initial state is drawn first (spacing errors up to ±500 m, speeds anywhere in ``[ρ̲, ρ̄]``) and each edge's
  band is then built around ``d_ij``, ``x_ij(0)`` and ``x_ij(0) + T·v_ij(0)`` with a slack that is often tiny, so
  (13) holds by construction and many pairs start right at a bound.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, replace

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from controllers.distributed import (
    CommGraph,
    Edge,
    EdgeData,
    PreconditionError,
    Scenario,
    TrainController,
    TrainJoin,
    TrainParams,
    local_windows,
    simulate,
)
from controllers.distributed.control import WINDOW_ROUNDING_M
from controllers.distributed.reference import network_controls

TOL = 1e-9


@dataclass(frozen=True)
class Instance:
    scenario: Scenario
    offsets_m: dict[str, float]  # d_i


def _instance(
    seed: int,
    n: int,
    sample_time_s: float,
    extra_edges: int,
    horizon_k: int = 150,
    min_input_slack: float = 0.01,
    spreads: tuple[float, ...] = (5.0, 50.0, 500.0),
) -> Instance:
    rng = random.Random(seed)
    t = sample_time_s
    ids = [f"t{k}" for k in range(n)]
    rng.shuffle(ids)  # labels carry no order
    v_r = rng.uniform(10.0, 100.0)
    offsets = {i: rng.uniform(-8000.0, 8000.0) for i in ids}
    params: dict[str, TrainParams] = {}
    for i in ids:
        m_lo, m_hi = rng.uniform(0.5, min(10.0, v_r - 1.0)), rng.uniform(0.5, 10.0)
        a, b, c = rng.uniform(0.0, 0.05), rng.uniform(-4e-3, 2e-3), rng.uniform(0.0, 1e-4)
        if rng.random() < 0.3:  # put the vertex of f inside [ρ̲, ρ̄]
            c = rng.uniform(1e-5, 1e-4)
            b = -2.0 * c * rng.uniform(v_r - m_lo, v_r + m_hi)
        p = TrainParams(a, b, c, v_r - m_lo, v_r + m_hi, 0.0, 0.0)
        f_lo, f_hi = p.resistance_bounds_mps2()
        e_lo = rng.choice([rng.uniform(min_input_slack, 0.5), rng.uniform(0.5, 10.0)])
        e_hi = rng.uniform(min_input_slack, 10.0)
        params[i] = replace(p, input_min_mps2=f_lo - m_hi / t - e_lo, input_max_mps2=f_hi + m_lo / t + e_hi)
    # Initial state first: spacing errors of up to a few hundred metres, speeds anywhere in their bounds.
    spread = rng.choice(spreads)
    x0 = {i: offsets[i] + rng.uniform(-spread, spread) for i in ids}
    v0 = {i: rng.uniform(params[i].speed_min_mps, params[i].speed_max_mps) for i in ids}
    pairs = [(ids[k], ids[rng.randrange(k)]) for k in range(1, n)]  # spanning tree
    others = [(ids[a], ids[b]) for a in range(n) for b in range(a) if (ids[a], ids[b]) not in pairs]
    rng.shuffle(others)
    pairs += others[:extra_edges]
    edges = []
    for i, j in pairs:
        d = offsets[i] - offsets[j]
        now, nxt = x0[i] - x0[j], (x0[i] + t * v0[i]) - (x0[j] + t * v0[j])
        # Bands that contain d, x_ij(0) and x_ij(0) + T·v_ij(0) (condition (13) and O1 at k = 0) with a slack
        # that is often tiny: many pairs start right at their bound, so the pair window α has to act.
        slack = (lambda: rng.uniform(0.01, 2.0)) if rng.random() < 0.5 else (lambda: rng.uniform(2.0, 1000.0))
        edges.append(Edge(i, j, EdgeData(d, min(d, now, nxt) - slack(), max(d, now, nxt) + slack())))
    graph = CommGraph.build(ids, edges)
    scen = Scenario("random", t, v_r, horizon_k, params, graph, x0, v0)
    return Instance(scen, offsets)


instances = st.builds(
    _instance,
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(2, 7),
    sample_time_s=st.sampled_from([0.5, 1.0, 2.0]),
    extra_edges=st.integers(0, 6),
)


def _scale(inst: Instance) -> float:
    return (
        1.0
        + max(abs(x) for x in inst.scenario.initial_positions_m.values())
        + inst.scenario.v_ref_mps * inst.scenario.sample_time_s * inst.scenario.horizon_k
    )


def _ybar(log, inst: Instance) -> np.ndarray:
    """ȳ_i(k) = x_i(k) − d_i − v_r·k·T (spec 002 eq. (5))."""
    s = inst.scenario
    d = np.array([inst.offsets_m[i] for i in log.train_ids])
    return log.x_m - d[None, :] - s.v_ref_mps * s.sample_time_s * log.k[:, None]


# ---------------------------------------------------------------------------------------------------- items 1–5


@settings(max_examples=150)
@given(instances)
def test_constraints_window_deadbeat_and_lyapunov(inst: Instance) -> None:
    s = inst.scenario
    log = simulate(s)
    t, v_r, scale = s.sample_time_s, s.v_ref_mps, _scale(inst)
    # 1–2. O1, O2 (speed and input) at every sample.
    assert log.violations(tol=TOL * scale) == []
    # 2 (strong form): μ̲ − f̲ ≤ ū ≤ μ̄ − f̄.
    for n, i in enumerate(log.train_ids):
        p = s.trains[i]
        f_lo, f_hi = p.resistance_bounds_mps2()
        assert np.all(log.ubar_mps2[:, n] >= p.input_min_mps2 - f_lo - 1e-9 * (1 + abs(p.input_min_mps2)))
        assert np.all(log.ubar_mps2[:, n] <= p.input_max_mps2 - f_hi + 1e-9 * (1 + abs(p.input_max_mps2)))
    # 3. window never empty, contains 0, s inside it.
    assert log.feasible.all()
    assert np.all(log.delta_lo_m <= TOL * scale) and np.all(log.delta_hi_m >= -TOL * scale)  # ≤ 0 ≤, up to rounding
    # (a window empty by rounding only is the point δ̄ = s, up to WINDOW_ROUNDING_M below δ̲: seed 201951533)
    assert np.all(log.s_m >= log.delta_lo_m - WINDOW_ROUNDING_M) and np.all(log.s_m <= log.delta_hi_m)
    # 4. dead-beat identity: v(k+1) = v_r + s(k)/T and ȳ(k+2) − ȳ(k+1) = s(k).
    np.testing.assert_allclose(log.v_mps[1:], v_r + log.s_m[:-1] / t, rtol=0, atol=1e-9 * (1 + v_r))
    yb = _ybar(log, inst)
    np.testing.assert_allclose(yb[2:] - yb[1:-1], log.s_m[:-2], rtol=0, atol=TOL * scale)
    # 5. max–min Lyapunov function on the fixed graph, k ≥ 1.
    lo, hi = yb.min(axis=1)[1:], yb.max(axis=1)[1:]
    big = TOL * scale
    assert np.all(np.diff(lo) >= -big) and np.all(np.diff(hi) <= big)
    v_fun = hi - lo
    n = len(log.train_ids)
    for k in range(len(v_fun) - n):
        if v_fun[k] > 1e-6 * scale:
            assert v_fun[k + n] < v_fun[k], f"V did not decrease within N = {n} steps from k = {k + 1}"


# Convergence runs need a horizon of V(0)/(smallest admissible step): keep the input slack and spread moderate.
converging_instances = st.builds(
    _instance,
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(2, 7),
    sample_time_s=st.sampled_from([0.5, 1.0, 2.0]),
    extra_edges=st.integers(0, 6),
    min_input_slack=st.just(1.0),
    spreads=st.just((5.0, 50.0)),
)


@settings(max_examples=60)
@given(converging_instances)
def test_errors_shrink_to_zero(inst: Instance) -> None:
    """6. Convergence, with the horizon scaled by V(0) over the slowest admissible displacement per step."""
    s = inst.scenario
    t, v_r = s.sample_time_s, s.v_ref_mps
    step_m = min(min(-w.hard_lo_m, w.hard_hi_m) for w in (local_windows(p, t, v_r) for p in s.trains.values()))
    yb0 = [s.initial_positions_m[i] - inst.offsets_m[i] for i in s.graph.nodes]
    v0 = max(yb0) - min(yb0)
    horizon = int(3 * v0 / step_m) + 60 * len(s.graph.nodes) + 200
    log = simulate(replace(s, horizon_k=horizon))
    spacing_err = np.abs(log.x_rel_m - log.edge_d_m)
    assert spacing_err[-1].max() <= 1e-6 * (1 + np.abs(log.edge_d_m[-1]).max())
    assert np.abs(log.v_mps[-1] - v_r).max() <= 1e-6
    f_vr = np.array([s.trains[i].resistance_mps2(v_r) for i in log.train_ids])
    assert np.abs(log.u_mps2[-1] - f_vr).max() <= 1e-5 / t
    # and the errors did shrink: the last error is far below the first one
    assert spacing_err[-1].max() <= 1e-3 * max(spacing_err[0].max(), 1e-3)


# ------------------------------------------------------------------------------------------------------ item 7


def _controls(s: Scenario, x: dict, v: dict, graph: CommGraph | None = None, params: dict | None = None) -> dict:
    graph = graph or s.graph
    params = params or s.trains
    # "fallback": a perturbed non-neighbour may have an empty window itself; only u_i is compared
    ctl = {i: TrainController(i, params[i], s.sample_time_s, s.v_ref_mps, on_empty="fallback") for i in graph.nodes}
    return {i: o.u_mps2 for i, o in network_controls(graph, ctl, x, v, s.sample_time_s).items()}


@settings(max_examples=60)
@given(instances, st.integers(0, 2**32 - 1))
def test_locality_translation_and_relabelling(inst: Instance, seed: int) -> None:
    s = inst.scenario
    rng = random.Random(seed)
    x, v = dict(s.initial_positions_m), dict(s.initial_speeds_mps)
    u = _controls(s, x, v)
    # Locality: perturbing a non-neighbour's state and parameters leaves u_i bit-identical.
    for i in s.graph.nodes:
        far = [j for j in s.graph.nodes if j != i and not s.graph.has_edge(i, j)]
        if not far:
            continue
        j = rng.choice(far)
        x2, v2, p2 = dict(x), dict(v), dict(s.trains)
        x2[j] += rng.uniform(-300.0, 300.0)
        v2[j] += rng.uniform(-0.4, 0.4)
        p2[j] = replace(p2[j], input_max_mps2=p2[j].input_max_mps2 + 1.0, resist_a_mps2=p2[j].resist_a_mps2 * 2)
        assert _controls(s, x2, v2, params=p2)[i] == u[i]
    # Translation invariance: a common shift of all positions changes nothing (up to rounding).
    shift = rng.uniform(-1e5, 1e5)
    u_shift = _controls(s, {i: xi + shift for i, xi in x.items()}, v)
    tol = 1e-9 * (1 + abs(shift) + max(abs(xi) for xi in x.values())) / s.sample_time_s**2
    assert all(abs(u_shift[i] - u[i]) <= tol for i in u)
    # Equivariance: relabelling the trains relabels the inputs.
    ids = sorted(s.graph.nodes)
    perm = dict(zip(ids, rng.sample(ids, len(ids))))
    g2 = CommGraph.build(
        [perm[i] for i in ids], [Edge(perm[i], perm[j], data) for i, j, data in s.graph.oriented_edges()]
    )
    u_perm = _controls(
        s,
        {perm[i]: x[i] for i in ids},
        {perm[i]: v[i] for i in ids},
        graph=g2,
        params={perm[i]: s.trains[i] for i in ids},
    )
    assert all(abs(u_perm[perm[i]] - u[i]) <= tol for i in ids)


@settings(max_examples=40)
@given(instances, st.integers(0, 2**32 - 1))
def test_neighbour_order_does_not_matter(inst: Instance, seed: int) -> None:
    s = inst.scenario
    ctl = {i: TrainController(i, s.trains[i], s.sample_time_s, s.v_ref_mps) for i in s.graph.nodes}
    from controllers.distributed import NeighbourMessage

    for i in s.graph.nodes:
        xh = {j: s.initial_positions_m[j] + s.sample_time_s * s.initial_speeds_mps[j] for j in s.graph.nodes}
        msgs = [NeighbourMessage(j, xh[i] - xh[j], s.graph.oriented(i, j)) for j in s.graph.neighbours(i)]
        a = ctl[i].control(s.initial_speeds_mps[i], msgs)
        random.Random(seed).shuffle(msgs)
        b = ctl[i].control(s.initial_speeds_mps[i], msgs)
        assert b.delta_lo_m == a.delta_lo_m and b.delta_hi_m == a.delta_hi_m
        assert abs(b.u_mps2 - a.u_mps2) <= 1e-9 * (1 + _scale(inst)) / s.sample_time_s**2


# ------------------------------------------------------------------------------------------------------ item 8


@settings(max_examples=40)
@given(instances)
def test_edge_antisymmetry_and_orientation_independence(inst: Instance) -> None:
    s = inst.scenario
    g = s.graph
    for i, j, data in g.oriented_edges():
        back = g.oriented(j, i)
        assert back.d_m == -data.d_m and back.gamma_lo_m == -data.gamma_hi_m and back.gamma_hi_m == -data.gamma_lo_m
        assert g.oriented(i, j) == data
    # Stating every edge the other way round describes the same system: identical trajectories.
    flipped = CommGraph.build(g.nodes, [Edge(j, i, data.reversed()) for i, j, data in g.oriented_edges()])
    a = simulate(replace(s, horizon_k=40))
    b = simulate(replace(s, graph=flipped, horizon_k=40))
    assert np.array_equal(a.x_m, b.x_m) and np.array_equal(a.u_mps2, b.u_mps2)


# ---------------------------------------------------------------------------------------------- items 9 and 12


BREAKS = (
    "gamma_order",
    "v_ref_outside",
    "mu_lo_above_f",
    "t_below_t_min",
    "d_cycle",
    "disconnected",
    "cond13",
    "o1_at_0",
    "speed_at_0",
)


@settings(max_examples=120)
@given(instances, st.sampled_from(BREAKS), st.integers(0, 2**32 - 1))
def test_infeasible_instances_are_rejected_before_running(inst: Instance, how: str, seed: int) -> None:
    s = inst.scenario
    rng = random.Random(seed)
    i = rng.choice(sorted(s.graph.nodes))
    ei, ej, data = rng.choice(list(s.graph.oriented_edges()))
    p = s.trains[i]
    g, trains, x0, v0, t, v_r = (
        s.graph,
        dict(s.trains),
        dict(s.initial_positions_m),
        dict(s.initial_speeds_mps),
        s.sample_time_s,
        s.v_ref_mps,
    )
    expect = {
        "gamma_order": "Assumption 2.2",
        "v_ref_outside": "Assumption 2.3",
        "mu_lo_above_f": "Assumption 2.4",
        "t_below_t_min": "Assumption 2.4",
        "d_cycle": "Assumption 2.2",
        "disconnected": "Assumption 2.1",
        "cond13": "condition (13)",
        "o1_at_0": "objective O1",
        "speed_at_0": "condition (13)",
    }[how]

    def rebuilt(new_data: EdgeData | None) -> CommGraph:
        keep = [Edge(a, b, dd) for a, b, dd in g.oriented_edges() if (a, b) != (ei, ej)]
        return CommGraph.build(g.nodes, keep + ([Edge(ei, ej, new_data)] if new_data else []))

    if how == "gamma_order":
        g = rebuilt(EdgeData(data.d_m, data.d_m + 1.0, data.gamma_hi_m))
    elif how == "v_ref_outside":
        trains[i] = replace(p, speed_max_mps=v_r - 0.01, speed_min_mps=v_r - 20.0)
    elif how == "mu_lo_above_f":
        trains[i] = replace(p, input_min_mps2=p.resistance_bounds_mps2()[0] + 0.01)
    elif how == "t_below_t_min":
        from controllers.distributed import min_sample_time_s

        t = min(min_sample_time_s(q, v_r) for q in trains.values()) * rng.uniform(0.2, 0.99)
    elif how == "d_cycle":
        # a second path between the edge's ends with a different d closes an inconsistent cycle
        mid = "extra"
        trains[mid] = p
        g = CommGraph.build(
            g.nodes | {mid},
            [Edge(a, b, dd) for a, b, dd in g.oriented_edges()]
            + [Edge(ei, mid, EdgeData(0.0, -1e4, 1e4)), Edge(mid, ej, EdgeData(data.d_m + 5.0, -1e5, 1e5))],
        )
        x0[mid], v0[mid] = x0[ei], v0[ei]
    elif how == "disconnected":
        g = CommGraph.build(g.nodes | {"lonely"}, [Edge(a, b, dd) for a, b, dd in g.oriented_edges()])
        trains["lonely"], x0["lonely"], v0["lonely"] = p, 0.0, v_r
    elif how == "cond13":
        # keep x_ij(0) inside, push x_ij(0) + T·v_ij(0) above γ̄ through the speeds (the speed bounds are widened)
        gap = data.gamma_hi_m - (x0[ei] - x0[ej])
        x0[ei] = x0[ej] + data.gamma_hi_m - 0.25 * gap
        dv = gap / t
        v0[ei] = v0[ej] + dv
        for n in (ei, ej):
            trains[n] = replace(
                trains[n],
                speed_min_mps=min(v0[n], trains[n].speed_min_mps),
                speed_max_mps=max(v0[n] + 1.0, trains[n].speed_max_mps),
            )
        trains = {
            n: replace(q, input_min_mps2=q.input_min_mps2 - 1e4, input_max_mps2=q.input_max_mps2 + 1e4)
            for n, q in trains.items()
        }  # keep Assumption 2.4 with the wider speed bounds
    elif how == "o1_at_0":
        x0[ei] = x0[ej] + data.gamma_lo_m - 1.0
    elif how == "speed_at_0":
        v0[i] = p.speed_max_mps + 0.5
    broken = replace(s, graph=g, trains=trains, initial_positions_m=x0, initial_speeds_mps=v0, sample_time_s=t)
    with pytest.raises(PreconditionError) as err:
        simulate(broken)
    assert any(v.assumption.startswith(expect) for v in err.value.violations), err.value.violations
    assert "\n" not in str(err.value)  # one line for the CLI


@settings(max_examples=30)
@given(instances, st.integers(0, 2**32 - 1), st.booleans())
def test_join_is_revalidated(inst: Instance, seed: int, violate: bool) -> None:
    """12. A train joining with an edge whose condition (13) fails is rejected (strict) or flagged — never accepted."""
    s = inst.scenario
    rng = random.Random(seed)
    k_join = rng.randrange(1, 30)
    anchor = rng.choice(sorted(s.graph.nodes))
    p = s.trains[anchor]
    # edge oriented from the anchor: the newcomer runs 50 m behind it (d = +50 m)
    edge = EdgeData(50.0, 50.0 - rng.uniform(1.0, 300.0), 50.0 + rng.uniform(1.0, 300.0))
    # Where the anchor will be at k_join: run the system without the join first (the law does not depend on it).
    pre = simulate(replace(s, horizon_k=k_join))
    xa, va = pre.x_m[k_join, pre.col(anchor)], pre.v_mps[k_join, pre.col(anchor)]
    x_new = xa - (edge.gamma_hi_m + 1.0 if violate else edge.d_m)  # outside the band, or exactly on d
    join = TrainJoin(k_join, "new", x_new, va, p, (Edge("new", anchor, edge.reversed()),))
    scen = replace(s, horizon_k=k_join + 20, events=(join,))
    if violate:
        with pytest.raises(PreconditionError) as err:
            simulate(scen)
        assert err.value.k == k_join and any(v.field.startswith("edges[") for v in err.value.violations)
        flagged = simulate(scen, strict=False, on_empty="fallback")  # a flagged run may meet empty windows
        assert flagged.flagged and any(e.kind == "precondition_violated" for e in flagged.events)
    else:
        log = simulate(scen)
        assert not log.flagged and log.present[k_join, log.col("new")] and not log.present[k_join - 1, log.col("new")]
        assert log.violations(tol=TOL * _scale(inst)) == []
