"""How ``qp_order`` starts an order (:mod:`.qp`): the trains' fastest runs and the first iterate, a timetable.

The SCP of one passing order needs a first iterate in the right region, and the first plan needs to know which
orders to try first. Both come from simple kinematics on a fine (2 m) grid per train, ``E = v²`` linear in
distance between grid points, capped by the order-independent speed bounds and turnout zones of the problem
(``_Structure.fine_grids`` in :mod:`.qp`):

* :func:`fastest_runs` — every train towards the line speed at full acceleration, braking into its turnout limits;
* :func:`chained_passages` — those runs held back at each switch until it is ready for the train in a given order
  (the switch interval behind the previous user, the lock and throw of the switch for the first one);
  :func:`controllers.junction.qp.order_estimates` reads the coupling instant off them;
* :func:`timetable_E` — the first iterate of one order: merge passages pushed apart by the switch intervals, a
  common coupling instant, and per train the profile (a cruise speed found by bisection) that keeps them.

Nothing here decides feasibility: the SCP and the rollout do.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np

from controllers.junction.model import JunctionParams, Problem


class Grids(Protocol):
    """What :func:`fastest_runs` reads of a problem's shared structure (``qp._Structure``)."""

    p: JunctionParams
    v0: np.ndarray

    def fine_grids(self) -> tuple[list[np.ndarray], list[np.ndarray]]: ...


def _interval(problem: Problem, a: int, b: int) -> float:
    """Least time between ``a`` and ``b`` at the merge switch: ``t_ls`` if they meet on different legs anywhere."""
    p = problem.params
    legs_a = {s.switch_id: s.leg for s in problem.trains[a].switches}
    differ = any(s.switch_id in legs_a and legs_a[s.switch_id] != s.leg for s in problem.trains[b].switches)
    return p.throw_time_s if (differ or p.headway_all_consecutive) else p.min_time_gap_s


def _profile(
    s: np.ndarray, E0: float, cap: np.ndarray, cruise: float, a_up: float, a_down: float, tail: tuple[float, float]
) -> np.ndarray:
    """``E = v²`` on the fine grid ``s``: from ``E0`` towards ``cruise²`` (accelerating at ``a_up`` or braking at
    ``a_down``), never above the caps ``cap`` (approached on a braking curve) and reaching ``tail = (position, E)``
    on a braking curve at its end (from there on held)."""
    c2 = cruise * cruise
    x = s - s[0]
    # forward: towards the cruise speed within the acceleration bounds (v² is linear in distance)
    E = np.minimum(E0 + 2.0 * a_up * x, c2) if E0 <= c2 else np.maximum(E0 - 2.0 * a_down * x, c2)
    x_t, E_t = tail
    cap = np.where(s >= x_t, E_t, cap)
    # backward: braking curves to every cap (and to the tail's speed): cap_i = min_{j≥i} cap_j + 2 b (s_j − s_i)
    reach = np.minimum.accumulate((cap + 2.0 * a_down * x)[::-1])[::-1] - 2.0 * a_down * x
    return np.minimum(E, reach)


def _run_time(s: np.ndarray, E: np.ndarray, x: float) -> float:
    """Time to run from ``s[0]`` to ``x`` with ``E`` linear in distance between grid points."""
    v = np.sqrt(np.maximum(E, 1e-6))
    dt = 2.0 * np.diff(s) / (v[:-1] + v[1:])
    t = np.concatenate([[0.0], np.cumsum(dt)])
    return float(np.interp(x, s, t))


def _timetable_rates(p: JunctionParams) -> tuple[float, float]:
    """Acceleration and braking rates of the timetable's profiles (room left for the SCP to tighten)."""
    return 0.8 * p.accel_max_mps2, 0.8 * abs(p.accel_min_mps2)


