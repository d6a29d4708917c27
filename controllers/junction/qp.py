"""``qp_order``: a deterministic junction planner — enumerate the passing orders, solve each by sequential convex QPs.

Why (issue 18). The improved PSO searches accelerations over distance segments and lets the passing order emerge.
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
:func:`_times_at`), the guard's ``RBD`` too, the ``Γ2`` term by its second-order expansion; the QP (OSQP) is
solved inside a trust region ``|E − Ē| ≤ Δ``; the step is accepted when the exact merit (objective + slack price ×
violation) falls, and ``Δ`` grows or shrinks (a classical ℓ1 trust-region SQP). The first iterate of an order is a
timetable (:func:`_timetable_E`); a re-plan starts from the previous plan shifted by the distance run (warm start)
and only re-enumerates the orders when that order has become infeasible.

The first plan must fit the online budget, so it does not search every order: it solves the order with the
earliest estimated coupling (:func:`order_estimates`: fastest profiles held back by the switch intervals at the
switch where each arises) with ``first_iterations`` QPs, then, if that plan is infeasible, the runner-up (up to
``first_orders`` orders). Only if none of them has a feasible plan are all orders screened,
visited by a kinematic lower bound on ``f_c`` (:func:`order_lower_bound`) and skipped once the bound exceeds the
best verified cost. Every result is **verified with** :func:`controllers.junction.model.rollout` (and,
when given, the exact interlocking rule): a plan is feasible only if the planner's own model says so. Everything is
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
from controllers.junction.model import JunctionParams, Problem, rollout, safety_margin_m


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
    max_iterations: int = 30  # QP solves per order (the chosen order, a re-plan)
    replan_iterations: int = 8  # QP solves of a warm-started re-plan (in the previous plan's order)
    first_iterations: int = 10  # QP solves per order of the first plan (the online budget)
    first_orders: int = 2  # orders the first plan tries, earliest estimated coupling first, before a full search
    screen_iterations: int = 40  # QP solves per order when all orders are searched (arrival order infeasible)
    feasible_tol: float = 0.02  # soft-constraint violation [s, m/s] small enough to stop (margins absorb it)
    converge_merit: float = 0.3  # merit improvement (cost units, λ4 = 1 per train-second) below which to stop
    osqp_eps: float = 1.0e-4
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
        for name in ("max_iterations", "replan_iterations", "first_iterations", "first_orders", "screen_iterations"):
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


class _Kinematics:
    """One train's motion for ``E = v²`` at breakpoints ``bp``: arrival times at any positions and their gradients.

    Inside a segment the acceleration is constant (``v²`` linear in distance); beyond the last breakpoint the train
    holds its speed; positions before the first breakpoint are clamped to it. The breakpoint times and their
    gradients (a lower-triangular matrix) are computed once per iterate.
    """

    def __init__(self, bp: np.ndarray, E: np.ndarray) -> None:
        self.bp, self.E = bp, E
        self.v = v = np.sqrt(E)
        self.ell = ell = np.diff(bp)
        vs = v[:-1] + v[1:]
        self.t_bp = np.concatenate([[0.0], np.cumsum(2.0 * ell / vs)])

    def segment_rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Linearised segment times: ``t_{j+1} − t_j ≈ Δt̄_j + α_j (E_j − Ē_j) + β_j (E_{j+1} − Ē_{j+1})``."""
        vs = self.v[:-1] + self.v[1:]
        g = -2.0 * self.ell / vs**2
        return 2.0 * self.ell / vs, g / (2.0 * self.v[:-1]), g / (2.0 * self.v[1:])

    def at(self, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """At positions ``ys``: ``(t, dt/dt_bp, dt/dE, E(y), dE(y)/dE)``, gradients as dense rows × len(bp).

        The time at a point is *local*: the time of the segment's start breakpoint (a QP variable) plus the run
        inside the segment, so every row has at most three entries (a sparse, well-conditioned QP).
        """
        bp, E, v, ell = self.bp, self.E, self.v, self.ell
        nb = bp.size
        ys = np.clip(np.atleast_1d(np.asarray(ys, dtype=float)), bp[0], None)
        rows = np.arange(ys.size)
        beyond = ys >= bp[-1]
        j = np.clip(np.searchsorted(bp, ys, side="right") - 1, 0, nb - 2)
        d = np.where(beyond, 0.0, ys - bp[j])
        w = d / ell[j]
        ey = (1.0 - w) * E[j] + w * E[j + 1]
        vy = np.sqrt(np.maximum(ey, 1e-9))
        t = self.t_bp[j] + 2.0 * d / (v[j] + vy)
        h = -2.0 * d / (v[j] + vy) ** 2
        Jt = np.zeros((ys.size, nb))
        Jt[rows, j] = 1.0
        JE = np.zeros((ys.size, nb))
        JE[rows, j] += h * (1.0 / (2.0 * v[j]) + (1.0 - w) / (2.0 * vy))
        JE[rows, j + 1] += h * w / (2.0 * vy)
        W = np.zeros((ys.size, nb))
        W[rows, j] = 1.0 - w
        W[rows, j + 1] = w
        if np.any(beyond):
            db = ys[beyond] - bp[-1]
            t[beyond] = self.t_bp[-1] + db / v[-1]
            Jt[beyond] = 0.0
            Jt[beyond, -1] = 1.0
            JE[beyond] = 0.0
            JE[beyond, -1] = -db / (2.0 * E[-1] ** 1.5)
            ey[beyond] = E[-1]
            W[beyond] = 0.0
            W[beyond, -1] = 1.0
        return t, Jt, JE, ey, W

    def position_at(self, ts: np.ndarray) -> np.ndarray:
        """Positions at times ``ts`` (the inverse of :meth:`at`; exact: constant acceleration inside a segment)."""
        bp, E, v, ell = self.bp, self.E, self.v, self.ell
        ts = np.clip(np.atleast_1d(np.asarray(ts, dtype=float)), 0.0, None)
        j = np.clip(np.searchsorted(self.t_bp, ts, side="right") - 1, 0, bp.size - 2)
        tau = ts - self.t_bp[j]
        a = (E[j + 1] - E[j]) / (2.0 * ell[j])
        s = np.minimum(bp[j] + v[j] * tau + 0.5 * a * tau * tau, bp[j + 1])
        beyond = ts >= self.t_bp[-1]
        return np.where(beyond, bp[-1] + v[-1] * (ts - self.t_bp[-1]), s)


class _OrderSCP:
    """The problem of one passing order in the ``E`` variables: structure, linearisation, SCP (module docstring)."""

    def __init__(self, problem: Problem, order: tuple[int, ...], qp: QpOrderParams) -> None:
        self.pb = problem
        self.order = order
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
        self.zone_caps: list[tuple[int, float, float]] = []  # (train, x, limit)
        for sid in problem.switch_ids:
            users = sorted(problem.switch_users[sid].tolist(), key=lambda k: rank[k])
            info = {k: next(s for s in problem.trains[k].switches if s.switch_id == sid) for k in users}
            for k in users:
                lim = p.limit_speed_mps(info[k].leg) - p.switch_speed_margin_mps - qp.speed_margin_mps
                self.zone_caps.append((k, info[k].distance_m, lim))
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
        self._soft_cache: tuple[bytes, tuple[np.ndarray, np.ndarray, list[str]]] | None = None
        self.timetable_T_s = math.nan  # the coupling instant of the first iterate (set by _timetable_E)
        self._build_static()

    # ------------------------------------------------------------------ constant parts
    def _build_static(self) -> None:
        p, qp = self.p, self.qp
        rows_r: list[np.ndarray] = []
        rows_c: list[np.ndarray] = []
        rows_v: list[np.ndarray] = []
        lo: list[float] = []
        hi: list[float] = []
        P = sp.lil_matrix((self.nE, self.nE))
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
            lo += [p.accel_min_mps2] * m
            hi += [p.accel_max_mps2] * m
            r += m
            # a follower holds its speed from its slot's segment on
            if k in self.slot:
                j0 = max(int(np.searchsorted(bp, self.slot[k], side="right")) - 1, 1)
                for j in range(j0, nb - 1):
                    rows_r.append(np.array([r, r]))
                    rows_c.append(np.array([o + j, o + j + 1]))
                    rows_v.append(np.array([1.0, -1.0]))
                    lo.append(0.0)
                    hi.append(0.0)
                    r += 1
            # comfort: Σ w_a a²ℓ + Σ w_s (Δa)²
            A = sp.lil_matrix((m, nb))
            A[np.arange(m), np.arange(m)] = -1.0 / (2.0 * ell)
            A[np.arange(m), np.arange(m) + 1] = 1.0 / (2.0 * ell)
            A = A.tocsr()
            Pk = 2.0 * qp.accel_weight * (A.T @ sp.diags(ell) @ A)
            if m > 1:
                D = sp.diags([-1.0, 1.0], [0, 1], shape=(m - 1, m)) @ A
                Pk = Pk + 2.0 * qp.smooth_weight * (D.T @ D)
            P[o : o + nb, o : o + nb] = Pk
        rr, cc, vv = (np.concatenate(rows_r), np.concatenate(rows_c), np.concatenate(rows_v))
        self.A_lin = sp.csc_matrix((vv, (rr, cc)), shape=(r, self.nE))
        lin = self.A_lin.tocoo()
        self._lin_coo = (lin.row, lin.col, lin.data)
        self.lin_lo = np.array(lo)
        self.lin_hi = np.array(hi)
        self.n_lin = r
        self.P_comfort = P.tocsc()
        pc = sp.triu(self.P_comfort).tocoo()  # OSQP reads the upper triangle
        self._comfort_coo = (pc.row, pc.col, pc.data)

    # ------------------------------------------------------------------ exact functions and linearisations
    def split(self, z: np.ndarray) -> list[np.ndarray]:
        return [z[self.off[k] : self.off[k + 1]] for k in range(self.n)]

    def soft(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """Soft constraints ``c(z) ≥ 0``: values, Jacobian over ``[E…, t…]`` (m × 2nE) and kind names.

        The last evaluation is cached (the SCP evaluates each accepted iterate twice: merit, then linearisation).
        """
        key = z.tobytes()
        if self._soft_cache is not None and self._soft_cache[0] == key:
            return self._soft_cache[1]
        out = self._soft(z)
        self._soft_cache = (key, out)
        return out

    def _soft(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[str]]:
        p, qp = self.p, self.qp
        Es = self.split(z)
        kin = [_Kinematics(self.bp[k], Es[k]) for k in range(self.n)]
        vals: list[float] = []
        rows: list[np.ndarray] = []
        kinds: list[str] = []

        nX = 2 * self.nE

        def tat(k: int, ys: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
            """Time at ``ys`` and its row over all QP variables ``[E…, t…]``; E there and its row."""
            t, Jt, JE, Ey, W = kin[k].at(ys)
            a, b = self.off[k], self.off[k + 1]
            Jf = np.zeros((len(ys), nX))
            Jf[:, a:b] = JE
            Jf[:, self.nE + a : self.nE + b] = Jt
            Wf = np.zeros((len(ys), nX))
            Wf[:, a:b] = W
            return t, Jf, Ey, Wf

        il = qp.interlocking
        for kind, a, xa, b, xb, need in self.pairs:
            if kind == "switch_headway":
                ta, Ja, _, _ = tat(a, np.array([xa]))
                tb, Jb, _, _ = tat(b, np.array([xb]))
                vals.append(float(tb[0] - ta[0] - need))
                rows.append(Jb[0] - Ja[0])
            else:
                assert il is not None
                ta, Ja, _, _ = tat(a, np.array([xa + il.release_after_m]))
                _, _, Eb, _ = tat(b, np.array([max(xb - il.grant_before_m, 0.0)]))
                yb = xb - il.grant_before_m - float(Eb[0]) / (2.0 * il.brake_decel_mps2)
                if yb < 0.0:  # already inside its braking distance: the lock is granted or out of our hands
                    vals.append(1.0)
                    rows.append(np.zeros(nX))
                else:
                    tb, Jb, _, _ = tat(b, np.array([yb]))
                    vals.append(float(tb[0] - ta[0] - il.throw_s - qp.headway_margin_s))
                    rows.append(Jb[0] - Ja[0])
            kinds.append(kind)
        for k, x, ready in self.first:
            t, J, _, _ = tat(k, np.array([x]))
            vals.append(float(t[0] - ready))
            rows.append(J[0])
            kinds.append("switch_state")
        # guard
        T_rbd, b_rbd = p.rbd_reaction_s, p.rbd_decel_mps2
        if T_rbd > 0.0:
            for lead, fol, ys, seg in self.guard:
                tf, Jf, Ef, Wf = tat(fol, ys)
                Ek = Es[fol]
                ell = np.diff(self.bp[fol])
                af = (Ek[seg + 1] - Ek[seg]) / (2.0 * ell[seg])
                af = np.where(ys >= self.bp[fol][-1] - 1e-9, 0.0, af)
                vf = np.sqrt(np.maximum(Ef, 1e-9))
                s_tilde = ys - self.d_m[fol]

                def rbd(vf_: np.ndarray, af_: np.ndarray, vl_: np.ndarray) -> np.ndarray:
                    return relative_braking_distance_m(vf_, vl_, b_rbd, b_rbd, T_rbd, af_, p.rbd_margin_m)

                # the leader's speed is the guard's at the same instant: where the leader's front *is* when the
                # follower is at ys (a leader slowing down is slower there than where the spacing ends, and a
                # speed read at the spacing's end would understate the guard's need by (v_y² − v_l²)/2b)
                y0 = s_tilde + self.d_m[lead] + p.pred_length_m + qp.rbd_margin_m
                _, _, El, Wl = tat(lead, kin[lead].position_at(tf))
                vl = np.sqrt(np.maximum(El, 1e-9))
                need = rbd(vf, af, vl)
                y = y0 + need
                tl, Jl, _, _ = tat(lead, y)
                h = 1e-4
                dn_dvf = (rbd(vf + h, af, vl) - rbd(vf - h, af, vl)) / (2 * h)
                dn_daf = (rbd(vf, af + h, vl) - rbd(vf, af - h, vl)) / (2 * h)
                dn_dEl = -1.0 / (2.0 * b_rbd)
                # d need / dz: through v_f (E_f at y), a_f (E_f at the segment ends) and v_l (E_l at y)
                dneed = (dn_dvf / (2.0 * vf))[:, None] * Wf + dn_dEl * Wl
                o = self.off[fol]
                inside = ys < self.bp[fol][-1] - 1e-9
                cols_a = o + seg
                rr = np.arange(ys.size)
                dneed[rr[inside], cols_a[inside]] += -dn_daf[inside] / (2.0 * ell[seg[inside]])
                dneed[rr[inside], cols_a[inside] + 1] += dn_daf[inside] / (2.0 * ell[seg[inside]])
                c = tf - tl
                Jc = Jf - Jl - dneed / vl[:, None]
                vals += c.tolist()
                rows += list(Jc)
                kinds += ["relative_braking"] * ys.size
        # coupling at T_c = t_lead(F)
        lead = self.lead
        tL, JL, EL, WL = tat(lead, np.array([self.d_F[lead]]))
        vbar = max(math.sqrt(EL[0]), 1.0)
        tol_t = qp.coupling_gap_tol_m / vbar
        tol_E = 2.0 * vbar * qp.coupling_speed_tol_mps
        for k, y in self.slot.items():
            tk, Jk, Ek, Wk = tat(k, np.array([y]))
            dt_ = float(tk[0] - tL[0])
            vals += [tol_t - dt_, tol_t + dt_]
            rows += [-(Jk[0] - JL[0]), Jk[0] - JL[0]]
            dE = float(Ek[0] - EL[0])
            sc = 1.0 / (2.0 * vbar)  # rows in m/s, not m²/s² (conditioning)
            vals += [sc * (tol_E - dE), sc * (tol_E + dE)]
            rows += [-sc * (Wk[0] - WL[0]), sc * (Wk[0] - WL[0])]
            kinds += ["coupling_gap", "coupling_gap", "coupling_speed", "coupling_speed"]
        return np.array(vals), (np.array(rows) if rows else np.zeros((0, nX))), kinds

    def times(self, z: np.ndarray) -> np.ndarray:
        """Breakpoint times of every train (the QP's ``t`` variables at their exact values for ``z``)."""
        return np.concatenate([_Kinematics(self.bp[k], E).t_bp for k, E in enumerate(self.split(z))])

    def objective(self, z: np.ndarray) -> tuple[float, np.ndarray, float]:
        """Exact ``n λ4 T_c + n λ2 Γ2(v_c)`` + comfort; its gradient over ``[E…, t…]`` (without comfort) and Γ2's
        curvature in the leader's ``E`` at F (``T_c`` is the leader's last breakpoint time: a QP variable)."""
        p = self.p
        lead = self.lead
        kin = _Kinematics(self.bp[lead], self.split(z)[lead])
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
            dt, al, be = _Kinematics(self.bp[k], E).segment_rows()
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
        ii, jj = np.nonzero(Jc)
        R += [r + ii, r + np.arange(m)]
        Cc += [jj, 2 * nE + np.arange(m)]
        V += [Jc[ii, jj] * col[jj], np.ones(m)]
        r += m
        # boxes: E and slacks
        R += [r + np.arange(nE), r + nE + np.arange(m)]
        Cc += [np.arange(nE), 2 * nE + np.arange(m)]
        V += [np.ones(nE), np.ones(m)]
        r += nE + m
        nv = 2 * nE + m
        A = sp.csc_matrix((np.concatenate(V), (np.concatenate(R), np.concatenate(Cc))), shape=(r, nv))
        lo = np.concatenate([self.lin_lo, b_t, -c + Jc @ xbar, self.lb / S, np.zeros(m)])
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
        solver = osqp.OSQP()
        solver.setup(
            P, q, A, lo, hi, verbose=False, eps_abs=qp.osqp_eps, eps_rel=qp.osqp_eps, max_iter=4000, polishing=True
        )
        solver.warm_start(x=np.concatenate([xbar / col, np.maximum(-c, 0.0)]))
        res = solver.solve(raise_error=False)
        if res.x is None or not np.all(np.isfinite(res.x)):
            return None, math.inf
        xn = col * res.x[: 2 * nE]
        zn = np.clip(xn[:nE], self.lb, self.ub)
        d = xn - xbar
        pred = (
            f + float(g @ d) + 0.5 * curv * d[iF] ** 2 + qp.slack_weight * float(np.sum(np.maximum(-(c + Jc @ d), 0.0)))
        )
        pred += float(0.5 * zn @ (self.P_comfort @ zn) - 0.5 * z @ (self.P_comfort @ z))
        return zn, pred

    def scp(self, z: np.ndarray, max_iterations: int) -> tuple[np.ndarray, int]:
        """Proximal SCP from ``z``; returns (last accepted iterate, QP solves).

        A step is accepted when the exact merit falls by at least a tenth of the QP's prediction; the proximal
        weight then falls (longer steps), else it rises. The loop ends when an accepted iterate violates the soft
        constraints by less than ``feasible_tol`` (their margins absorb that) and improved the merit by less than
        ``converge_merit`` — or after ``max_iterations`` QPs.
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


def order_lower_bound(problem: Problem, order: tuple[int, ...]) -> float:
    """A kinematic lower bound on ``f_c`` for ``order``: earliest merge passages (full acceleration to ``v_max``)
    chained by the switch intervals, the last train then running at ``v_max`` to its slot, and ``Γ2`` at ``v_max``."""
    p = problem.params
    ms = problem.merge_switch_id
    earliest = []
    for tr in problem.trains:
        d = next(s.distance_m for s in tr.switches if s.switch_id == ms)
        v0, vm, a = tr.initial_speed_mps, p.line_speed_mps, p.accel_max_mps2
        d_acc = (vm * vm - v0 * v0) / (2.0 * a)
        earliest.append((vm - v0) / a + (d - d_acc) / vm if d >= d_acc else (math.sqrt(v0 * v0 + 2.0 * a * d) - v0) / a)
    t = earliest[order[0]]
    for a, b in zip(order, order[1:]):
        t = max(earliest[b], t + _interval(problem, a, b))
    last = order[-1]
    run = problem.trains[last].distance_to_F_m - problem.merge_distance_m[last]
    slot = (len(order) - 1) * float(safety_margin_m(p.line_speed_mps, p.line_speed_mps, p))
    t_c = t + max(run - slot, 0.0) / p.line_speed_mps
    n = problem.n_trains
    return n * p.weight_time * t_c + n * p.weight_speed * 2.0 * p.braking_distance_m / (
        p.line_speed_mps - p.speed_error_mps
    )


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


def _fine_grids(scp: _OrderSCP) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Per train a 2 m grid from its start to F and the ``v²`` cap on it (bounds, turnout zones held over
    ``zone_m``); the caps do not depend on the order."""
    grids, caps = [], []
    for k in range(scp.n):
        s = np.linspace(0.0, scp.d_F[k], max(int(scp.d_F[k] / 2.0), 20) + 1)
        ub = np.interp(s, scp.bp[k], scp.ub[scp.off[k] : scp.off[k + 1]])
        for kk, x, lim in scp.zone_caps:  # the caps hold over the zone, not only at breakpoints
            if kk == k:
                ub = np.where((s >= x - 1e-9) & (s <= x + scp.qp.zone_m), np.minimum(ub, lim * lim), ub)
        grids.append(s)
        caps.append(ub)
    return grids, caps


def _fastest_runs(scp: _OrderSCP, a_up: float, a_down: float) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Per train its fine grid and the time along it on its fastest profile (towards the line speed at ``a_up``,
    braking curves into its turnout limits at ``a_down``: :func:`_profile` on the bounds of ``scp``)."""
    grids, caps = _fine_grids(scp)
    runs = []
    for k, s in enumerate(grids):
        E = _profile(s, scp.v0[k] ** 2, caps[k].copy(), scp.p.line_speed_mps, a_up, a_down, (math.inf, 0.0))
        v = np.sqrt(np.maximum(E, 1e-6))
        runs.append(np.concatenate([[0.0], np.cumsum(2.0 * np.diff(s) / (v[:-1] + v[1:]))]))
    return grids, runs


def _chained_passages(
    problem: Problem,
    qp: QpOrderParams,
    order: tuple[int, ...],
    grids: list[np.ndarray],
    runs: list[np.ndarray],
) -> tuple[dict[int, dict[str, float]], dict[int, float]]:
    """Each train's switch passages (by switch id) and hold [s] in ``order`` when it runs its fastest profile (``runs``) but is held
    back at each of its switches until the switch is ready for it: after the switch interval behind the previous
    user in ``order`` (``t_ls`` when the legs differ, plus ``headway_margin_s``), and for the
    first user after the switch's own lock and throw. A hold is carried on along the train's path, so an interval
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
                ready = prev[0] + (p.throw_time_s if differ else p.min_time_gap_s) + qp.headway_margin_s
            else:
                st = problem.switch_states.get(sw.switch_id)
                ready = 0.0
                if st is not None:
                    ready = st.locked_until_s + (p.throw_time_s if sw.leg != st.position else 0.0)
                    ready = ready + qp.headway_margin_s if ready > 0.0 else 0.0
            hold += max(ready - t_sw, 0.0)
            t_sw = max(t_sw, ready)
            last[sw.switch_id] = (t_sw, sw.leg)
            passages[k][sw.switch_id] = t_sw
        holds[k] = hold
    return passages, holds


def order_estimates(problem: Problem, qp: QpOrderParams, orders: list[tuple[int, ...]]) -> list[float]:
    """Estimated coupling instant of each order [s] — how the first plan picks its order.

    Every train runs its fastest profile (full acceleration, braking curves into its turnout limits) held back at
    its switches by :func:`_chained_passages`; the coupling instant is when the leader reaches F or, if later, a
    follower its slot. Unlike :func:`order_lower_bound` it charges an interval at the switch where it arises
    (at ``sw1`` for two trains from ``sw1``'s legs, not at the merge) and the switches' own positions.
    """
    if not orders:
        return []
    scp = _OrderSCP(problem, orders[0], qp)  # bounds and caps do not depend on the order
    p = scp.p
    grids, runs = _fastest_runs(scp, p.accel_max_mps2, abs(p.accel_min_mps2))
    out = []
    for order in orders:
        _, holds = _chained_passages(problem, qp, order, grids, runs)
        lead = order[0]
        t_c = 0.0
        for r, k in enumerate(order):
            end = scp.d_F[k] if r == 0 else scp.d_m[k] + scp.d_F[lead] - scp.d_m[lead] - r * scp.margin0_m
            t_c = max(t_c, float(np.interp(end, grids[k], runs[k])) + holds[k])
        out.append(t_c)
    return out


def _timetable_E(scp: _OrderSCP) -> np.ndarray:
    """First iterate of an order: a timetable, then per train the ``v²`` profile that keeps it.

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
    grids, caps = _fine_grids(scp)

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
    one plan is feasible; if none is, every such order is (``screen_iterations`` QPs each, the best one then up to
    ``max_iterations``). With ``warm_x`` (a
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

    def consider(order: tuple[int, ...], z0: np.ndarray | None, iterations: int, resume: bool = False) -> None:
        nonlocal best, solves, solved
        if resume:
            scp, z = states[order]
        else:
            scp = _OrderSCP(problem, order, qp)
            z = scp.from_x(z0) if z0 is not None else _timetable_E(scp)
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
        ranked = sorted(zip(order_estimates(problem, qp, allowed), allowed))
        for _, order in ranked[: qp.first_orders]:
            consider(order, None, qp.first_iterations)
            assert best is not None
            if best[0] <= 0.0:
                break
        if best is None or best[0] > 0.0:
            # no feasible plan in that order: screen every order with a longer SCP, then finish the best one
            orders = sorted(
                (o for o in itertools.permutations(range(n)) if _respects_locks(problem, o)),
                key=lambda o: (order_lower_bound(problem, o), o),
            )
            for order in orders:
                if best is not None and best[0] <= 0.0 and order_lower_bound(problem, order) >= best[1]:
                    continue
                consider(order, None, qp.screen_iterations)
            assert best is not None
            consider(best[3], None, qp.max_iterations, resume=True)
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
