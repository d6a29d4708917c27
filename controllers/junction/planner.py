"""The online junction planner's pure core (Paper E, spec 004 §7): states in, a :class:`JunctionPlan` out.

Inputs
    * per train a :class:`TrainState`: which track it is on (``entry1``/``entry2``/``entry3`` of the project's
      ``y_junction`` world, or ``trunk`` = between sw1 and sw2), the distance from its front to the next switch
      on that track [m] and its speed [m/s];
    * per switch a :class:`~controllers.junction.model.SwitchState` (position, lock holder, lock end);
    * the :class:`YJunctionLayout` (S4, S5 and which leg of each switch is the branch) and the parameters.

Output — a :class:`JunctionPlan`: per train the acceleration profile over distance segments (``(start, end,
accel)`` along its own path from its current front position), the predicted passage time/speed at each switch
and at F; the passing order at the merge switch sw2; a switch schedule (for each switch, in passage order: which
leg, not before which time, by which time); the predicted coupling time ``T_c`` (leader at F), the coupling point
(F, and each follower's slot as a distance behind F), the coupled speed, ``f_c``, the Shapley shares ``Φ_k``.
Times are relative to the plan instant.

Method: improved PSO (default) or plain PSO over the acceleration encoding of :mod:`.model`; the initial swarm
mixes uniform particles with smooth "speed-waypoint" profiles (spec §6 #23) and, on a re-plan, the previous
plan shifted by the distance each train has run (warm start, §7). ``qp_order`` (:mod:`.qp`) is deterministic:
it enumerates the passing orders and solves each as a sequence of convex QPs, warm-started from the same shifted
previous plan; its result is decoded into the same :class:`JunctionPlan`.

Re-planning and the point of no return (documented criterion)
    :func:`replan` freezes the passing order at sw2 to the previous plan's order as soon as **any** train is
    within its service-braking distance ``v²/(2|a_min|)`` of a switch still ahead of it: from there it can no
    longer stop short of the switch, so the interlocking must already have set and locked the route for it and
    the sequence behind it must not change. Frozen re-plans optimise the profiles only, under that order.

Infeasible inputs (exact behaviour)
    * a train that is already past the merge switch, or a negative distance on its track → :class:`PlannerError`
      naming the train and the switch (the plan ends for it; spec §7 step 5 hands it to the follower controller);
    * a switch locked indefinitely (``locked_until_s = inf``) for a train outside the plan →
      :class:`PlannerError` naming the switch and the lock holder; a *finite* ``locked_until_s`` is not an error:
      it becomes a constraint (first passage ≥ lock end, plus a throw if the switch lies in the wrong leg);
    * if the optimiser finds no feasible profile the plan is still returned with ``feasible=False`` and the
      violation per constraint (``violations``): the documented fallback is the caller's (spec §7: run the
      naive closest-first strategy, :func:`controllers.junction.baselines.run_naive`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from controllers.braking import require
from controllers.junction.game import closed_form_shapley, players_from_outcome
from controllers.junction.model import (
    JunctionParams,
    Leg,
    Problem,
    SwitchOnPath,
    SwitchState,
    TrainPath,
    compile_problem,
    profile_from_speed_waypoints,
    rollout,
)
from controllers.junction.pso import PSOParams, improved_pso_params, plain_pso_params, run_pso
from controllers.junction.qp import QpOrderParams, solve_qp_order

Track = Literal["entry1", "entry2", "entry3", "trunk"]
Method = Literal["improved_pso", "plain_pso", "qp_order"]
OPTIMISERS: tuple[str, ...] = ("improved_pso", "plain_pso", "qp_order")
MERGE_SWITCH = "sw2"


class PlannerError(ValueError):
    """The planner cannot plan for these inputs; the message names the train or switch at fault."""


@dataclass(frozen=True)
class YJunctionLayout:
    """Geometry of the ``y_junction`` world that the planner needs (its docstring: spec §2.1, §6 #2)."""

    S4_m: float = 200.0  # sw1 → sw2
    S5_m: float = 200.0  # sw2 → F
    sw1_branch_leg: Leg = "reverse"  # leg used by entry3 at sw1 (entry2 uses the other)
    sw2_branch_leg: Leg = "reverse"  # leg used by entry1 at sw2 (the line from sw1 uses the other)

    def __post_init__(self) -> None:
        require("S4_m", self.S4_m > 0.0, "a number > 0", self.S4_m)
        require("S5_m", self.S5_m > 0.0, "a number > 0", self.S5_m)
        for name in ("sw1_branch_leg", "sw2_branch_leg"):
            require(name, getattr(self, name) in ("normal", "reverse"), "normal or reverse", getattr(self, name))


def _other(leg: Leg) -> Leg:
    return "normal" if leg == "reverse" else "reverse"


@dataclass(frozen=True)
class TrainState:
    """A train as the planner sees it: track, distance from its front to the next switch on it [m], speed."""

    train_id: str
    track: Track
    distance_to_switch_m: float
    speed_mps: float


def train_path(state: TrainState, layout: YJunctionLayout) -> TrainPath:
    """The :class:`TrainPath` (switches with legs, distance to F) of a train in the ``y_junction`` world."""
    d = state.distance_to_switch_m
    if state.track not in ("entry1", "entry2", "entry3", "trunk"):
        raise PlannerError(f"{state.train_id}: unknown track {state.track!r}; expected entry1, entry2, entry3 or trunk")
    if not math.isfinite(d) or not math.isfinite(state.speed_mps):
        raise PlannerError(f"{state.train_id}: distance and speed must be finite numbers")
    next_switch = "sw1" if state.track in ("entry2", "entry3") else MERGE_SWITCH
    if d < 0.0:
        raise PlannerError(
            f"{state.train_id}: already past switch {next_switch} "
            f"({-d:g} m beyond it on {state.track}); give it on the next track, or, past "
            f"{MERGE_SWITCH}, leave it out of the plan"
        )
    if state.track == "entry1":
        sws = (SwitchOnPath(MERGE_SWITCH, d, layout.sw2_branch_leg),)
        to_f = d + layout.S5_m
    elif state.track == "trunk":
        sws = (SwitchOnPath(MERGE_SWITCH, d, _other(layout.sw2_branch_leg)),)
        to_f = d + layout.S5_m
    else:
        leg1 = layout.sw1_branch_leg if state.track == "entry3" else _other(layout.sw1_branch_leg)
        sws = (SwitchOnPath("sw1", d, leg1), SwitchOnPath(MERGE_SWITCH, d + layout.S4_m, _other(layout.sw2_branch_leg)))
        to_f = d + layout.S4_m + layout.S5_m
    return TrainPath(state.train_id, float(state.speed_mps), sws, float(to_f))


@dataclass(frozen=True)
class SwitchPassage:
    switch_id: str
    leg: Leg
    time_s: float
    speed_mps: float


@dataclass(frozen=True)
class TrainPlan:
    """One train's plan. ``segments`` are ``(start_m, end_m, accel_mps2)`` along its own path from its front."""

    train_id: str
    segments: tuple[tuple[float, float, float], ...]
    passages: tuple[SwitchPassage, ...]
    arrival_F_s: float
    speed_at_F_mps: float
    slot_behind_F_m: float  # 0 for the leader; head-to-head distance behind F at T_c for followers
    shapley_share: float

    def accel_at(self, distance_m: float) -> float:
        """The planned acceleration at ``distance_m`` run since the plan instant (last segment's beyond F: 0)."""
        for start, end, a in self.segments:
            if start <= distance_m < end:
                return a
        return 0.0


@dataclass(frozen=True)
class SwitchCommand:
    """Set ``switch_id`` to ``leg`` for ``train_id``: not before ``not_before_s``, done by ``pass_time_s``."""

    switch_id: str
    leg: Leg
    train_id: str
    not_before_s: float
    pass_time_s: float
    throw_needed: bool


@dataclass(frozen=True)
class JunctionPlan:
    trains: tuple[TrainPlan, ...]
    order: tuple[str, ...]  # passing order at the merge switch sw2
    switch_schedule: tuple[SwitchCommand, ...]
    coupling_time_s: float  # T_c: the leader reaches F
    coupling_point: str  # "F"
    coupled_speed_mps: float  # mean speed of the platoon at T_c
    cost: float  # f_c(N)
    shapley: dict[str, float]
    feasible: bool
    violation: float
    violations: dict[str, float]
    frozen_order: bool
    method: str
    iterations: int
    wall_time_s: float
    # for warm starts: the distance-to-F of every train at plan time and its raw acceleration vector
    distance_to_F_m: dict[str, float] = field(default_factory=dict)
    converged: bool = True  # qp_order: False when the QP budget ran out first (the plan can still be polished)

    def train(self, train_id: str) -> TrainPlan:
        return next(t for t in self.trains if t.train_id == train_id)


def build_problem(
    trains: Sequence[TrainState],
    switches: Sequence[SwitchState] = (),
    layout: YJunctionLayout | None = None,
    params: JunctionParams | None = None,
    frozen_order: Sequence[str] | None = None,
) -> Problem:
    """Validate the inputs (see module docstring) and compile the optimisation problem."""
    layout = layout or YJunctionLayout()
    params = params or JunctionParams()
    if len(trains) < 2:
        raise PlannerError(f"need at least 2 trains to couple, got {len(trains)}")
    if len(trains) > 8:
        raise PlannerError(f"at most 8 trains per plan (exact Shapley enumeration), got {len(trains)}")
    ids = [t.train_id for t in trains]
    if len(set(ids)) != len(ids):
        raise PlannerError(f"duplicate train ids in {ids}")
    for t in trains:
        if not (0.0 < t.speed_mps <= params.line_speed_mps):
            raise PlannerError(f"{t.train_id}: speed {t.speed_mps:g} m/s outside (0, {params.line_speed_mps:g}]")
    paths = tuple(train_path(t, layout) for t in trains)
    states: dict[str, SwitchState] = {}
    for s in switches:
        if s.switch_id not in ("sw1", MERGE_SWITCH):
            raise PlannerError(f"switch {s.switch_id!r}: not a switch of the junction (sw1, sw2)")
        held_by_other = s.locked_for is not None and s.locked_for not in ids
        if held_by_other and not math.isfinite(s.locked_until_s):
            raise PlannerError(
                f"switch {s.switch_id}: locked for {s.locked_for} (outside this plan) with no "
                "release time; cannot plan through it"
            )
        if s.locked_for is not None and not held_by_other:
            s = SwitchState(s.switch_id, s.position, 0.0, s.locked_for)  # the lock belongs to the plan
        states[s.switch_id] = s
    order_idx = None
    if frozen_order is not None:
        if sorted(frozen_order) != sorted(ids):
            raise PlannerError(f"frozen order {list(frozen_order)} does not match the trains {ids}")
        order_idx = tuple(ids.index(t) for t in frozen_order)
    return compile_problem(paths, MERGE_SWITCH, params, states, order_idx)


def heuristic_seeds(problem: Problem, count: int, rng: np.random.Generator) -> np.ndarray:
    """Smooth initial particles: per train ``v(s)`` through random waypoints at its switches and F (§6 #23).

    The speed at F is common to all trains of a seed (the coupled state wants equal speeds); switch waypoints are
    drawn under the leg's limit. Deterministic given ``rng``.
    """
    p = problem.params
    out = np.empty((count, problem.dimension))
    for c in range(count):
        v_c = rng.uniform(4.0, p.normal_speed_mps - 0.5)
        for k, tr in enumerate(problem.trains):
            wp = [0.0]
            sp = [tr.initial_speed_mps]
            for sw in tr.switches:
                wp.append(sw.distance_m)
                sp.append(rng.uniform(3.0, p.limit_speed_mps(sw.leg) - 0.3))
            wp.append(tr.distance_to_F_m)
            sp.append(v_c)
            out[c, problem.dim_slices[k]] = profile_from_speed_waypoints(problem, k, np.array(wp), np.array(sp))
    return out


def _middle_speed(length_m: float, duration_s: float, v_a: float, v_b: float) -> float:
    """Midpoint speed so that two constant-acceleration halves of ``length_m`` each take ``duration_s`` in total.

    Bisection on the monotone duration; clipped to [0.3, 20] m/s when the target cannot be met.
    """
    lo, hi = 0.3, 20.0

    def dur(vm: float) -> float:
        return 2.0 * length_m / (v_a + vm) + 2.0 * length_m / (vm + v_b)

    if dur(hi) >= duration_s:
        return hi
    if dur(lo) <= duration_s:
        return lo
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if dur(mid) > duration_s:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def timed_seeds(problem: Problem, count: int, rng: np.random.Generator) -> np.ndarray:
    """Initial particles built from a random *timetable* that respects the switch headways (spec §6 #23).

    For each seed: random switch speeds (under the leg's limit) and a common coupled speed ``v_c``; nominal
    passage times from random average speeds; the passages at every switch sorted and pushed later until
    consecutive trains using different legs are ``t_ls`` apart (and trains sharing track keep their order);
    arrival times at F chosen so that follower i is ``i·S_m`` behind the leader when it reaches F. Each train's
    profile then follows ``v(s)`` through its switch speeds, with one free midpoint speed per leg solved so the
    leg takes its target time. Accelerations are clipped to the bounds, so targets are approximate.
    """
    p = problem.params
    n = problem.n_trains
    out = np.empty((count, problem.dimension))
    trains = problem.trains
    for c in range(count):
        v_c = rng.uniform(4.0, 12.0)
        sw_speed: list[list[float]] = []
        times: list[list[float]] = []
        for tr in trains:
            vs, ts = [], []
            t_prev, d_prev, v_prev = 0.0, 0.0, tr.initial_speed_mps
            for sw in tr.switches:
                v = rng.uniform(3.0, p.limit_speed_mps(sw.leg) - 0.3)
                t_prev += (sw.distance_m - d_prev) / (0.5 * (v_prev + v) * rng.uniform(0.6, 1.0))
                vs.append(v)
                ts.append(t_prev)
                d_prev, v_prev = sw.distance_m, v
            sw_speed.append(vs)
            times.append(ts)
        # enforce order and headway switch by switch, upstream first (sw1 before sw2)
        for sid in problem.switch_ids:
            users = [
                (k, [s.switch_id for s in trains[k].switches].index(sid))
                for k in range(n)
                if any(s.switch_id == sid for s in trains[k].switches)
            ]
            # trains that already share track upstream keep their order (no overtaking): a later one is
            # pushed at least a couple of seconds behind the earlier one before sorting
            for ka, ja in users:
                for kb, jb in users:
                    if ja > 0 and jb > 0 and times[ka][ja - 1] < times[kb][jb - 1]:
                        times[kb][jb] = max(times[kb][jb], times[ka][ja] + 2.0)
            users.sort(key=lambda kj: times[kj[0]][kj[1]])
            for (k0, j0), (k1, j1) in zip(users, users[1:]):
                leg0 = trains[k0].switches[j0].leg
                leg1 = trains[k1].switches[j1].leg
                need = p.throw_time_s if (leg0 != leg1 or p.headway_all_consecutive) else rng.uniform(1.0, 4.0)
                shift = max(times[k0][j0] + need - times[k1][j1], 0.0)
                for j in range(j1, len(times[k1])):
                    times[k1][j] += shift
        merge_t = [times[k][-1] for k in range(n)]
        order = np.argsort(merge_t)
        margin = p.standstill_gap_m + p.pred_length_m
        t_c = max(
            merge_t[k]
            + (trains[k].distance_to_F_m - problem.merge_distance_m[k])
            / (0.5 * (sw_speed[k][-1] + v_c) * rng.uniform(1.0, 1.3))
            - pos * margin / v_c
            for pos, k in enumerate(order)
        )
        for pos, k in enumerate(order):
            tr = trains[k]
            wp = [0.0]
            sp = [tr.initial_speed_mps]
            t_prev, v_prev = 0.0, tr.initial_speed_mps
            legs = [(s.distance_m, times[k][j], sw_speed[k][j]) for j, s in enumerate(tr.switches)]
            legs.append((tr.distance_to_F_m, t_c + pos * margin / v_c, v_c))
            for d, t_target, v_end in legs:
                length = d - wp[-1]
                vm = _middle_speed(0.5 * length, max(t_target - t_prev, 1e-3), v_prev, v_end)
                wp += [wp[-1] + 0.5 * length, d]
                sp += [vm, v_end]
                t_prev, v_prev = t_target, v_end
            out[c, problem.dim_slices[k]] = profile_from_speed_waypoints(problem, k, np.array(wp), np.array(sp))
    return out


def _warm_start(problem: Problem, previous: JunctionPlan) -> np.ndarray | None:
    x = np.zeros(problem.dimension)
    for k, tr in enumerate(problem.trains):
        if tr.train_id not in previous.distance_to_F_m:
            return None
        run_m = previous.distance_to_F_m[tr.train_id] - tr.distance_to_F_m
        plan = previous.train(tr.train_id)
        nk = int(problem.n_segments[k])
        mids = 0.5 * (problem.breakpoints_m[k, :nk] + problem.breakpoints_m[k, 1 : nk + 1]) + run_m
        x[problem.dim_slices[k]] = [plan.accel_at(m) for m in mids]
    return x


def solve(
    problem: Problem,
    method: Method = "improved_pso",
    pso: PSOParams | None = None,
    rng: np.random.Generator | None = None,
    warm: np.ndarray | None = None,
    qp: QpOrderParams | None = None,
):
    """Run the chosen optimiser on a compiled problem.

    Returns a :class:`~controllers.junction.pso.PSOResult` (PSO methods) or a
    :class:`~controllers.junction.qp.QpOrderResult` (``qp_order``, which ignores ``pso`` and ``rng``); both carry
    ``x``, ``feasible``, ``iterations`` and ``wall_time_s``.
    """
    if method not in OPTIMISERS:
        raise PlannerError(f"method {method!r}: expected one of {', '.join(OPTIMISERS)}")
    if method == "qp_order":
        return solve_qp_order(problem, qp, warm)
    if pso is None:
        pso = improved_pso_params() if method == "improved_pso" else plain_pso_params()
    rng = rng if rng is not None else np.random.default_rng(0)
    n_seed = int(round(pso.seed_fraction * pso.swarm_size))
    n_timed = n_seed // 2
    init = np.vstack([timed_seeds(problem, n_timed, rng), heuristic_seeds(problem, n_seed - n_timed, rng)])
    if warm is not None:
        init = np.vstack([warm[None, :], init])[: pso.swarm_size]
    lo, hi = problem.bounds

    def objective(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r = rollout(problem, X)
        return r.cost, r.violation

    return run_pso(objective, problem.dimension, (lo, hi), pso, rng, init)


def decode(
    problem: Problem,
    x: np.ndarray,
    method: str = "",
    iterations: int = 0,
    wall_time_s: float = 0.0,
    frozen: bool = False,
    converged: bool = True,
) -> JunctionPlan:
    """Turn one particle into a :class:`JunctionPlan` (profiles, passages, order, switch schedule, Φ_k)."""
    r = rollout(problem, x[None, :])
    p = problem.params
    ids = [tr.train_id for tr in problem.trains]
    order = [int(i) for i in r.order[0]]
    s_tilde = r.position_at_tc_m[0] - problem.merge_distance_m
    players = players_from_outcome(
        ids, order, r.merge_time_s[0], float(r.coupling_time_s[0]), r.speed_at_tc_mps[0], s_tilde
    )
    shares = closed_form_shapley(players, p)
    s_F = max(tr.distance_to_F_m - d for tr, d in zip(problem.trains, problem.merge_distance_m))
    plans = []
    for k, tr in enumerate(problem.trains):
        nk = int(problem.n_segments[k])
        bp = problem.breakpoints_m[k]
        acc = r.accel_mps2[0, k]
        segs = tuple((float(bp[j]), float(bp[j + 1]), float(acc[j])) for j in range(nk))
        passages = []
        for sw in tr.switches:
            j = int(np.argmin(np.abs(bp[: nk + 1] - sw.distance_m)))
            passages.append(
                SwitchPassage(sw.switch_id, sw.leg, float(r.time_s[0, k, j]), float(r.speed_signed_mps[0, k, j]))
            )
        plans.append(
            TrainPlan(
                tr.train_id,
                segs,
                tuple(passages),
                float(r.time_s[0, k, nk]),
                float(r.speed_signed_mps[0, k, nk]),
                float(s_F - s_tilde[k]),
                shares[tr.train_id],
            )
        )
    schedule = []
    for sid in problem.switch_ids:
        passes = sorted(
            ((pl.train_id, ps) for pl in plans for ps in pl.passages if ps.switch_id == sid),
            key=lambda item: item[1].time_s,
        )
        st = problem.switch_states.get(sid)
        prev_leg = st.position if st is not None else None
        prev_t = st.locked_until_s if st is not None else 0.0
        for tid, ps in passes:
            throw = prev_leg is not None and ps.leg != prev_leg
            schedule.append(SwitchCommand(sid, ps.leg, tid, float(prev_t), ps.time_s, throw))
            prev_leg, prev_t = ps.leg, ps.time_s
    viol = {name: float(v[0]) for name, v in r.terms.items()}
    return JunctionPlan(
        trains=tuple(plans),
        order=tuple(ids[i] for i in order),
        switch_schedule=tuple(schedule),
        coupling_time_s=float(r.coupling_time_s[0]),
        coupling_point="F",
        coupled_speed_mps=float(np.mean(r.speed_at_tc_mps[0])),
        cost=float(r.cost[0]),
        shapley=shares,
        feasible=bool(r.violation[0] <= 0.0),
        violation=float(r.violation[0]),
        violations=viol,
        frozen_order=frozen,
        method=method,
        iterations=iterations,
        wall_time_s=wall_time_s,
        converged=converged,
        distance_to_F_m={tr.train_id: tr.distance_to_F_m for tr in problem.trains},
    )


def plan(
    trains: Sequence[TrainState],
    switches: Sequence[SwitchState] = (),
    layout: YJunctionLayout | None = None,
    params: JunctionParams | None = None,
    method: Method = "improved_pso",
    pso: PSOParams | None = None,
    rng: np.random.Generator | None = None,
    qp: QpOrderParams | None = None,
    order: Sequence[str] | None = None,
) -> JunctionPlan:
    """Initial plan at the coupling opportunity (spec §7 step 1). ``order``: a passing order at the merge switch
    fixed by the caller (a formation's leader first), the plan then frozen to it; None lets the planner choose."""
    problem = build_problem(trains, switches, layout, params, order)
    res = solve(problem, method, pso, rng, qp=qp)
    return decode(
        problem,
        res.x,
        method,
        res.iterations,
        res.wall_time_s,
        frozen=order is not None,
        converged=getattr(res, "converged", True),
    )


def past_point_of_no_return(trains: Sequence[TrainState], params: JunctionParams | None = None) -> list[str]:
    """Trains within their service-braking distance ``v²/(2|a_min|)`` of the next switch ahead of them."""
    params = params or JunctionParams()
    return [t.train_id for t in trains if t.distance_to_switch_m <= t.speed_mps**2 / (2.0 * abs(params.accel_min_mps2))]


def replan(
    previous: JunctionPlan,
    trains: Sequence[TrainState],
    switches: Sequence[SwitchState] = (),
    layout: YJunctionLayout | None = None,
    params: JunctionParams | None = None,
    method: Method = "improved_pso",
    pso: PSOParams | None = None,
    rng: np.random.Generator | None = None,
    keep_order: bool = False,
    qp: QpOrderParams | None = None,
) -> JunctionPlan:
    """Receding-horizon re-plan (spec §7 steps 2–4): warm start from ``previous``; order frozen past the PNR.

    ``keep_order`` freezes the order regardless of the current states (a caller that froze it earlier keeps it
    frozen after the train that triggered the freeze has passed its switch and left the criterion).
    """
    params = params or JunctionParams()
    frozen = keep_order or bool(past_point_of_no_return(trains, params))
    ids = [t.train_id for t in trains]
    if frozen and sorted(previous.order) != sorted(ids):
        raise PlannerError(
            f"order is frozen ({', '.join(past_point_of_no_return(trains, params))} past the point "
            f"of no return) but the trains changed: {list(previous.order)} -> {ids}"
        )
    problem = build_problem(trains, switches, layout, params, previous.order if frozen else None)
    warm = _warm_start(problem, previous)
    res = solve(problem, method, pso, rng, warm, qp)
    return decode(
        problem, res.x, method, res.iterations, res.wall_time_s, frozen, converged=getattr(res, "converged", True)
    )