def fastest_runs(base: Grids, a_up: float, a_down: float) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Per train its fine grid and the time along it on its fastest profile (towards the line speed at ``a_up``,
    braking curves into its turnout limits at ``a_down``: :func:`_profile` on the bounds of ``base``)."""
    grids, caps = base.fine_grids()
    runs = []
    for k, s in enumerate(grids):
        E = _profile(s, base.v0[k] ** 2, caps[k].copy(), base.p.line_speed_mps, a_up, a_down, (math.inf, 0.0))
        v = np.sqrt(np.maximum(E, 1e-6))
        runs.append(np.concatenate([[0.0], np.cumsum(2.0 * np.diff(s) / (v[:-1] + v[1:]))]))
    return grids, runs


def chained_passages(
    problem: Problem,
    headway_margin_s: float,
    order: tuple[int, ...],
    grids: list[np.ndarray],
    runs: list[np.ndarray],
) -> tuple[dict[int, dict[str, float]], dict[int, float]]:
    """Each train's switch passages (by switch id) and hold [s] in ``order`` when it runs its fastest profile
    (``runs``) but is held back at each of its switches until the switch is ready for it: after the switch
    interval behind the previous user in ``order`` (``t_ls`` when the legs differ, plus ``headway_margin_s``),
    and for the first user after the switch's own lock and throw. A hold is carried on along the train's path, so an interval
    charged at ``sw1`` delays the merge passage too (two trains from ``sw1``'s legs run on at different speeds:
    their interval at the merge is not the one at ``sw1``)."""
    p = problem.params
    last: dict[str, tuple[float, str]] = {}  # switch -> (passage time, leg) of its previous user
    passages: dict[int, dict[str, float]] = {}
    holds: dict[int, float] = {}
    for k in order:
        hold = 0.0
        passages[k] = {}
        for sw in sorted(problem.trains[k].switches, key=lambda x: x.distance_m):
            t_sw = float(np.interp(sw.distance_m, grids[k], runs[k])) + hold
            prev = last.get(sw.switch_id)
            if prev is not None:
                differ = prev[1] != sw.leg or p.headway_all_consecutive
                ready = prev[0] + (p.throw_time_s if differ else p.min_time_gap_s) + headway_margin_s
            else:
                st = problem.switch_states.get(sw.switch_id)
                ready = 0.0
                if st is not None:
                    ready = st.locked_until_s + (p.throw_time_s if sw.leg != st.position else 0.0)
                    ready = ready + headway_margin_s if ready > 0.0 else 0.0
            hold += max(ready - t_sw, 0.0)
            t_sw = max(t_sw, ready)
            last[sw.switch_id] = (t_sw, sw.leg)
            passages[k][sw.switch_id] = t_sw
        holds[k] = hold
    return passages, holds


def timetable_E(scp: Any) -> np.ndarray:
    """First iterate of an order (``scp``: its ``qp._OrderSCP``): a timetable, then per train the ``v²`` profile
    that keeps it.

    Merge passages: each train's earliest (the fastest profile: line speed, braking curves to its turnout limits),
    pushed later along the order by the switch intervals; the coupling instant ``T``: the last train's earliest
    arrival at its slot after its passage. Each train then runs, on a fine grid, towards the cruise speed (found by
    bisection) that meets its passage time, and after the merge switch towards the one that meets its slot at
    ``T``, ending at the common coupled speed ``v_c`` on a braking curve; the profile is read at the breakpoints
    and clipped to the bounds. Feasibility is left to the SCP; this only puts it in the right region.
    """
    pb, p, qp = scp.pb, scp.p, scp.qp
    order = scp.order
    a_up, a_down = _timetable_rates(p)
    floor = qp.speed_floor_mps + 0.5
    grids, caps = scp.base.fine_grids()

    def timed(k: int, x: float, target: float, E0: float, tail: tuple[float, float]) -> np.ndarray:
        s, cap = grids[k], caps[k]
        lo, hi = floor, p.line_speed_mps
        fast = _profile(s, E0, cap.copy(), hi, a_up, a_down, tail)
        if _run_time(s, fast, x) >= target:
            return fast
        for _ in range(30):
            mid = 0.5 * (lo + hi)
            if _run_time(s, _profile(s, E0, cap.copy(), mid, a_up, a_down, tail), x) > target:
                lo = mid
            else:
                hi = mid
        return _profile(s, E0, cap.copy(), hi, a_up, a_down, tail)

    none = (math.inf, 0.0)
    tau: dict[int, float] = {}
    prev = None
    for k in order:
        s = grids[k]
        t = _run_time(s, _profile(s, scp.v0[k] ** 2, caps[k].copy(), p.line_speed_mps, a_up, a_down, none), scp.d_m[k])
        if prev is not None:
            t = max(t, tau[prev] + _interval(pb, prev, k) + qp.headway_margin_s + 1.0)
        tau[k] = t
        prev = k
    lead, last = order[0], order[-1]
    first = {k: timed(k, scp.d_m[k], tau[k], scp.v0[k] ** 2, none) for k in range(scp.n)}
    end_last = scp.slot.get(last, scp.d_F[last])
    E_m = float(np.interp(scp.d_m[last], grids[last], first[last]))
    s = grids[last]
    after = _profile(s, E_m, caps[last].copy(), p.line_speed_mps, a_up, a_down, none)
    T = tau[last] + _run_time(s, after, end_last) - _run_time(s, after, scp.d_m[last]) + 2.0
    scp.timetable_T_s = T
    v_c = float(np.clip((scp.d_F[lead] - scp.d_m[lead]) / max(T - tau[lead], 1.0), floor, p.normal_speed_mps))
    z = np.empty(scp.nE)
    for k in range(scp.n):
        s = grids[k]
        end = scp.slot.get(k, scp.d_F[k])
        E_pass = float(np.interp(scp.d_m[k], s, first[k]))
        # after the merge switch: a timed profile on the grid shifted to start there, stitched to the first one
        mask = s >= scp.d_m[k]
        sub = s[mask] - scp.d_m[k]
        grids_k = grids[k]
        grids[k] = np.concatenate([[0.0], sub[sub > 0.0]])
        caps_k = caps[k]
        caps[k] = np.interp(grids[k] + scp.d_m[k], grids_k, caps_k)
        later = timed(k, end - scp.d_m[k], T - tau[k], E_pass, (end - scp.d_m[k], v_c * v_c))
        grids[k], caps[k] = grids_k, caps_k
        prof = first[k].copy()
        prof[mask] = np.interp(s[mask] - scp.d_m[k], np.concatenate([[0.0], sub[sub > 0.0]]), later)
        E = np.interp(scp.bp[k], s, prof)
        lo, hi = scp.lb[scp.off[k] : scp.off[k + 1]], scp.ub[scp.off[k] : scp.off[k + 1]]
        for j in range(1, E.size):  # the acceleration bounds at the breakpoints
            ell = scp.bp[k][j] - scp.bp[k][j - 1]
            E[j] = float(
                np.clip(E[j], E[j - 1] + 2.0 * p.accel_min_mps2 * ell, E[j - 1] + 2.0 * p.accel_max_mps2 * ell)
            )
            E[j] = float(np.clip(E[j], lo[j], hi[j]))
        z[scp.off[k] : scp.off[k + 1]] = E
    return z
