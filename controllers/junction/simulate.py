"""A pure-numpy plant for junction plans, the comparison metrics, and the Table 3 experiment (spec 004 §5, §8).

:func:`simulate_plan` integrates each train's distance-segment acceleration profile in time with the spec's
§2.9 step (``s ← s + vΔt + ½aΔt²`` with the old ``v``, then ``v ← v + aΔt``, Δt = 0.1 s), optionally through a
first-order actuator lag τ (spec §6 #12). It shares no code with the exact distance-domain rollout the optimiser
uses, so the two check each other. Behind F a train holds its speed (coupled running).

:func:`measure` reads any trajectory (plan or naive baseline) the same way: switch passage times/speeds by
interpolation, the passing order at the merge switch, ``T_c`` = the leader at F, gaps and speed differences at
``T_c``, ``coupled_at_F`` (Eqs. 2–3 for every consecutive pair), ``f_c`` (via the game's Eq. 31 shares),
operation time = the last train at F (spec §6 #24), the minimum separation between trains on shared track,
the minimum speed and the worst switch-speed excess and headway shortfall.

:func:`compare_table3` runs Table 3 scenarios × methods × seeds and returns mean ± std per cell (``qp_order`` and the
naive strategies are deterministic: one run, std 0).
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from controllers.junction.baselines import run_naive
from controllers.junction.game import closed_form_shapley, players_from_outcome
from controllers.junction.model import JunctionParams, Problem, safety_margin_m
from controllers.junction.planner import (
    TrainState,
    YJunctionLayout,
    build_problem,
    solve,
)
from controllers.junction.pso import PSOParams, improved_pso_params, plain_pso_params

# Table 3 (spec §5.1): S1, S2, S3, S4, S5 [m], v1, v2, v3 [m/s]
TABLE3: dict[int, tuple[float, ...]] = {
    1: (400.0, 200.0, 160.0, 200.0, 200.0, 20.0, 15.0, 15.0),
    2: (600.0, 400.0, 200.0, 200.0, 200.0, 10.0, 20.0, 10.0),
    3: (400.0, 200.0, 200.0, 200.0, 200.0, 5.0, 5.0, 10.0),
}


def table3_scenario(
    number: int, sw1_branch_leg: str = "reverse", sw2_branch_leg: str = "reverse"
) -> tuple[list[TrainState], YJunctionLayout]:
    """Trains 1–3 on entry1–3 of ``y_junction`` with the Table 3 distances and speeds."""
    S1, S2, S3, S4, S5, v1, v2, v3 = TABLE3[number]
    trains = [
        TrainState("train1", "entry1", S1, v1),
        TrainState("train2", "entry2", S2, v2),
        TrainState("train3", "entry3", S3, v3),
    ]
    return trains, YJunctionLayout(S4, S5, sw1_branch_leg, sw2_branch_leg)  # type: ignore[arg-type]


@dataclass(frozen=True)
class Outcome:
    """Metrics of one run (SI units; ``nan`` only where a quantity does not exist, e.g. no train reached F)."""

    coupled_at_F: bool
    order: tuple[str, ...]
    coupling_time_s: float
    coupled_speed_mps: float  # mean platoon speed at T_c
    cost: float  # f_c at T_c
    operation_time_s: float  # last train at F
    min_separation_m: float  # head-to-head, trains on shared track
    min_speed_mps: float
    max_gap_error_m: float  # max |D − S_m| at T_c
    max_speed_diff_mps: float  # max |Δv| at T_c
    switch_speed_excess_mps: float  # max(v_pass − v_lim, 0) over passages
    headway_shortfall_s: float  # max(t_ls needed − Δt, 0) over switches


def _advance_exact(
    s: float, v: float, dt: float, edges: np.ndarray, prof: np.ndarray, d_F: float
) -> tuple[float, float]:
    """Advance one train by ``dt`` with its distance profile, splitting the step at segment boundaries."""
    remaining = dt
    while remaining > 1e-12:
        if s >= d_F - 1e-9:
            return s + v * remaining, v  # behind F: hold the speed
        j = min(int(np.searchsorted(edges, s, side="right")) - 1, len(prof) - 1)
        a = float(prof[j])
        end = float(edges[j + 1])
        gap = end - s
        # time to the segment end: smallest positive root of ½aτ² + vτ − gap = 0
        if abs(a) < 1e-12:
            tau = gap / v if v > 0 else np.inf
        else:
            disc = v * v + 2.0 * a * gap
            tau = (-v + np.sqrt(disc)) / a if disc >= 0.0 else np.inf
        if a < 0.0 and v + a * remaining <= 0.0 and (not np.isfinite(tau) or -v / a < tau):
            t_stop = -v / a  # stops inside the segment: stays stopped
            return s + 0.5 * v * t_stop, 0.0
        if tau >= remaining:
            return s + v * remaining + 0.5 * a * remaining**2, v + a * remaining
        s, v = end + 1e-12, v + a * tau
        remaining -= tau
    return s, v


def simulate_plan(
    problem: Problem,
    x: np.ndarray,
    dt_s: float = 0.1,
    lag_s: float = 0.0,
    integrator: str = "exact",
    horizon_s: float = 600.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integrate the plan ``x`` (one particle); returns ``(time_s, position_m (T, n), speed_mps (T, n))``.

    ``integrator="exact"`` splits each Δt step at segment boundaries, so the acceleration really is piecewise
    constant in distance (the plan's model); ``"euler"`` applies the acceleration of the segment the train is
    in at the start of each step for the whole step (what a 0.1 s controller does), optionally through the
    first-order lag ``lag_s`` — the plan's sensitivity to both is the reason for re-planning.
    """
    if integrator not in ("exact", "euler"):
        raise ValueError(f"integrator: expected exact or euler, got {integrator!r}")
    n = problem.n_trains
    profiles = problem.split(np.asarray(x, dtype=float))
    s = np.zeros(n)
    v = np.array([tr.initial_speed_mps for tr in problem.trains], dtype=float)
    a = np.zeros(n)
    d_F = np.array([tr.distance_to_F_m for tr in problem.trains])
    edges = [problem.breakpoints_m[k, : problem.n_segments[k] + 1] for k in range(n)]
    ts, ss, vs = [0.0], [s.copy()], [v.copy()]
    t = 0.0
    while t < horizon_s - 1e-9 and not np.all(s > d_F):
        if integrator == "exact" and lag_s <= 0.0:
            for k in range(n):
                s[k], v[k] = _advance_exact(s[k], v[k], dt_s, edges[k], profiles[k], d_F[k])
        else:
            cmd = np.array(
                [
                    profiles[k][min(int(np.searchsorted(edges[k], s[k], side="right")) - 1, len(profiles[k]) - 1)]
                    if s[k] < d_F[k]
                    else 0.0
                    for k in range(n)
                ]
            )
            a = cmd if lag_s <= 0.0 else a + (cmd - a) * min(dt_s / lag_s, 1.0)
            s = s + np.maximum(v * dt_s + 0.5 * a * dt_s**2, 0.0)
            v = np.maximum(v + a * dt_s, 0.0)
        t += dt_s
        ts.append(t)
        ss.append(s.copy())
        vs.append(v.copy())
    return np.array(ts), np.array(ss), np.array(vs)


