"""Naive baselines of Paper E (spec 004 §4.2): closest-first and fastest-first, then the switch limit speed.

Both are rule-based, time-stepped controllers (they may stop and wait, which the acceleration-over-distance
encoding cannot express):

1. a **priority order** — naive 1: ascending distance to the train's first switch (ties: higher speed, then list
   order); naive 2: descending initial speed (ties: shorter distance, then list order). Scenario 1 of Table 3
   gives 3, 2, 1 and 1, 3, 2, as in the paper's narratives;
2. every train runs at (accelerates at ``a_max`` / brakes at ``|a_min|`` towards) the **limit speed of its next
   switch**, passing it at no more than that limit; after its last switch it holds that switch's limit speed;
3. **switch clearance**: a train may pass switch σ only after every higher-priority user of σ has passed and,
   if the switch must be thrown for it (its leg differs from the last passer's; every pair with
   ``headway_all_consecutive``), ``t_ls`` has elapsed since that passage; otherwise it brakes to a stop in
   front of σ ("waits at the switches") and restarts when cleared;
4. a train never closes to less than the standstill gap ``S_0`` behind a train ahead on shared track (absolute
   braking-distance cap) — the paper does not mention it, it only keeps the baseline collision-free.
No gap closing is attempted, so the platoon is coupled at F only if the gaps happen to be right.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from controllers.junction.model import JunctionParams, Problem

Rule = Literal["naive1", "naive2"]


def priority_order(problem: Problem, rule: Rule) -> list[int]:
    """Train indices in priority order for ``rule`` (see module docstring)."""
    d_first = [tr.switches[0].distance_m for tr in problem.trains]
    v0 = [tr.initial_speed_mps for tr in problem.trains]
    idx = range(problem.n_trains)
    if rule == "naive1":
        return sorted(idx, key=lambda k: (d_first[k], -v0[k], k))
    if rule == "naive2":
        return sorted(idx, key=lambda k: (-v0[k], d_first[k], k))
    raise ValueError(f"rule: expected naive1 or naive2, got {rule!r}")


def approach_speed_cap(speed_mps: float, distance_m: float, limit_mps: float, dt_s: float, brake_mps2: float) -> float:
    """Highest speed [m/s] allowed now so that the train meets ``limit_mps`` at ``distance_m`` ahead.

    The braking curve uses 80 % of ``brake_mps2`` and looks one step ahead, so discrete tracking of the curve
    never overshoots the switch or its limit (the naive strategies' "run towards the next switch's limit").
    """
    look = distance_m - speed_mps * dt_s
    return float(min(limit_mps, np.sqrt(limit_mps**2 + 2.0 * 0.8 * brake_mps2 * max(look, 0.0))))


def accel_towards(speed_cap_mps: float, speed_mps: float, dt_s: float, params: JunctionParams) -> float:
    """Acceleration that reaches ``speed_cap_mps`` in one step, within the planner's ``[a_min, a_max]``."""
    return float(np.clip((speed_cap_mps - speed_mps) / dt_s, params.accel_min_mps2, params.accel_max_mps2))


def run_naive(
    problem: Problem, rule: Rule, dt_s: float = 0.1, horizon_s: float = 600.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Simulate the naive strategy; returns ``(time_s (T,), position_m (T, n), speed_mps (T, n))``.

    Positions are along each train's own path from its start; the run ends when every train is past F (plus
    one step) or at ``horizon_s``.
    """
    p = problem.params
    n = problem.n_trains
    trains = problem.trains
    prio = priority_order(problem, rule)
    rank = {k: r for r, k in enumerate(prio)}
    s = np.zeros(n)
    v = np.array([tr.initial_speed_mps for tr in trains], dtype=float)
    passed: dict[str, list[tuple[float, int, str]]] = {sid: [] for sid in problem.switch_ids}
    nxt = [0] * n
    b = abs(p.accel_min_mps2)
    ts, ss, vs = [0.0], [s.copy()], [v.copy()]
    t = 0.0
    d_F = np.array([tr.distance_to_F_m for tr in trains])
    while t < horizon_s - 1e-9 and not np.all(s > d_F):
        acc = np.zeros(n)
        for k in prio:
            tr = trains[k]
            caps = []
            if nxt[k] < len(tr.switches):
                sw = tr.switches[nxt[k]]
                v_lim = p.limit_speed_mps(sw.leg)
                d_sw = sw.distance_m - s[k]
                caps.append(approach_speed_cap(float(v[k]), d_sw, v_lim, dt_s, b))
                look = d_sw - v[k] * dt_s
                users = [q for q in range(n) if any(x.switch_id == sw.switch_id for x in trains[q].switches)]
                ahead = [q for q in users if rank[q] < rank[k]]
                done = {q for _, q, _ in passed[sw.switch_id]}
                cleared = all(q in done for q in ahead)
                if cleared and passed[sw.switch_id]:
                    t_last, _, leg_last = passed[sw.switch_id][-1]
                    need = p.throw_time_s if (leg_last != sw.leg or p.headway_all_consecutive) else 0.0
                    cleared = t - t_last >= need
                if not cleared:
                    caps.append(np.sqrt(2.0 * 0.8 * b * max(look - 1.0, 0.0)))
            else:
                caps.append(p.limit_speed_mps(tr.switches[-1].leg))
            # absolute braking cap behind trains ahead on shared track (common coordinate)
            for i, j, ii, _jj in problem.shared_pairs:
                if k not in (i, j):
                    continue
                q = j if k == i else i
                st_k = s[k] - problem.merge_distance_m[k]
                st_q = s[q] - problem.merge_distance_m[q]
                first_common = problem.breakpoints_m[i, ii[0]] - problem.merge_distance_m[i]
                if st_q > st_k and st_k >= first_common - 1e-9 and st_q >= first_common:
                    gap = st_q - st_k - p.pred_length_m - p.standstill_gap_m - v[k] * dt_s
                    caps.append(np.sqrt(2.0 * 0.8 * b * max(gap, 0.0)))
            acc[k] = accel_towards(min(caps), float(v[k]), dt_s, p)
        s_new = s + np.maximum(v * dt_s + 0.5 * acc * dt_s**2, 0.0)
        v_new = np.maximum(v + acc * dt_s, 0.0)
        for k, tr in enumerate(trains):
            while nxt[k] < len(tr.switches) and s_new[k] >= tr.switches[nxt[k]].distance_m:
                sw = tr.switches[nxt[k]]
                frac = (sw.distance_m - s[k]) / max(s_new[k] - s[k], 1e-12)
                passed[sw.switch_id].append((t + frac * dt_s, k, sw.leg))
                nxt[k] += 1
        s, v, t = s_new, v_new, t + dt_s
        ts.append(t)
        ss.append(s.copy())
        vs.append(v.copy())
    return np.array(ts), np.array(ss), np.array(vs)
