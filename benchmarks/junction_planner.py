"""Junction planner benchmark (Paper E, spec 004): online (re-)plan wall time and the Table 3 comparison.

Part 1 — planner timing, 3 trains (:func:`replan_timing`): for each Table 3 scenario and ``--replan-seeds``
seeds (one for the deterministic methods), plan at t = 0, execute the plan in the numpy plant and re-plan every
``--period`` seconds (warm start, order frozen past the point of no return) until the first train reaches sw2;
from every state while the order is open also a cold first plan. Every first plan and re-plan is timed, wall
and CPU (``time.process_time``: the machine is shared, and its load inflates wall time far more); median, p95
and max of each, per method — improved PSO, plain PSO (the online budget: 200 iterations, 0.09 s wall-time cap),
``qp_order`` (a budget in QP solves: at most ``first_orders·first_iterations + rescue_iterations`` per first
plan, ``replan_iterations`` per re-plan), naive 1/2 (the priority rule) — and the CPU-time ratios to improved
PSO measured in the same run. The target is ≤ 100 ms per (re-)plan. Both under the paper model and under the
corrected model SUMO flies (:func:`controllers.junction.model.sumo_corrected_params`: t_ls 21.6 s, RBD guard,
20 m trains; ``qp_order`` with the engine's turnout zones and interlocking). The load average at start and
end is part of the output.

Part 2 — Table 3 scenarios 1–3 × {improved PSO, plain PSO, qp_order, naive 1, naive 2} × ``--seeds`` seeds
(deterministic methods run once), default PSO budget (300 iterations), every plan executed in the plant at
Δt = 0.1 s and measured there; and improved PSO vs qp_order under the corrected model.

Prints one JSON object.

    .venv/bin/python benchmarks/junction_planner.py [--seeds 30] [--replan-seeds 5] [--period 2] [--timing-only]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from controllers.junction.baselines import priority_order, run_naive  # noqa: E402
from controllers.junction.model import sumo_corrected_params  # noqa: E402
from controllers.junction.planner import (  # noqa: E402
    TrainState,
    build_problem,
    past_point_of_no_return,
    plan,
    replan,
)
from controllers.junction.pso import improved_pso_params, plain_pso_params  # noqa: E402
from controllers.junction.qp import InterlockingModel, QpOrderParams  # noqa: E402
from controllers.junction.simulate import compare_table3, simulate_plan, table3_scenario  # noqa: E402

ONLINE = improved_pso_params(max_iterations=200, wall_time_s=0.09)
ONLINE_PLAIN = plain_pso_params(max_iterations=200, wall_time_s=0.09)
NAIVE = ("naive1", "naive2")
TIMED_METHODS = ("improved_pso", "plain_pso", "qp_order", *NAIVE)
# qp_order's settings as the engine's coordinator derives them for the Table 3 scenarios (turnouts 10 m, trains
# 20 m, clearance 10 m, protection 20 m + the ATO's 5 m authority margin, ATO planning braking 0.96 m/s²):
# railsim/engine/extensions/junction_coordinator (coordinator.py and readings.interlocking_model)
ENGINE_QP = QpOrderParams(
    zone_m=30.0,
    approach_decel_mps2=0.48,
    approach_hold_m=20.0,
    line_speed_margin_mps=3.0,
    interlocking=InterlockingModel(release_after_m=40.0, throw_s=10.0, grant_before_m=17.0, brake_decel_mps2=0.96),
)


def _state_at(problem, trains, s_row, v_row):
    """Train states at positions ``s_row`` / speeds ``v_row`` along their paths (None once any train is past sw2)."""
    out = []
    for k, (tr, st) in enumerate(zip(problem.trains, trains)):
        s, v = float(s_row[k]), min(float(v_row[k]), problem.params.line_speed_mps)  # no float overshoot
        d_sw = [sw.distance_m for sw in tr.switches]
        if s >= d_sw[-1]:
            return None
        if len(d_sw) == 2 and s >= d_sw[0]:
            out.append(TrainState(st.train_id, "trunk", d_sw[1] - s, max(v, 0.1)))
        else:
            out.append(TrainState(st.train_id, st.track, d_sw[0] - s, max(v, 0.1)))
    return out


def _timed(fn, *args):
    """``fn(*args)`` with its wall and CPU time [ms] (CPU: ``time.process_time`` of this process, which a loaded,
    shared machine inflates far less than wall time)."""
    t0, c0 = time.perf_counter(), time.process_time()
    out = fn(*args)
    return out, (time.perf_counter() - t0) * 1000.0, (time.process_time() - c0) * 1000.0


def _stats(wall_ms, cpu_ms, feasible, work):
    if not wall_ms:
        return {"plans": 0}
    w, c = np.array(wall_ms), np.array(cpu_ms)
    out = {"plans": int(w.size)}
    for name, arr in (("wall", w), ("cpu", c)):
        out[f"{name}_median_ms"] = round(float(np.median(arr)), 2)
        out[f"{name}_p95_ms"] = round(float(np.percentile(arr, 95)), 2)
        out[f"{name}_max_ms"] = round(float(arr.max()), 2)
    if any(f is not None for f in feasible):
        out["feasible_rate"] = float(np.mean([bool(f) for f in feasible]))
    if any(k is not None for k in work):
        out["max_work"] = int(max(k for k in work if k is not None))  # QP solves (qp_order), iterations (PSO)
    return out


def replan_timing(seeds: int, period_s: float, method: str = "improved_pso", params=None, qp=None) -> dict:
    """First plans and re-plans of ``method`` along its own executed trajectory; wall and CPU time of each.

    Per Table 3 scenario and seed (one run for the deterministic methods): a first plan at t = 0; the plan (the
    naive rule's run) is executed in the numpy plant and, every ``period_s`` until the first train reaches sw2,
    the method re-plans from the state reached (warm start; the order frozen past the point of no return). From
    every such state while the order is still open it also makes a **cold first plan** (not used further), so the
    first-plan figures rest on more than three problems: the online coordinator makes a first plan from whatever
    state the trains are in when they are all on the line. The naive rules have no plan to warm-start: their
    "plan" is the priority rule evaluated on the compiled problem (what the engine does, once, at the first
    decision), their "re-plan" the same rule from a later state."""
    first_w, first_c, first_ok, first_k = [], [], [], []
    re_w, re_c, re_ok, re_k = [], [], [], []
    pso = ONLINE if method == "improved_pso" else ONLINE_PLAIN
    naive = method in NAIVE
    deterministic = naive or method == "qp_order"

    def decide(trains, layout, rng, previous=None):
        if naive:
            return priority_order(build_problem(trains, (), layout, params), method)
        if previous is None:
            return plan(trains, (), layout, params, method, pso=pso, rng=rng, qp=qp)
        return replan(previous, trains, (), layout, params, method, pso=pso, rng=rng, qp=qp)

    def record(out, w, c, lists):
        lists[0].append(w)
        lists[1].append(c)
        lists[2].append(None if naive else out.feasible)
        lists[3].append(None if naive else out.iterations)

    firsts, replans = (first_w, first_c, first_ok, first_k), (re_w, re_c, re_ok, re_k)
    for sc in (1, 2, 3):
        trains0, layout = table3_scenario(sc)
        problem0 = build_problem(trains0, (), layout, params)
        for seed in range(1 if deterministic else seeds):
            rng = np.random.default_rng(seed)
            current, w, c = _timed(decide, trains0, layout, rng)
            record(current, w, c, firsts)
            naive_run = run_naive(problem0, method, dt_s=0.1) if naive else None
            trains, t_s = trains0, 0.0
            while True:
                t_s += period_s
                if naive_run is not None:
                    i = min(int(np.searchsorted(naive_run[0], t_s - 1e-9)), naive_run[0].size - 1)
                    nxt = _state_at(problem0, trains0, naive_run[1][i], naive_run[2][i])
                else:
                    problem = build_problem(trains, (), layout, params)
                    x = np.concatenate(
                        [np.array([a for _, _, a in current.train(t.train_id).segments]) for t in trains]
                    )
                    _, ss, vs = simulate_plan(problem, x, dt_s=0.1, horizon_s=period_s)
                    nxt = _state_at(problem, trains, ss[-1], vs[-1])
                if nxt is None:
                    break
                trains = nxt
                open_order = not past_point_of_no_return(trains, params)
                new, w, c = _timed(decide, trains, layout, rng, None if naive else current)
                record(new, w, c, replans)
                if not naive:
                    current = new
                if open_order:  # a cold first plan from the same state (not used further)
                    cold, w, c = _timed(decide, trains, layout, rng)
                    record(cold, w, c, firsts)
    out = {"first_plan": _stats(*firsts), "replan": _stats(*replans), "target_ms": 100.0}
    if method == "qp_order":
        q = qp or QpOrderParams()
        out["budget"] = {
            "first_plan_qps_max": q.first_orders * q.first_iterations + q.rescue_iterations,
            "replan_qps_max": q.replan_iterations,
        }
    elif not naive:
        out["budget"] = {"max_iterations": pso.max_iterations, "wall_time_s": pso.wall_time_s, "swarm": pso.swarm_size}
    return out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--replan-seeds", type=int, default=5)
    ap.add_argument("--period", type=float, default=2.0)
    ap.add_argument("--timing-only", action="store_true", help="part 1 only (re-plan wall times)")
    ap.add_argument("--methods", nargs="+", default=list(TIMED_METHODS), choices=TIMED_METHODS)
    args = ap.parse_args()
    t0 = time.perf_counter()
    load_start = [round(x, 2) for x in os.getloadavg()]
    models = {"paper": None, "corrected": sumo_corrected_params(switch_speed_margin_mps=0.3)}
    timing: dict = {}
    for name, params in models.items():
        timing[name] = {
            m: replan_timing(args.replan_seeds, args.period, m, params, ENGINE_QP if name == "corrected" else None)
            for m in args.methods
        }
        base = timing[name].get("improved_pso")
        for m, row in timing[name].items() if base else ():  # CPU-time ratios against improved PSO, same run
            if m == "improved_pso":
                continue
            for kind in ("first_plan", "replan"):
                for stat in ("median", "p95"):
                    ref = base[kind][f"cpu_{stat}_ms"]
                    row[kind][f"cpu_{stat}_ratio_to_improved_pso"] = round(row[kind][f"cpu_{stat}_ms"] / ref, 3)
    if args.timing_only:
        print(
            json.dumps(
                {
                    "benchmark": "junction_planner",
                    "load_average_1_5_15_min": {"start": load_start, "end": [round(x, 2) for x in os.getloadavg()]},
                    "cpus": os.cpu_count(),
                    "replan_timing_3_trains": timing,
                },
                indent=1,
            )
        )
        return
    rows = compare_table3(seeds=range(args.seeds))
    rows_corrected = compare_table3(
        seeds=range(args.seeds), methods=("improved_pso", "qp_order"), params=models["corrected"]
    )
    print(
        json.dumps(
            {
                "benchmark": "junction_planner",
                "python": platform.python_version(),
                "load_average_1_5_15_min": {"start": load_start, "end": [round(x, 2) for x in os.getloadavg()]},
                "cpus": os.cpu_count(),
                "replan_timing_3_trains": timing,
                "table3_mean_std": _table(rows),
                "table3_corrected_model_mean_std": _table(rows_corrected),
                "total_wall_s": round(time.perf_counter() - t0, 1),
            },
            indent=1,
        )
    )


def _table(rows: list[dict]) -> list[dict]:
    keep = ("scenario", "method", "runs", "coupled_rate", "plan_feasible_rate")
    table = []
    for r in rows:
        row = {k: r[k] for k in keep}
        for name in (
            "coupling_time_s",
            "coupled_speed_mps",
            "cost",
            "operation_time_s",
            "min_separation_m",
            "wall_time_s",
        ):
            row[name] = [round(r[f"{name}_mean"], 3), round(r[f"{name}_std"], 3)]
        table.append(row)
    return table


if __name__ == "__main__":
    main()