def _crossing(t: np.ndarray, s: np.ndarray, v: np.ndarray, x: float) -> tuple[float, float]:
    """Time and speed when position series ``s`` first reaches ``x`` (linear interpolation); nan if never."""
    idx = np.flatnonzero(s >= x)
    if idx.size == 0:
        return float("nan"), float("nan")
    i = int(idx[0])
    if i == 0:
        return float(t[0]), float(v[0])
    f = (x - s[i - 1]) / max(s[i] - s[i - 1], 1e-12)
    return float(t[i - 1] + f * (t[i] - t[i - 1])), float(v[i - 1] + f * (v[i] - v[i - 1]))


def measure(problem: Problem, t: np.ndarray, s: np.ndarray, v: np.ndarray) -> Outcome:
    """Metrics of a trajectory (see module docstring)."""
    p: JunctionParams = problem.params
    n = problem.n_trains
    ids = [tr.train_id for tr in problem.trains]
    nan = float("nan")
    passes: dict[str, list[tuple[float, float, str, float]]] = {}
    merge_t = np.full(n, np.inf)
    excess = 0.0
    for k, tr in enumerate(problem.trains):
        for sw in tr.switches:
            tp, vp = _crossing(t, s[:, k], v[:, k], sw.distance_m)
            if np.isnan(tp):
                continue
            passes.setdefault(sw.switch_id, []).append((tp, vp, sw.leg, k))
            excess = max(excess, vp - p.limit_speed_mps(sw.leg))
            if sw.switch_id == problem.merge_switch_id:
                merge_t[k] = tp
    shortfall = 0.0
    for lst in passes.values():
        lst.sort()
        for (t0, _, l0, _), (t1, _, l1, _) in zip(lst, lst[1:]):
            need = p.throw_time_s if (l0 != l1 or p.headway_all_consecutive) else 0.0
            shortfall = max(shortfall, need - (t1 - t0))
    order = [int(k) for k in np.argsort(merge_t, kind="stable")]
    st = s - problem.merge_distance_m[None, :]
    min_sep = np.inf
    for i, j, ii, _ in problem.shared_pairs:
        first = problem.breakpoints_m[i, ii[0]] - problem.merge_distance_m[i]
        both = (st[:, i] >= first) & (st[:, j] >= first)
        if both.any():
            min_sep = min(min_sep, float(np.min(np.abs(st[both, i] - st[both, j]))))
    leader = order[0]
    d_F = [tr.distance_to_F_m for tr in problem.trains]
    t_c, _ = _crossing(t, s[:, leader], v[:, leader], d_F[leader])
    op_times = [_crossing(t, s[:, k], v[:, k], d_F[k])[0] for k in range(n)]
    op_time = max(op_times) if not any(np.isnan(op_times)) else nan
    if np.isnan(t_c) or not np.all(np.isfinite(merge_t)):
        return Outcome(
            False,
            tuple(ids[k] for k in order),
            t_c,
            nan,
            nan,
            op_time,
            min_sep,
            float(v.min()),
            nan,
            nan,
            max(excess, 0.0),
            max(shortfall, 0.0),
        )
    st_c = np.array([np.interp(t_c, t, st[:, k]) for k in range(n)])
    v_c = np.array([np.interp(t_c, t, v[:, k]) for k in range(n)])
    gaps = np.array([st_c[order[i - 1]] - st_c[order[i]] for i in range(1, n)])
    dvs = np.array([v_c[order[i - 1]] - v_c[order[i]] for i in range(1, n)])
    margins = np.array([float(safety_margin_m(v_c[order[i - 1]], v_c[order[i]], p)) for i in range(1, n)])
    gap_err = np.abs(gaps - margins)
    coupled = bool(np.all(gap_err <= p.gap_tolerance_m) and np.all(np.abs(dvs) <= p.speed_tolerance_mps))
    players = players_from_outcome(ids, order, merge_t, t_c, v_c, st_c)
    cost = float(sum(closed_form_shapley(players, p).values()))
    return Outcome(
        coupled,
        tuple(ids[k] for k in order),
        t_c,
        float(v_c.mean()),
        cost,
        op_time,
        min_sep,
        float(v.min()),
        float(gap_err.max()),
        float(np.abs(dvs).max()),
        max(excess, 0.0),
        max(shortfall, 0.0),
    )


