"""``qp_order``: a deterministic junction planner — enumerate the passing orders, solve each by sequential convex QPs.

Why a second planner: the improved PSO searches accelerations over distance segments and lets the passing order emerge.
With the constraints SUMO really imposes — a switch interval of ~21.6 s, an interlocking that frees a switch only
behind the leader's rear, and the coupled follower's relative-braking-distance guard
(:func:`controllers.braking.relative_braking_distance_m`) — its swarm rarely finds a feasible plan. Spec 004
§6 #27 suggests the alternative used here: the order is a discrete choice (n! ≤ 24 for n ≤ 4), and *for a fixed
order* what is left is a smooth problem that sequential convex programming solves reliably.

Variables: kinetic energy per unit mass over distance
    The plan's own encoding is one constant acceleration per distance segment (:mod:`.model`). With
    ``E = v²`` at the segment boundaries, ``a_j = (E_{j+1} − E_j)/(2ℓ_j)`` — so the decision variables here are
    the ``E_k[j]`` of every train ``k`` at every breakpoint ``j`` of its grid, and the plan handed back is the
    *exact* acceleration vector of the model: no conversion between grids, no loss. In these variables

    * the acceleration bounds (Eq. 36), the speed bounds (Eq. 38) and the turnout speed limits (Eq. 37, held from
      the switch point over ``zone_m`` — the turnout plus the train's length, as the ATO enforces it) are
      **linear** and hard;
    * the speed at any point is linear (``v²`` is linear in distance inside a segment);
    * the time to reach a point, ``t(y) = Σ 2ℓ_j/(√E_j + √E_{j+1})``, is a **convex** function of ``E`` — the only
      non-linear ingredient, together with the guard's ``v_f²``.

Constraints of one order ``π`` (each soft, ``c(E) ≥ 0`` with one slack priced ``slack_weight`` per unit, so every
QP solves and an impossible input ends as ``feasible=False`` with named violations, never an exception)

    * switch interval (Eq. 39, the model's ``t_ls``): consecutive trains of ``π`` at a switch, legs differing:
      ``t_f(x_f) − t_l(x_l) ≥ t_ls + headway_margin_s``; the switch's own lock/throw state for the first one;
    * the **interlocking as the engine runs it** (optional, :class:`InterlockingModel`): the leader's front must
      have run ``release_after_m`` past its switch point (turnout + its length + clearance: the lock is released),
      and the throw done, before the follower reaches the point where its ATO would start braking for the end of
      its movement authority (``grant_before_m`` plus its braking distance ``v²/(2 b)`` before its switch point);
      a leader that crawls after the switch releases late — the fixed ``t_ls`` does not see that, this does;
    * the guard: for every pair on shared track (leader earlier in ``π``), at every follower breakpoint and
      segment midpoint on the shared track, the leader's front must already be ``L + RBD(v_f, a_f, v_l) +
      rbd_margin_m`` ahead: ``t_l(s̃_f + L + RBD) ≤ t_f(s̃_f)``, with ``v_l`` the leader's speed *at that instant*
      ``t_f(s̃_f)`` — where its front is then, as the guard and the rollout read it (a speed read where the spacing
      ends is higher when the leader slows down and understates ``RBD`` by ``(v_y² − v_l²)/2b``: the 0.18 m
      shortfall of scenario 2's first plan before this was fixed);
    * Eqs. 2–3 at the coupling instant ``T_c = t_lead(F)``: follower ``r`` of ``π`` reaches its slot (``r`` margins
      ``S_m`` behind F) within ``coupling_gap_tol_m`` of ``T_c`` and at the leader's speed within
      ``coupling_speed_tol_mps``; from its slot on it holds that speed (segment H).

Objective (the game's cost, spec §2.6): ``n λ4 T_c + n λ2 · 2D/(v_c − V_δ)`` (every train's ``t_1k + t_2k = T_c``;
``v_c`` the leader's speed at F), plus small penalties on accelerations and their changes (comfort), plus the
slacks. The pair terms of ``f_c`` are held near their minimum by the coupling constraints.

Sequential convex programming: at the iterate ``Ē`` every time is linearised (value and gradient are exact,
:mod:`.qp_kinematics`: sparse rows, evaluated in one batch per train), the guard's ``RBD`` too, the ``Γ2`` term by
its second-order expansion; the QP (OSQP, tolerance 1e-3 with its polishing, warm-started with the previous QP's
dual) is solved with a proximal term ``ρ|E − Ē|²`` as the trust region; the step is accepted when the exact merit
(objective + slack price × violation) falls, and ``ρ`` falls or rises (a classical ℓ1 trust-region SQP). A step
the merit rejects is tried at half its length first (one merit evaluation, no QP): the SCP then spends fewer of
its QPs on steps it throws away (on the benchmark's 39 first plans: mean ``f_c`` 226.6 in 8 QPs against 232.9 in
10 without). The first iterate of an order is a timetable (:func:`.qp_timetable.timetable_E`); a re-plan starts
from the previous plan shifted by the distance run (warm start).

**The first plan has a budget in QP solves, whatever the input** (the online budget; no wall clock, so the
plan is deterministic): it solves the order with the earliest estimated coupling (:func:`order_estimates`:
fastest profiles held back by the switch intervals at the switch where each arises) with ``first_iterations``
QPs, then, if that plan is infeasible, the runner-up (up to ``first_orders`` orders); if none is feasible, the
least violating of them continues its SCP for ``rescue_iterations`` more — at most ``first_orders ·
first_iterations + rescue_iterations`` QPs (26 by default). An unfinished plan is returned as such
(``converged=False``, or ``feasible=False`` with its violations): the coordinator polishes it with warm re-plans.
(Searching all n! orders, 40 QPs each, after a first plan whose two orders failed would cost ~1 s.) Every result
is **verified with** :func:`controllers.junction.model.rollout` (and, when given, the exact interlocking rule): a
plan is feasible only if the planner's own model says so. Everything is
deterministic (no random numbers; OSQP is deterministic for fixed data).
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, field

import numpy as np
import osqp
import scipy.sparse as sp

from controllers.braking import relative_braking_distance_m, require
from controllers.junction.model import Problem, rollout, safety_margin_m
from controllers.junction.qp_kinematics import (
    Jacobian,
    Kinematics,
    Local,
    Queries,
    Rows,
    Term,
    energy_terms,
    negated,
    time_terms,
)
from controllers.junction.qp_timetable import chained_passages, fastest_runs, timetable_E

E_SCALE = 100.0  # m²/s²: E = v² enters the QP as E / E_SCALE (conditioning)
T_SCALE = 10.0  # s: breakpoint times enter the QP as t / T_SCALE


@dataclass(frozen=True)
class InterlockingModel:
    """The engine's switch rule, in the planner's distances (see the module docstring).

    ``release_after_m``: distance the leader's front runs past its (planner) switch point until the lock is
    released (turnout + train length + clearance). ``throw_s``: the throw that follows. ``grant_before_m``: the
    follower must hold its lock when its front is this far before its switch point *plus* its braking distance
    ``v²/(2·brake_decel_mps2)`` (the ATO's end-of-authority braking point).
    """

    release_after_m: float
    throw_s: float
    grant_before_m: float
    brake_decel_mps2: float

    def __post_init__(self) -> None:
        for name in ("release_after_m", "throw_s", "grant_before_m"):
            require(name, getattr(self, name) >= 0.0, "a number >= 0", getattr(self, name))
        require("brake_decel_mps2", self.brake_decel_mps2 > 0.0, "a number > 0", self.brake_decel_mps2)


@dataclass(frozen=True)
class QpOrderParams:
    """Settings of :func:`solve_qp_order` (units in the names)."""

    speed_floor_mps: float = 2.0  # least planned speed (hard, where reachable): a crawl is fragile to track
    zone_m: float = 0.0  # turnout speed limit held this far past the planner switch point
    approach_decel_mps2: float = 0.0  # a turnout limit is approached on this braking curve (0: |a_min|)
    approach_hold_m: float = 0.0  # ... and reached this far before the turnout
    line_speed_margin_mps: float = 0.0  # planned speeds stay this far below v_max (room for the ATO's cruise law)
    headway_margin_s: float = 1.0  # extra on every switch interval
    speed_margin_mps: float = 0.2  # below each switch limit (on top of the model's switch_speed_margin_mps)
    rbd_margin_m: float = 1.0  # extra on the guard's spacing (interior instants between the samples)
    coupling_gap_tol_m: float = 1.0  # |D − S_m| at the coupling instant
    coupling_speed_tol_mps: float = 0.1  # |Δv| at the coupling instant
    accel_weight: float = 0.02  # Σ a²·ℓ (comfort)
    smooth_weight: float = 2.0  # Σ (Δa)² between neighbouring segments (comfort, trackability)
    slack_weight: float = 100.0  # price of one unit of constraint violation (above every multiplier: exact)
    prox_weight: float = 0.05  # initial proximal weight on |E − Ē|² (the step control)
    max_iterations: int = 30  # QP solves of a frozen order planned without a previous plan
    replan_iterations: int = 8  # QP solves of a warm-started re-plan (in the previous plan's order)
    first_iterations: int = 8  # QP solves per order of the first plan (the online budget)
    first_orders: int = 2  # orders the first plan tries, earliest estimated coupling first
    rescue_iterations: int = 10  # more QPs for the least violating of them if none is feasible (the QP budget)
    feasible_tol: float = 0.02  # soft-constraint violation [s, m/s] small enough to stop (margins absorb it)
    converge_merit: float = 0.3  # merit improvement (cost units, λ4 = 1 per train-second) below which to stop
    osqp_eps: float = 1.0e-3  # OSQP's absolute and relative tolerance (its polishing refines the active set)
    osqp_max_iter: int = 1000  # ADMM iterations per QP (a QP cut short is judged by the merit like any other)
    interlocking: InterlockingModel | None = None

    def __post_init__(self) -> None:
        for name in ("speed_floor_mps", "prox_weight", "feasible_tol", "converge_merit", "osqp_eps"):
            require(name, getattr(self, name) > 0.0, "a number > 0", getattr(self, name))
        for name in (
            "zone_m",
            "approach_decel_mps2",
            "line_speed_margin_mps",
            "approach_hold_m",
            "headway_margin_s",
            "speed_margin_mps",
            "rbd_margin_m",
            "coupling_gap_tol_m",
            "coupling_speed_tol_mps",
            "accel_weight",
            "smooth_weight",
        ):
            require(name, getattr(self, name) >= 0.0, "a number >= 0", getattr(self, name))
        require("slack_weight", self.slack_weight > 0.0, "a number > 0", self.slack_weight)
        for name in (
            "max_iterations",
            "replan_iterations",
            "first_iterations",
            "first_orders",
            "rescue_iterations",
            "osqp_max_iter",
        ):
            require(name, int(getattr(self, name)) >= 1, "an integer >= 1", getattr(self, name))


@dataclass
class QpOrderResult:
    """What :func:`solve_qp_order` returns (the fields :func:`.planner.decode` and the callers read)."""

    x: np.ndarray  # distance-segment accelerations (the encoding of .model)
    order: tuple[int, ...]  # passing order at the merge switch (train indices)
    cost: float  # rolled-out f_c
    violation: float  # rolled-out Σ max(g, 0) plus the interlocking shortfall [s]
    feasible: bool
    iterations: int  # QP solves
    orders_solved: int
    wall_time_s: float
    violations: dict[str, float] = field(default_factory=dict)  # soft-constraint shortfall per kind (last QP)
    converged: bool = True  # the chosen order's SCP met its convergence test before its QP budget ran out


class _Structure:
    """What every order of one problem shares: the grids, the bounds on ``E`` (speed floor and limits, turnout
    zones and their approach curves), the acceleration rows and the comfort matrix. Built once per plan."""

    def __init__(self, problem: Problem, qp: QpOrderParams) -> None:
        self.pb = problem
        self.qp = qp
        p = self.p = problem.params
        n = self.n = problem.n_trains
        self.nb = [int(problem.n_segments[k]) + 1 for k in range(n)]
        self.bp = [problem.breakpoints_m[k, : self.nb[k]].copy() for k in range(n)]
        self.off = np.concatenate([[0], np.cumsum(self.nb)]).astype(int)
        self.nE = int(self.off[-1])
        self.v0 = np.array([tr.initial_speed_mps for tr in problem.trains])
        self.d_F = np.array([tr.distance_to_F_m for tr in problem.trains])
        self.d_m = problem.merge_distance_m
        self.zone_caps: list[tuple[int, float, float]] = []  # (train, x, limit) of every switch on its path
        for k, tr in enumerate(problem.trains):
            for sw in tr.switches:
                lim = p.limit_speed_mps(sw.leg) - p.switch_speed_margin_mps - qp.speed_margin_mps
                self.zone_caps.append((k, sw.distance_m, lim))
        self._grids: tuple[list[np.ndarray], list[np.ndarray]] | None = None
        self._build()

    def _build(self) -> None:
        p, qp = self.p, self.qp
        rows_r: list[np.ndarray] = []
        rows_c: list[np.ndarray] = []
        rows_v: list[np.ndarray] = []
        pr: list[np.ndarray] = []
        pc: list[np.ndarray] = []
        pv: list[np.ndarray] = []
        self.lb = np.empty(self.nE)
        self.ub = np.empty(self.nE)
        r = 0
        for k in range(self.n):
            o, nb, bp = int(self.off[k]), self.nb[k], self.bp[k]
            ell = np.diff(bp)
            E0 = self.v0[k] ** 2
            reach_lo = np.maximum(E0 + 2.0 * p.accel_min_mps2 * bp, 0.0)  # slowest reachable E
            reach_hi = E0 + 2.0 * p.accel_max_mps2 * bp
            floor = qp.speed_floor_mps**2
            lb = np.maximum(np.minimum(floor, reach_hi), p.min_speed_mps**2)
            ub = np.full(nb, (p.line_speed_mps - qp.line_speed_margin_mps) ** 2)
            for kk, x, lim in self.zone_caps:
                if kk != k:
                    continue
                inside = (bp >= x - 1e-9) & (bp <= x + qp.zone_m + 1e-9)
                after = np.nonzero(bp > x + qp.zone_m + 1e-9)[0]
                if after.size:
                    inside[after[0]] = True
                ub = np.where(inside, np.minimum(ub, lim * lim), ub)
                # approached on a braking curve gentler than the ATO's, at the limit speed for the last
                # approach_hold_m (the ATO's speed law lags its own curve: a plan braking on it would be capped)
                b_app = qp.approach_decel_mps2 if qp.approach_decel_mps2 > 0.0 else abs(p.accel_min_mps2)
                x_hold = x - qp.approach_hold_m
                curve = lim * lim + 2.0 * b_app * np.maximum(x_hold - bp, 0.0)
                ub = np.where(bp < x, np.minimum(ub, curve), ub)
            ub = np.maximum(ub, reach_lo + 1e-6)
            lb = np.minimum(lb, ub)
            lb[0] = ub[0] = E0
            self.lb[o : o + nb] = lb
            self.ub[o : o + nb] = ub
            # acceleration rows: a_min ≤ (E_{j+1} − E_j)/(2ℓ) ≤ a_max
            m = nb - 1
            ridx = r + np.arange(m)
            rows_r += [ridx, ridx]
            rows_c += [o + np.arange(m), o + 1 + np.arange(m)]
            rows_v += [-1.0 / (2.0 * ell), 1.0 / (2.0 * ell)]
            r += m
            # comfort: Σ w_a a²ℓ + Σ w_s (Δa)², a = A E (dense: a train has a few dozen breakpoints)
            A = np.zeros((m, nb))
            A[np.arange(m), np.arange(m)] = -1.0 / (2.0 * ell)
            A[np.arange(m), np.arange(m) + 1] = 1.0 / (2.0 * ell)
            Pk = 2.0 * qp.accel_weight * (A.T @ (ell[:, None] * A))
            if m > 1:
                D = A[1:] - A[:-1]
                Pk = Pk + 2.0 * qp.smooth_weight * (D.T @ D)
            ii, jj = np.nonzero(np.triu(Pk))  # OSQP reads the upper triangle
            pr.append(o + ii)
            pc.append(o + jj)
            pv.append(Pk[ii, jj])
        self.n_acc = r
        self._acc_coo = (np.concatenate(rows_r), np.concatenate(rows_c), np.concatenate(rows_v))
        self.acc_lo = np.full(r, p.accel_min_mps2)
        self.acc_hi = np.full(r, p.accel_max_mps2)
        self._comfort_coo = (np.concatenate(pr), np.concatenate(pc), np.concatenate(pv))
        full_r = np.concatenate([self._comfort_coo[0], self._comfort_coo[1]])
        full_c = np.concatenate([self._comfort_coo[1], self._comfort_coo[0]])
        diag = self._comfort_coo[0] == self._comfort_coo[1]
        full_v = np.concatenate([self._comfort_coo[2], np.where(diag, 0.0, self._comfort_coo[2])])
        self.P_comfort = sp.csc_matrix((full_v, (full_r, full_c)), shape=(self.nE, self.nE))

    def fine_grids(self) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Per train a 2 m grid from its start to F and the ``v²`` cap on it (bounds, turnout zones held over
        ``zone_m``); the caps do not depend on the order (computed once, copies handed out)."""
        if self._grids is None:
            grids, caps = [], []
            for k in range(self.n):
                s = np.linspace(0.0, self.d_F[k], max(int(self.d_F[k] / 2.0), 20) + 1)
                ub = np.interp(s, self.bp[k], self.ub[self.off[k] : self.off[k + 1]])
                for kk, x, lim in self.zone_caps:  # the caps hold over the zone, not only at breakpoints
                    if kk == k:
                        ub = np.where((s >= x - 1e-9) & (s <= x + self.qp.zone_m), np.minimum(ub, lim * lim), ub)
                grids.append(s)
                caps.append(ub)
            self._grids = (grids, caps)
        return list(self._grids[0]), list(self._grids[1])


class _OrderSCP:
    """The problem of one passing order in the ``E`` variables: structure, linearisation, SCP (module docstring)."""

    def __init__(self, base: _Structure, order: tuple[int, ...]) -> None:
        self.base = base
        self.pb = problem = base.pb
        self.order = order
        self.qp = qp = base.qp
        p = self.p = base.p
        self.n = base.n
        self.nb, self.bp, self.off, self.nE = base.nb, base.bp, base.off, base.nE
        self.v0, self.d_F, self.d_m = base.v0, base.d_F, base.d_m
        self.zone_caps, self.lb, self.ub, self.P_comfort = base.zone_caps, base.lb, base.ub, base.P_comfort
        self._comfort_coo = base._comfort_coo
        rank = {k: i for i, k in enumerate(order)}
        self.lead = order[0]
        self.margin0_m = float(safety_margin_m(p.normal_speed_mps, p.normal_speed_mps, p))
        # slot of every follower (own coordinates) and the first breakpoint from which it holds its speed
        self.slot: dict[int, float] = {}
        F_tilde = self.d_F[self.lead] - self.d_m[self.lead]
        for r, k in enumerate(order[1:], start=1):
            self.slot[k] = float(self.d_m[k] + F_tilde - r * self.margin0_m)
        # switch pairs: (kind, lead, x_lead, fol, x_fol, need_s); first users with a ready time
        self.pairs: list[tuple[str, int, float, int, float, float]] = []
        self.first: list[tuple[int, float, float]] = []
        for sid in problem.switch_ids:
            users = sorted(problem.switch_users[sid].tolist(), key=lambda k: rank[k])
            info = {k: next(s for s in problem.trains[k].switches if s.switch_id == sid) for k in users}
            for a, b in zip(users, users[1:]):
                differ = info[a].leg != info[b].leg or p.headway_all_consecutive
                need = (p.throw_time_s if differ else p.min_time_gap_s) + qp.headway_margin_s
                self.pairs.append(("switch_headway", a, info[a].distance_m, b, info[b].distance_m, need))
                if differ and qp.interlocking is not None:
                    self.pairs.append(("interlocking", a, info[a].distance_m, b, info[b].distance_m, 0.0))
            st = problem.switch_states.get(sid)
            if st is not None and users:
                f0 = info[users[0]]
                ready = st.locked_until_s + (p.throw_time_s if f0.leg != st.position else 0.0)
                if ready > 0.0:
                    self.first.append((users[0], f0.distance_m, ready + qp.headway_margin_s))
        # guard pairs: (leader, follower, follower positions on shared track)
        self.guard: list[tuple[int, int, np.ndarray, np.ndarray]] = []
        for i, j, ii, jj in problem.shared_pairs:
            lead, fol, jf = (i, j, jj) if rank[i] < rank[j] else (j, i, ii)
            pts = self.bp[fol][jf]
            mids = 0.5 * (pts[:-1] + pts[1:])
            ys = np.concatenate([pts, mids])
            if fol in self.slot:
                ys = ys[ys <= self.slot[fol] + 1e-9]
            seg = np.clip(np.searchsorted(self.bp[fol], ys, side="right") - 1, 0, self.nb[fol] - 2)
            self.guard.append((lead, fol, ys, seg))
        self._soft_cache: tuple[bytes, tuple[np.ndarray, Jacobian, list[str]]] | None = None
        self._y: np.ndarray | None = None  # the last QP's dual (warm start of the next)
        self.timetable_T_s = math.nan  # the coupling instant of the first iterate (set by timetable_E)
        self._build_linear()

    # ------------------------------------------------------------------ constant parts
    def _build_linear(self) -> None:
        """The hard linear rows: the shared acceleration rows, plus a follower holding its speed from its slot."""
        rows_r, rows_c, rows_v = [self.base._acc_coo[0]], [self.base._acc_coo[1]], [self.base._acc_coo[2]]
        r = self.base.n_acc
        for k, y in self.slot.items():
            o, bp = int(self.off[k]), self.bp[k]
            j0 = max(int(np.searchsorted(bp, y, side="right")) - 1, 1)
            js = np.arange(j0, self.nb[k] - 1)
            ridx = r + np.arange(js.size)
            rows_r += [ridx, ridx]
            rows_c += [o + js, o + js + 1]
            rows_v += [np.ones(js.size), -np.ones(js.size)]
            r += js.size
        self._lin_coo = (np.concatenate(rows_r), np.concatenate(rows_c), np.concatenate(rows_v))
        hold = r - self.base.n_acc
        self.lin_lo = np.concatenate([self.base.acc_lo, np.zeros(hold)])
        self.lin_hi = np.concatenate([self.base.acc_hi, np.zeros(hold)])
        self.n_lin = r

    # ------------------------------------------------------------------ exact functions and linearisations
    def split(self, z: np.ndarray) -> list[np.ndarray]:
        return [z[self.off[k] : self.off[k + 1]] for k in range(self.n)]

    def soft(self, z: np.ndarray) -> tuple[np.ndarray, Jacobian, list[str]]:
        """Soft constraints ``c(z) ≥ 0``: values, Jacobian over ``[E…, t…]`` (sparse, m × 2nE) and kind names.

        The last evaluation is cached (the SCP evaluates each accepted iterate twice: merit, then linearisation).
        """
        key = z.tobytes()
        if self._soft_cache is not None and self._soft_cache[0] == key:
            return self._soft_cache[1]
        out = self._soft(z)
        self._soft_cache = (key, out)
        return out

    def _soft(self, z: np.ndarray) -> tuple[np.ndarray, Jacobian, list[str]]:
        """Every soft row, in three phases of batched position queries (a position asked in a later phase
        depends on values of an earlier one: the interlocking's braking point on the follower's speed, the
        guard's leader position on the follower's time and then on the spacing it needs)."""
        p, qp = self.p, self.qp
        Es = self.split(z)
        kin = [Kinematics(self.bp[k], Es[k]) for k in range(self.n)]
        nE = self.nE
        off = self.off

        def tt(k: int, loc: Local, scale: np.ndarray | float = 1.0) -> list[Term]:
            return time_terms(loc, int(off[k]), nE + int(off[k]), scale)

        def et(k: int, loc: Local, scale: np.ndarray | float = 1.0) -> list[Term]:
            return energy_terms(loc, int(off[k]), scale)

        il = qp.interlocking
        T_rbd, b_rbd = p.rbd_reaction_s, p.rbd_decel_mps2
        guard = self.guard if T_rbd > 0.0 else []
        # phase 1: positions known beforehand
        q1 = Queries(kin)
        h_pairs = []
        for kind, a, xa, b, xb, _ in self.pairs:
            if kind == "switch_headway":
                h_pairs.append((q1.ask(a, xa), q1.ask(b, xb)))
            else:
                assert il is not None
                h_pairs.append((q1.ask(a, xa + il.release_after_m), q1.ask(b, max(xb - il.grant_before_m, 0.0))))
        h_first = [q1.ask(k, x) for k, x, _ in self.first]
        h_guard = [q1.ask(fol, ys) for _, fol, ys, _ in guard]
        h_lead = q1.ask(self.lead, self.d_F[self.lead])
        h_slot = {k: q1.ask(k, y) for k, y in self.slot.items()}
        q1.run()
        # phase 2: the interlocking's braking points; where each guard leader is at its follower's instants
        q2 = Queries(kin)
        h_brake: list[tuple[int, slice] | None] = []
        for (kind, _, _, b, xb, _), (_, hb) in zip(self.pairs, h_pairs):
            yb = xb - il.grant_before_m - float(q1[hb].E[0]) / (2.0 * il.brake_decel_mps2) if il else -1.0
            h_brake.append(q2.ask(b, yb) if kind == "interlocking" and yb >= 0.0 else None)
        h_lpos = [q2.ask(lead, kin[lead].position_at(q1[h].t)) for (lead, _, _, _), h in zip(guard, h_guard)]
        q2.run()
        # phase 3: the guard's spacing ends (they depend on the leader's speed found in phase 2)
        q3 = Queries(kin)
        needs = []
        for (lead, fol, ys, seg), hf, hl in zip(guard, h_guard, h_lpos):
            Ek, ell = Es[fol], np.diff(self.bp[fol])
            af = np.where(ys >= self.bp[fol][-1] - 1e-9, 0.0, (Ek[seg + 1] - Ek[seg]) / (2.0 * ell[seg]))
            vf = np.sqrt(np.maximum(q1[hf].E, 1e-9))
            vl = np.sqrt(np.maximum(q2[hl].E, 1e-9))
            need = relative_braking_distance_m(vf, vl, b_rbd, b_rbd, T_rbd, af, p.rbd_margin_m)
            y0 = ys - self.d_m[fol] + self.d_m[lead] + p.pred_length_m + qp.rbd_margin_m
            needs.append((af, vf, vl, q3.ask(lead, y0 + need)))
        q3.run()

        rows = Rows()
        for (kind, a, _, b, _, need), (ha, hb), hbrake in zip(self.pairs, h_pairs, h_brake):
            la = q1[ha]
            if kind == "switch_headway":
                lb = q1[hb]
                rows.add(kind, lb.t - la.t - need, tt(b, lb) + tt(a, la, -1.0))
            elif hbrake is None:  # already inside its braking distance: the lock is granted or out of our hands
                rows.add(kind, 1.0, [])
            else:
                assert il is not None
                lb = q2[hbrake]
                rows.add(kind, lb.t - la.t - il.throw_s - qp.headway_margin_s, tt(b, lb) + tt(a, la, -1.0))
        for (k, _, ready), h in zip(self.first, h_first):
            loc = q1[h]
            rows.add("switch_state", loc.t - ready, tt(k, loc))
        # the guard: t_f(ys) − t_l(y0 + need(v_f, a_f, v_l)) ≥ 0, v_l read where the leader is at t_f(ys) (a leader
        # slowing down is slower there than where the spacing ends; reading it there understates the need by
        # (v_y² − v_l²)/2b)
        for (lead, fol, ys, seg), hf, hl, (af, vf, vl, hy) in zip(guard, h_guard, h_lpos, needs):
            lf, ll, ly = q1[hf], q2[hl], q3[hy]

            h = 1e-4  # central differences in v_f and a_f, the four evaluations in one call
            r4 = relative_braking_distance_m(
                np.concatenate([vf + h, vf - h, vf, vf]),
                np.tile(vl, 4),
                b_rbd,
                b_rbd,
                T_rbd,
                np.concatenate([af, af, af + h, af - h]),
                p.rbd_margin_m,
            ).reshape(4, -1)
            dn_dvf = (r4[0] - r4[1]) / (2 * h)
            dn_daf = (r4[2] - r4[3]) / (2 * h)
            dn_dEl = -1.0 / (2.0 * b_rbd)
            # d need/dz through v_f (E_f at ys), a_f (E_f at the segment's ends) and v_l (E_l where the leader is)
            inside = ys < self.bp[fol][-1] - 1e-9
            ell = np.diff(self.bp[fol])[seg]
            da = np.where(inside, dn_daf / (2.0 * ell), 0.0) / vl
            o = int(off[fol])
            terms = tt(fol, lf) + tt(lead, ly, -1.0)
            terms += et(fol, lf, -(dn_dvf / (2.0 * vf)) / vl) + et(lead, ll, -dn_dEl / vl)
            terms += [(o + seg, da), (o + seg + 1, -da)]
            rows.add("relative_braking", lf.t - ly.t, terms)
        # coupling at T_c = t_lead(F): each follower at its slot within the gap and speed tolerances
        lL = q1[h_lead]
        vbar = max(math.sqrt(lL.E[0]), 1.0)
        tol_t = qp.coupling_gap_tol_m / vbar
        tol_E = 2.0 * vbar * qp.coupling_speed_tol_mps
        sc = 1.0 / (2.0 * vbar)  # speed rows in m/s, not m²/s² (conditioning)
        lead = self.lead
        for k in self.slot:
            lk = q1[h_slot[k]]
            dt_, dE = lk.t - lL.t, lk.E - lL.E
            gap = tt(k, lk) + tt(lead, lL, -1.0)
            rows.add("coupling_gap", tol_t - dt_, negated(gap))
            rows.add("coupling_gap", tol_t + dt_, gap)
            spd = et(k, lk, sc) + et(lead, lL, -sc)
            rows.add("coupling_speed", sc * (tol_E - dE), negated(spd))
            rows.add("coupling_speed", sc * (tol_E + dE), spd)
        return rows.done()

    def times(self, z: np.ndarray) -> np.ndarray:
        """Breakpoint times of every train (the QP's ``t`` variables at their exact values for ``z``)."""
        return np.concatenate([Kinematics(self.bp[k], E).t_bp for k, E in enumerate(self.split(z))])

    def objective(self, z: np.ndarray) -> tuple[float, np.ndarray, float]:
        """Exact ``n λ4 T_c + n λ2 Γ2(v_c)`` + comfort; its gradient over ``[E…, t…]`` (without comfort) and Γ2's
        curvature in the leader's ``E`` at F (``T_c`` is the leader's last breakpoint time: a QP variable)."""
        p = self.p
        lead = self.lead
        kin = Kinematics(self.bp[lead], self.split(z)[lead])
        n = self.n
        c2 = n * p.weight_speed * 2.0 * p.braking_distance_m
        iF = self.off[lead + 1] - 1
        v = math.sqrt(z[iF])
        den = max(v - p.speed_error_mps, 0.05)
        d1 = -c2 / den**2  # d/dv
        d2 = 2.0 * c2 / den**3
        g = np.zeros(2 * self.nE)
        g[self.nE + iF] = n * p.weight_time
        g[iF] = d1 / (2.0 * v)
        curv = max((d2 - d1 / v) / (4.0 * v * v), 0.0)
        comfort = float(0.5 * z @ (self.P_comfort @ z))
        return float(n * p.weight_time * kin.t_bp[-1] + c2 / den + comfort), g, curv

    def merit(self, z: np.ndarray) -> tuple[float, float]:
        f, _, _ = self.objective(z)
        c, _, _ = self.soft(z)
        viol = float(np.sum(np.maximum(-c, 0.0)))
        return f + self.qp.slack_weight * viol, viol

    # ------------------------------------------------------------------ one QP and the SCP loop
    def _qp_step(self, z: np.ndarray, prox: float) -> tuple[np.ndarray | None, float]:
        """Solve the linearised QP at ``z`` with the proximal term ``prox·|E' − E|²``; returns (E', predicted merit).

        Variables ``[E…, t…, σ…]`` (E and t scaled to O(1)): ``t`` at every breakpoint, tied to ``E`` by the
        linearised segment times, so every constraint row is short. The proximal term is the step control (a
        Levenberg–Marquardt-style trust region) and makes the QP strongly convex in ``E``.
        """
        qp = self.qp
        nE = self.nE
        xbar = np.concatenate([z, self.times(z)])
        c, Jc, _ = self.soft(z)
        f, g, curv = self.objective(z)
        m = c.size
        iF = self.off[self.lead + 1] - 1
        S, ST = E_SCALE, T_SCALE
        col = np.concatenate([np.full(nE, S), np.full(nE, ST)])  # x = col · w
        # every block as COO triplets, one sparse matrix at the end (scipy's block stacking is slow at this size)
        R: list[np.ndarray] = [self._lin_coo[0]]
        Cc: list[np.ndarray] = [self._lin_coo[1]]
        V: list[np.ndarray] = [S * self._lin_coo[2]]
        r = self.n_lin
        rhs: list[np.ndarray] = []
        # linearised segment times: t_{j+1} − t_j − α E_j − β E_{j+1} = Δt̄ − α Ē_j − β Ē_{j+1}; t_0 = 0
        r_t0 = r
        for k, E in enumerate(self.split(z)):
            dt, al, be = Kinematics(self.bp[k], E).segment_rows()
            o = self.off[k]
            ms = dt.size
            idx = np.arange(ms)
            ri = r + 1 + idx
            R += [np.array([r]), ri, ri, ri, ri]
            Cc += [np.array([nE + o]), nE + o + idx + 1, nE + o + idx, o + idx, o + idx + 1]
            V += [np.array([ST]), np.full(ms, ST), np.full(ms, -ST), -S * al, -S * be]
            rhs += [np.array([0.0]), dt - al * E[:-1] - be * E[1:]]
            r += ms + 1
        b_t = np.concatenate(rhs)
        n_t = r - r_t0
        # soft rows: c + Jc (x' − x̄) + σ ≥ 0
        ii, jj = Jc.rows, Jc.cols
        R += [r + ii, r + np.arange(m)]
        Cc += [jj, 2 * nE + np.arange(m)]
        V += [Jc.vals * col[jj], np.ones(m)]
        r += m
        # boxes: E and slacks
        R += [r + np.arange(nE), r + nE + np.arange(m)]
        Cc += [np.arange(nE), 2 * nE + np.arange(m)]
        V += [np.ones(nE), np.ones(m)]
        r += nE + m
        nv = 2 * nE + m
        A = sp.csc_matrix((np.concatenate(V), (np.concatenate(R), np.concatenate(Cc))), shape=(r, nv))
        lo = np.concatenate([self.lin_lo, b_t, -c + Jc.dot(xbar), self.lb / S, np.zeros(m)])
        hi = np.concatenate([self.lin_hi, b_t, np.full(m, np.inf), self.ub / S, np.full(m, np.inf)])
        assert lo.size == r and n_t == b_t.size
        # ½ x'ᵀ(P_comfort + curv·e_F e_Fᵀ + 2·prox·I) x' + (g − curv·x̄_F e_F − 2·prox·Ē)ᵀ x' + μ Σ σ + ½ ε Σ σ²
        pr, pc, pv = self._comfort_coo
        P = sp.csc_matrix(
            (
                np.concatenate([S * S * pv, np.full(nE, S * S * 2.0 * prox), [S * S * curv], np.full(m, 1e-3)]),
                (
                    np.concatenate([pr, np.arange(nE), [iF], 2 * nE + np.arange(m)]),
                    np.concatenate([pc, np.arange(nE), [iF], 2 * nE + np.arange(m)]),
                ),
            ),
            shape=(nv, nv),
        )
        qx = g.copy()
        qx[:nE] -= 2.0 * prox * z
        qx[iF] -= curv * z[iF]
        q = np.concatenate([col * qx, np.full(m, qp.slack_weight)])
        solver = osqp.OSQP(algebra="builtin")  # named: OSQP otherwise probes for other backends at every setup
        solver.setup(
            P,
            q,
            A,
            lo,
            hi,
            verbose=False,
            eps_abs=qp.osqp_eps,
            eps_rel=qp.osqp_eps,
            max_iter=qp.osqp_max_iter,
            polishing=True,
        )
        # warm start: the primal at the linearisation point, the dual of the previous QP of this order (same rows)
        x0 = np.concatenate([xbar / col, np.maximum(-c, 0.0)])
        if self._y is not None and self._y.size == r:
            solver.warm_start(x=x0, y=self._y)
        else:
            solver.warm_start(x=x0)
        res = solver.solve(raise_error=False)
        if res.x is None or not np.all(np.isfinite(res.x)):
            return None, math.inf
        self._y = np.array(res.y, dtype=float)
        xn = col * res.x[: 2 * nE]
        zn = np.clip(xn[:nE], self.lb, self.ub)
        d = xn - xbar
        pred = (
            f
            + float(g @ d)
            + 0.5 * curv * d[iF] ** 2
            + qp.slack_weight * float(np.sum(np.maximum(-(c + Jc.dot(d)), 0.0)))
        )
        pred += float(0.5 * zn @ (self.P_comfort @ zn) - 0.5 * z @ (self.P_comfort @ z))
        return zn, pred

    def scp(self, z: np.ndarray, max_iterations: int) -> tuple[np.ndarray, int]:
        """Proximal SCP from ``z``; returns (last accepted iterate, QP solves).

        A step is accepted when the exact merit falls by at least a tenth of the QP's prediction; the proximal
        weight then falls (longer steps); a rejected step is tried at half its length (accepted if the merit
        falls by a twentieth of the prediction); the weight then rises. The loop ends when an accepted iterate
        violates the soft constraints by less than ``feasible_tol`` (their margins absorb that) and improved the
        merit by less than ``converge_merit`` — or after ``max_iterations`` QPs.
        """
        qp = self.qp
        prox = qp.prox_weight
        phi, viol = self.merit(z)
        solves = 0
        for _ in range(max_iterations):
            zn, pred = self._qp_step(z, prox)
            solves += 1
            if zn is None:
                prox *= 4.0
                continue
            phi_n, viol_n = self.merit(zn)
            predicted = phi - pred
            actual = phi - phi_n
            if actual > 0.0 and (predicted <= 1e-12 or actual >= 0.1 * predicted):
                z, phi, viol = zn, phi_n, viol_n
                if actual >= 0.25 * predicted:
                    prox = max(prox * 0.3, 1e-7)
                if viol <= qp.feasible_tol and actual < qp.converge_merit:
                    break
            else:
                if viol <= qp.feasible_tol and predicted < qp.converge_merit:
                    break
                # half the step (a merit evaluation, no QP): taken if it decreases enough; either way the
                # step was too long for the linearisation, so the proximal weight rises
                zh = 0.5 * (z + zn)
                phi_h, viol_h = self.merit(zh)
                if phi_h < phi and phi - phi_h >= 0.05 * predicted:
                    z, phi, viol = zh, phi_h, viol_h
                    prox *= 2.0
                    continue
                prox *= 4.0
        return z, solves

    # ------------------------------------------------------------------ conversions
    def to_x(self, z: np.ndarray) -> np.ndarray:
        x = np.empty(self.pb.dimension)
        for k, E in enumerate(self.split(z)):
            a = np.diff(E) / (2.0 * np.diff(self.bp[k]))
            x[self.pb.dim_slices[k]] = np.clip(a, *self.pb.bounds)
        return x

    def from_x(self, x: np.ndarray) -> np.ndarray:
        z = np.empty(self.nE)
        for k in range(self.n):
            a = x[self.pb.dim_slices[k]]
            E = self.v0[k] ** 2 + np.concatenate([[0.0], np.cumsum(2.0 * a * np.diff(self.bp[k]))])
            lo, hi = self.lb[self.off[k] : self.off[k + 1]], self.ub[self.off[k] : self.off[k + 1]]
            z[self.off[k] : self.off[k + 1]] = np.clip(E, lo, hi)
        return z


def _respects_locks(problem: Problem, order: tuple[int, ...]) -> bool:
    """True unless a planned train holding a granted lock on a switch would pass it after another user of it."""
    ids = [tr.train_id for tr in problem.trains]
    rank = {k: i for i, k in enumerate(order)}
    for sid, st in problem.switch_states.items():
        if st.locked_for is None or st.locked_for not in ids:
            continue
        holder = ids.index(st.locked_for)
        users = problem.switch_users.get(sid)
        if users is None or holder not in users.tolist():
            continue
        if any(rank[int(k)] < rank[holder] for k in users):
            return False
    return True


def order_estimates(
    problem: Problem, qp: QpOrderParams, orders: list[tuple[int, ...]], base: _Structure | None = None
) -> list[float]:
    """Estimated coupling instant of each order [s] — how the first plan picks its order.

    Every train runs its fastest profile (full acceleration, braking curves into its turnout limits) held back at
    its switches by :func:`.qp_timetable.chained_passages`; the coupling instant is when the leader reaches F or,
    if later, a follower its slot. It charges an interval at the switch where it arises (at ``sw1`` for two trains from
    ``sw1``'s legs, not at the merge) and the switches' own positions. ``base``: the problem's shared structure,
    if already built.
    """
    if not orders:
        return []
    base = base or _Structure(problem, qp)  # bounds and caps do not depend on the order
    p = base.p
    margin0_m = float(safety_margin_m(p.normal_speed_mps, p.normal_speed_mps, p))
    grids, runs = fastest_runs(base, p.accel_max_mps2, abs(p.accel_min_mps2))
    out = []
    for order in orders:
        _, holds = chained_passages(problem, qp.headway_margin_s, order, grids, runs)
        lead = order[0]
        t_c = 0.0
        for r, k in enumerate(order):
            end = base.d_F[k] if r == 0 else base.d_m[k] + base.d_F[lead] - base.d_m[lead] - r * margin0_m
            t_c = max(t_c, float(np.interp(end, grids[k], runs[k])) + holds[k])
        out.append(t_c)
    return out


def _verify(problem: Problem, scp: _OrderSCP, z: np.ndarray) -> tuple[np.ndarray, float, float, dict[str, float]]:
    """Plan ``x`` of ``z``, its rolled-out cost and violation (model + interlocking shortfall), violations by kind."""
    x = scp.to_x(z)
    r = rollout(problem, x[None, :])
    viol = float(r.violation[0])
    kinds = {name: float(v[0]) for name, v in r.terms.items()}
    if scp.qp.interlocking is not None:
        c, _, names = scp.soft(scp.from_x(x))
        short = sum(max(-(ci + scp.qp.headway_margin_s), 0.0) for ci, nm in zip(c, names) if nm == "interlocking")
        kinds["interlocking"] = short
        viol += short
    if tuple(int(k) for k in r.order[0]) != scp.order and problem.frozen_order is None:
        viol = max(viol, 1e-9)  # the plan does not realise the order it was built for
    return x, float(r.cost[0]), viol, kinds


def solve_qp_order(
    problem: Problem, params: QpOrderParams | None = None, warm_x: np.ndarray | None = None
) -> QpOrderResult:
    """Enumerate the passing orders, solve each by trust-region SCP over OSQP QPs, verify with the rollout.

    Without ``warm_x`` (the first plan) the ``first_orders`` orders with the earliest estimated coupling among
    those consistent with the granted locks are solved from their timetables (``first_iterations`` QPs each) until
    one plan is feasible; if none is, the least violating one continues for ``rescue_iterations`` more QPs — at
    most ``first_orders·first_iterations + rescue_iterations`` QPs in all, whatever the input. With ``warm_x`` (a
    re-plan: the previous plan shifted by :func:`.planner._warm_start`) only the previous plan's order is
    polished, ``replan_iterations`` QPs from the warm start — the online budget; an infeasible result is returned
    as such (the coordinator keeps the previous plan). ``problem.frozen_order`` fixes the order.
    """
    qp = params or QpOrderParams()
    t0 = time.perf_counter()
    n = problem.n_trains
    best: tuple[float, float, np.ndarray, tuple[int, ...], dict[str, float], bool] | None = None
    solves = solved = 0
    states: dict[tuple[int, ...], tuple[_OrderSCP, np.ndarray]] = {}
    base = _Structure(problem, qp)

    def consider(order: tuple[int, ...], z0: np.ndarray | None, iterations: int, resume: bool = False) -> None:
        nonlocal best, solves, solved
        if resume:
            scp, z = states[order]
        else:
            scp = _OrderSCP(base, order)
            z = scp.from_x(z0) if z0 is not None else timetable_E(scp)
            solved += 1
        z, k = scp.scp(z, iterations)
        states[order] = (scp, z)
        solves += k
        x, cost, viol, kinds = _verify(problem, scp, z)
        if (
            best is None
            or best[3] == order
            or (viol <= 0.0 and (best[0] > 0.0 or cost < best[1]))
            or (best[0] > 0.0 and viol < best[0])
        ):
            best = (viol, cost, x, order, kinds, k < iterations)

    warm_order: tuple[int, ...] | None = None
    if problem.frozen_order is not None:
        warm_order = tuple(problem.frozen_order)
    elif warm_x is not None:
        r = rollout(problem, warm_x[None, :])
        warm_order = tuple(int(k) for k in r.order[0])
    if warm_x is not None and warm_order is not None:
        # the online re-plan: polish the previous plan in its order; if that fails it is reported infeasible and
        # the caller keeps flying the previous plan (the orders were searched at the first plan)
        consider(warm_order, warm_x, qp.replan_iterations)
    elif warm_order is not None:
        consider(warm_order, None, qp.max_iterations)  # a frozen order without a previous plan
    if warm_x is None and problem.frozen_order is None:
        # the online first plan: the orders of the earliest estimated couplings, a short SCP each (it stops once
        # converged), until one is feasible
        allowed = [o for o in itertools.permutations(range(n)) if _respects_locks(problem, o)]
        ranked = sorted(zip(order_estimates(problem, qp, allowed, base), allowed))
        for _, order in ranked[: qp.first_orders]:
            consider(order, None, qp.first_iterations)
            assert best is not None
            if best[0] <= 0.0:
                break
        if best is not None and best[0] > 0.0:
            # none is feasible yet: the least violating one continues its SCP, a bounded number of QPs (an
            # unfinished plan is returned unconverged; the coordinator's polishing re-plans carry on from it)
            consider(best[3], None, qp.rescue_iterations, resume=True)
    assert best is not None
    viol, cost, x, order, kinds, converged = best
    return QpOrderResult(
        x=x,
        order=order,
        cost=cost,
        violation=viol,
        feasible=viol <= 0.0,
        iterations=solves,
        orders_solved=solved,
        wall_time_s=time.perf_counter() - t0,
        violations=kinds,
        converged=converged,
    )