METHODS = ("improved_pso", "plain_pso", "qp_order", "naive1", "naive2")
DETERMINISTIC = ("qp_order", "naive1", "naive2")


def run_method(
    problem: Problem, method: str, seed: int = 0, pso: PSOParams | None = None, dt_s: float = 0.1
) -> tuple[Outcome, dict[str, float]]:
    """One run of ``method`` on a compiled problem: the measured outcome plus planner diagnostics."""
    if method in ("naive1", "naive2"):
        t0 = time.perf_counter()
        traj = run_naive(problem, method, dt_s)  # type: ignore[arg-type]
        return measure(problem, *traj), {"plan_feasible": float("nan"), "wall_time_s": time.perf_counter() - t0}
    if pso is None and method != "qp_order":
        pso = improved_pso_params() if method == "improved_pso" else plain_pso_params()
    res = solve(problem, method, pso, np.random.default_rng(seed))  # type: ignore[arg-type]
    traj = simulate_plan(problem, res.x, dt_s)
    return measure(problem, *traj), {
        "plan_feasible": float(res.feasible),
        "wall_time_s": res.wall_time_s,
        "iterations": float(res.iterations),
    }


def compare_table3(
    seeds: Iterable[int] = range(30),
    scenarios: Sequence[int] = (1, 2, 3),
    methods: Sequence[str] = METHODS,
    params: JunctionParams | None = None,
    pso_overrides: dict | None = None,
) -> list[dict]:
    """Table 3 scenarios × methods × seeds → one row per (scenario, method) with mean/std of every metric.

    Row keys: ``scenario``, ``method``, ``runs``, ``coupled_rate``, ``plan_feasible_rate`` and, for each of
    ``coupling_time_s``, ``coupled_speed_mps``, ``cost``, ``operation_time_s``, ``min_separation_m``,
    ``wall_time_s``: ``<name>_mean`` and ``<name>_std`` (over runs where the value exists).
    """
    seeds = list(seeds)
    rows = []
    for sc in scenarios:
        trains, layout = table3_scenario(sc)
        problem = build_problem(trains, (), layout, params)
        for m in methods:
            pso = None
            if m in ("improved_pso", "plain_pso") and pso_overrides:
                base = improved_pso_params() if m == "improved_pso" else plain_pso_params()
                pso = PSOParams(**{**asdict(base), **pso_overrides})
            run_seeds = seeds[:1] if m in DETERMINISTIC else seeds
            outs, diags = [], []
            for sd in run_seeds:
                o, d = run_method(problem, m, sd, pso)
                outs.append(o)
                diags.append(d)
            row: dict = {
                "scenario": sc,
                "method": m,
                "runs": len(outs),
                "coupled_rate": float(np.mean([o.coupled_at_F for o in outs])),
                "plan_feasible_rate": float(np.nanmean([d["plan_feasible"] for d in diags]))
                if m not in ("naive1", "naive2")
                else float("nan"),
            }
            for name in ("coupling_time_s", "coupled_speed_mps", "cost", "operation_time_s", "min_separation_m"):
                vals = np.array([getattr(o, name) for o in outs], dtype=float)
                vals = vals[np.isfinite(vals)]
                row[f"{name}_mean"] = float(vals.mean()) if vals.size else float("nan")
                row[f"{name}_std"] = float(vals.std()) if vals.size else float("nan")
            w = np.array([d["wall_time_s"] for d in diags])
            row["wall_time_s_mean"], row["wall_time_s_std"] = float(w.mean()), float(w.std())
            rows.append(row)
    return rows
