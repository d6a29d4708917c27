"""``qp_order``: a deterministic junction planner — enumerate the passing orders, solve each as a convex QP (OSQP).

Why (issue 18). The improved PSO searches accelerations over distance segments and lets the passing order emerge.
With the constraints SUMO really imposes — a 21.6 s switch interval and the coupled follower's
relative-braking-distance guard (:func:`controllers.braking.relative_braking_distance_m`) — its swarm rarely finds
a feasible plan. Spec 004 §6 #27 suggests the alternative used here: the order is a discrete choice (n! ≤ 24
for n ≤ 4), and *for a fixed order* what is left is nearly convex.

Model for one order (time domain, fixed grid ``Δt = step_s``)
    Per train ``k`` the decision is a piecewise-constant acceleration ``u_k[i]`` on ``[iΔt, (i+1)Δt)``; position and
    speed along its own path are QP variables tied by the exact double-integrator equalities
    ``v[i+1] = v[i] + u[i]Δt``, ``s[i+1] = s[i] + v[i]Δt + u[i]Δt²/2`` (spec Eqs. 9–10, 14–15). Hard: Eq. 36
    (``a_min ≤ u ≤ a_max``), Eq. 38 (``v_eps ≤ v ≤ v_max``) and a comfort jerk bound ``|u[i+1] − u[i]| ≤ J·Δt``.
    The horizon ends at the **coupling instant** ``N·Δt``: from then on every train holds its speed (segment H).

    Soft (each group ``g`` gets one slack ``σ_g ≥ 0`` priced ``slack_weight`` per unit, so a QP always solves and
    an impossible input ends as ``feasible=False`` with violations, never as an exception):

    * Eq. 37, switch speed: the speed at the grid points around the switch passage ≤ leg limit − margin;
    * Eq. 39, switch interval: consecutive trains of the order at each switch pass ``t_ls`` apart (legs differ) or
      ``min_time_gap_s`` (same leg), plus the switch's own lock/throw state for the first one;
    * the guard: for every pair on shared track, from the leader's passage of their first common switch on,
      ``s̃_lead − s̃_fol − L ≥ RBD(v_fol, u_fol, v_lead) + rbd_margin_m`` at every grid point;
    * Eqs. 2–3 at the coupling instant: each follower at its slot ``S_m`` behind its predecessor (``S_m`` of Eq. 1,
      linear in the speeds when the closing speed is ≥ 0, which the speed-equality band guarantees), speeds equal
      within ``coupling_speed_tol_mps``, and the leader not yet past F (``T_c`` ≥ the coupling instant).

    Passage times are the only non-convex part: ``t_k(x) ≈ τ̄ − (s_k(τ̄) − x)/v̄`` linearised at the previous
    iterate's passage ``τ̄`` (``s_k(τ̄)`` is linear in the variables), and the guard's RBD is linearised in
    ``(v_fol, u_fol, v_lead)``. Sequential convex programming re-linearises at each solution until the passage
    times move less than ``converge_s``.

Objective (the game's cost, spec §2.6): ``f_c = Σ_k [λ4(t_1k + t_2k) + λ2·2D/(v_k − V_δ)] + pair terms``.
    ``t_1k + t_2k = T_c`` for every train and ``T_c = NΔt + (d_F − s_lead[N])/v_lead[N]``: the QP minimises
    ``nλ4·T_c`` linearised plus ``λ2·2D/(v_k[N] − V_δ)`` by its second-order expansion (convex), plus small
    penalties on ``u`` and ``Δu`` (smoothness). The pair terms are held at their minimum by the constraints.

Coupling instant. Feasibility is (nearly) monotone in ``N`` and the cost falls with ``N`` while the leader still
has ≥ Δt to run to F at ``N``; the search starts from a guess (the warm start's, else a kinematic one), steps
up until feasible, then jumps by the leader's remaining time until it is < Δt.

Orders. All ``n!`` passing orders at the merge switch (only the frozen one when ``problem.frozen_order`` is set),
visited by a kinematic lower bound on ``f_c`` (earliest passages chained by the switch intervals) and skipped once
the bound exceeds the best verified cost. Every QP result is converted to the distance-segment encoding of
:mod:`.model` (``a_j = (v_{j+1}² − v_j²)/(2ℓ_j)`` through the QP's speeds at the breakpoints — exact in speed at
every breakpoint) and **verified with** :func:`controllers.junction.model.rollout`: a plan is feasible only if the
planner's own model, guard included, says so. The best order is the feasible one with the least rolled-out
``f_c`` (else the least violation); Shapley shares come from :func:`.planner.decode` as for the other methods.

Everything is deterministic (no random numbers; OSQP is deterministic for fixed data).
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass

import numpy as np
import osqp
import scipy.sparse as sp

from controllers.braking import require
from controllers.junction.model import Problem, rollout, safety_margin_m


@dataclass(frozen=True)
class QpOrderParams:
    """Settings of :func:`solve_qp_order` (units in the names)."""

    step_s: float = 1.0  # Δt of the time grid
    jerk_max_mps3: float = 1.0  # comfort bound |Δu| ≤ J·Δt
    speed_floor_mps: float = 3.0  # least planned speed once reachable (see _OrderQP.solve)
    accel_weight: float = 0.01  # Σ u² (per s of grid)
    smooth_weight: float = 0.1  # Σ (Δu)²
    slack_weight: float = 1000  # price of one unit of constraint violation (above every dual: exact)
    proximal_weight: float = 0.001  # Σ (v − v̄)² on the speeds: damps the SCP step, helps ADMM
    osqp_eps: float = 1.0e-4  # OSQP's absolute and relative tolerances (the solution is polished)
    headway_margin_s: float = 0.5  # extra on every switch interval (grid and conversion error)
    speed_margin_mps: float = 0.1  # below each switch limit
    rbd_margin_m: float = 2.0  # extra on the guard's spacing (linearisation and conversion error)
    coupling_speed_tol_mps: float = 0.1  # |Δv| at the coupling instant
    coupling_gap_tol_m: float = 1.0  # |D − S_m| at the coupling instant
    scp_iterations: int = 6  # re-linearisations per coupling instant
    trust_s: float = 4.0  # a passage time moves at most this much per SCP step (soft)
    converge_s: float = 0.25  # passage times moving less than this: converged
    max_probes: int = 10  # coupling instants tried per order
    lower_probes: int = 2  # earlier coupling instants tried after the first feasible one
    max_horizon_s: float = 300.0
    feasibility_tol: float = 1e-3  # total slack below which a QP counts as feasible

    def __post_init__(self) -> None:
        for name in ("step_s", "jerk_max_mps3", "max_horizon_s", "trust_s", "converge_s", "feasibility_tol"):
            require(name, getattr(self, name) > 0.0, "a number > 0", getattr(self, name))
        for name in (
            "speed_floor_mps",
            "accel_weight",
            "smooth_weight",
            "proximal_weight",
            "osqp_eps",
            "headway_margin_s",
            "speed_margin_mps",
            "rbd_margin_m",
            "coupling_speed_tol_mps",
            "coupling_gap_tol_m",
        ):
            require(name, getattr(self, name) >= 0.0, "a number >= 0", getattr(self, name))
        require("slack_weight", self.slack_weight > 0.0, "a number > 0", self.slack_weight)
        for name in ("scp_iterations", "max_probes", "lower_probes"):
            require(name, int(getattr(self, name)) >= 1, "an integer >= 1", getattr(self, name))


@dataclass
class QpOrderResult:
    """What :func:`solve_qp_order` returns (the fields :func:`.planner.decode` and the callers read)."""

    x: np.ndarray  # distance-segment accelerations (the encoding of .model)
    order: tuple[int, ...]  # passing order at the merge switch (train indices)
    cost: float  # rolled-out f_c
    violation: float  # rolled-out Σ max(g, 0)
    feasible: bool
    iterations: int  # QP solves
    orders_solved: int
    wall_time_s: float
    coupling_step: int  # N of the chosen plan (coupling instant = N·step_s)


@dataclass
class _Traj:
    """A time-grid trajectory of all trains: positions/speeds (n, N+1), accelerations (n, N)."""

    s: np.ndarray
    v: np.ndarray
    u: np.ndarray

    @property
    def steps(self) -> int:
        return self.u.shape[1]


def _passage_time(tr: _Traj, k: int, x: float, dt: float) -> float:
    """Time at which train ``k`` of the grid trajectory reaches ``x`` (exact within a step; constant speed after)."""
    s, v, u = tr.s[k], tr.v[k], tr.u[k]
    N = tr.steps
    if x <= s[0]:
        return 0.0
    if x > s[N]:
        return N * dt + (x - s[N]) / max(v[N], 1e-3)
    i = min(int(np.searchsorted(s, x, side="right")) - 1, N - 1)
    d = x - s[i]
    if abs(u[i]) < 1e-9:
        return i * dt + d / max(v[i], 1e-3)
    disc = max(v[i] * v[i] + 2.0 * u[i] * d, 0.0)
    return i * dt + (math.sqrt(disc) - v[i]) / u[i]


def _resample(tr: _Traj, N: int, dt: float) -> _Traj:
    """The same motion on a grid of ``N`` steps: truncated, or extended at constant speed."""
    M = tr.steps
    if N <= M:
        return _Traj(tr.s[:, : N + 1].copy(), tr.v[:, : N + 1].copy(), tr.u[:, :N].copy())
    extra = np.arange(1, N - M + 1) * dt
    s = np.concatenate([tr.s, tr.s[:, -1:] + tr.v[:, -1:] * extra[None, :]], axis=1)
    v = np.concatenate([tr.v, np.repeat(tr.v[:, -1:], N - M, axis=1)], axis=1)
    u = np.concatenate([tr.u, np.zeros((tr.u.shape[0], N - M))], axis=1)
    return _Traj(s, v, u)


def trajectory_from_profile(problem: Problem, x: np.ndarray, N: int, dt: float) -> _Traj:
    """Sample the distance-segment plan ``x`` (exact rollout) on a time grid of ``N`` steps (an SCP iterate)."""
    r = rollout(problem, x[None, :])
    n = problem.n_trains
    times = np.arange(N + 1) * dt
    s = np.empty((n, N + 1))
    v = np.empty((n, N + 1))
    for k in range(n):
        nk = int(problem.n_segments[k])
        tk = r.time_s[0, k, : nk + 1]
        vk = np.maximum(r.speed_signed_mps[0, k, : nk + 1], problem.params.min_speed_mps)
        bp = problem.breakpoints_m[k, : nk + 1]
        s[k] = np.where(times <= tk[-1], np.interp(times, tk, bp), bp[-1] + vk[-1] * (times - tk[-1]))
        v[k] = np.interp(times, tk, vk)
    u = np.clip(np.diff(v, axis=1) / dt, *problem.bounds)
    return _Traj(s, v, u)


class _Rows:
    """Sparse constraint rows ``l ≤ A·z ≤ u`` collected as COO triplets."""

    def __init__(self) -> None:
        self.r: list[np.ndarray] = []
        self.c: list[np.ndarray] = []
        self.v: list[np.ndarray] = []
        self.lo: list[float] = []
        self.hi: list[float] = []

    def add(self, cols: list[int] | np.ndarray, vals: list[float] | np.ndarray, lo: float, hi: float) -> None:
        row = len(self.lo)
        cols = np.asarray(cols, dtype=int)
        self.r.append(np.full(cols.size, row))
        self.c.append(cols)
        self.v.append(np.asarray(vals, dtype=float))
        self.lo.append(lo)
        self.hi.append(hi)

    def add_block(self, rows_c: np.ndarray, rows_v: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
        """Many rows with the same number of entries: ``rows_c``/``rows_v`` are (R, m)."""
        R = rows_c.shape[0]
        base = len(self.lo)
        self.r.append(np.repeat(np.arange(base, base + R), rows_c.shape[1]))
        self.c.append(rows_c.ravel().astype(int))
        self.v.append(rows_v.ravel().astype(float))
        self.lo.extend(np.broadcast_to(lo, (R,)).tolist())
        self.hi.extend(np.broadcast_to(hi, (R,)).tolist())

    def matrix(self, n_cols: int) -> tuple[sp.csc_matrix, np.ndarray, np.ndarray]:
        A = sp.csc_matrix(
            (np.concatenate(self.v), (np.concatenate(self.r), np.concatenate(self.c))), shape=(len(self.lo), n_cols)
        )
        return A, np.array(self.lo), np.array(self.hi)


class _OrderQP:
    """The QP of one passing order: building, solving and re-linearising it (see the module docstring)."""

    def __init__(self, problem: Problem, order: tuple[int, ...], qp: QpOrderParams) -> None:
        self.pb = problem
        self.order = order
        self.qp = qp
        p = problem.params
        self.n = problem.n_trains
        self.v0 = np.array([tr.initial_speed_mps for tr in problem.trains])
        self.d_F = np.array([tr.distance_to_F_m for tr in problem.trains])
        self.d_m = problem.merge_distance_m
        rank = {k: i for i, k in enumerate(order)}
        # consecutive users of each switch in the order's sequence, with the interval they need
        self.switch_pairs: list[tuple[int, float, int, float, float]] = []  # (lead, x_lead, fol, x_fol, need_s)
        self.switch_first: list[tuple[int, float, float]] = []  # (train, x, ready_s)
        self.speed_points: list[tuple[int, float, float]] = []  # (train, x, limit)
        for sid in problem.switch_ids:
            users = sorted(problem.switch_users[sid].tolist(), key=lambda k: rank[k])
            info = {}
            for k in users:
                sw = next(s for s in problem.trains[k].switches if s.switch_id == sid)
                info[k] = sw
                self.speed_points.append((k, sw.distance_m, p.limit_speed_mps(sw.leg) - qp.speed_margin_mps))
            for a, b in zip(users, users[1:]):
                differ = info[a].leg != info[b].leg or p.headway_all_consecutive
                need = (p.throw_time_s if differ else p.min_time_gap_s) + qp.headway_margin_s
                self.switch_pairs.append((a, info[a].distance_m, b, info[b].distance_m, need))
            st = problem.switch_states.get(sid)
            if st is not None and users:
                first = info[users[0]]
                ready = st.locked_until_s + (p.throw_time_s if first.leg != st.position else 0.0)
                if ready > 0.0:
                    self.switch_first.append((users[0], first.distance_m, ready + qp.headway_margin_s))
        # pairs on shared track (leader = earlier in the order) and the distance of their first common switch
        self.shared: list[tuple[int, int, float]] = []
        for i, j, _, _ in problem.shared_pairs:
            lead, fol = (i, j) if rank[i] < rank[j] else (j, i)
            common = [
                s
                for s in problem.trains[lead].switches
                if s.switch_id in {t.switch_id for t in problem.trains[fol].switches}
            ]
            self.shared.append((lead, fol, common[0].distance_m))
        v_ref = p.normal_speed_mps
        self.margin0_m = float(safety_margin_m(v_ref, v_ref, p))  # S_m at equal speeds
        self.margin_slope_s = float(safety_margin_m(v_ref, v_ref + 1.0, p)) - self.margin0_m  # ∂S_m/∂(v_f − v_l)

    # -------------------------------------------------------------- variable layout
    def _idx(self, N: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        block = 3 * N + 2
        base = np.arange(self.n)[:, None] * block
        s = base + np.arange(N + 1)[None, :]
        v = base + N + 1 + np.arange(N + 1)[None, :]
        u = base + 2 * N + 2 + np.arange(N)[None, :]
        return s, v, u

    def _lin_point(
        self, tr: _Traj, k: int, x: float, N: int, S: np.ndarray, V: np.ndarray, U: np.ndarray
    ) -> tuple[list[int], list[float], float, float, list[int]]:
        """Linearised passage time of train ``k`` at ``x``: ``t ≈ Σ c·z + const``; also the grid speeds around it."""
        dt = self.qp.step_s
        tau = _passage_time(tr, k, x, dt)
        if tau < N * dt:
            i0 = min(int(tau // dt), N - 1)
            f = tau - i0 * dt
            vbar = max(tr.v[k, i0] + tr.u[k, i0] * f, 0.3)
            cols = [S[k, i0], V[k, i0], U[k, i0]]
            coef = [-1.0 / vbar, -f / vbar, -0.5 * f * f / vbar]
            speed_idx = [V[k, i0], V[k, i0 + 1]]
        else:
            f = tau - N * dt
            vbar = max(tr.v[k, N], 0.3)
            cols = [S[k, N], V[k, N]]
            coef = [-1.0 / vbar, -f / vbar]
            speed_idx = [V[k, N]]
        return cols, coef, tau + x / vbar, tau, speed_idx

    def solve(self, tr: _Traj) -> tuple[_Traj, float, float]:
        """One QP linearised at ``tr`` (N = its steps). Returns the new trajectory, the total slack, the f_c model."""
        qp, p = self.qp, self.pb.params
        n, dt, N = self.n, qp.step_s, tr.steps
        S, V, U = self._idx(N)
        n_state = n * (3 * N + 2)
        groups: dict[str, int] = {}

        def slack(name: str) -> int:
            return n_state + groups.setdefault(name, len(groups))

        rows = _Rows()
        # dynamics (exact double integrator on the grid) and initial state
        for k in range(n):
            i = np.arange(N)
            rows.add_block(
                np.stack([V[k, i + 1], V[k, i], U[k, i]], axis=1),
                np.tile([1.0, -1.0, -dt], (N, 1)),
                np.zeros(N),
                np.zeros(N),
            )
            rows.add_block(
                np.stack([S[k, i + 1], S[k, i], V[k, i], U[k, i]], axis=1),
                np.tile([1.0, -1.0, -dt, -0.5 * dt * dt], (N, 1)),
                np.zeros(N),
                np.zeros(N),
            )
            rows.add([S[k, 0]], [1.0], 0.0, 0.0)
            rows.add([V[k, 0]], [1.0], self.v0[k], self.v0[k])
            # speed floor (reachable from v0 at half the traction bound): a train that must wait does so by running
            # slowly over a distance, which the distance-segment encoding can represent — not by a dip to a crawl
            # inside one segment, which it cannot
            reach = self.v0[k] + 0.5 * p.accel_max_mps2 * dt * np.arange(1, N + 1)
            floor = np.maximum(np.minimum(qp.speed_floor_mps, reach), p.min_speed_mps + 0.05)
            rows.add_block(V[k, 1:, None], np.ones((N, 1)), floor, np.full(N, p.line_speed_mps - qp.speed_margin_mps))
            rows.add_block(U[k, :, None], np.ones((N, 1)), np.full(N, p.accel_min_mps2), np.full(N, p.accel_max_mps2))
            if N > 1:
                rows.add_block(
                    np.stack([U[k, 1:], U[k, :-1]], axis=1),
                    np.tile([1.0, -1.0], (N - 1, 1)),
                    np.full(N - 1, -qp.jerk_max_mps3 * dt),
                    np.full(N - 1, qp.jerk_max_mps3 * dt),
                )
        inf = np.inf
        # Eq. 37: speed at the switch passage
        for k, x, lim in self.speed_points:
            cols, vals, const, tau, sidx = self._lin_point(tr, k, x, N, S, V, U)
            for c in sidx:
                rows.add([c, slack("switch_speed")], [-1.0, 1.0], -lim, inf)
            # trust region: the linearised passage time stays within trust_s of the iterate's
            g = slack("trust")
            rows.add(cols + [g], vals + [1.0], tau - qp.trust_s - const, inf)
            rows.add(cols + [g], [-c for c in vals] + [1.0], -tau - qp.trust_s + const, inf)
        # Eq. 39: switch intervals between consecutive trains, and the switch's own state
        for a, xa, b, xb, need in self.switch_pairs:
            ca, va, consta, _, _ = self._lin_point(tr, a, xa, N, S, V, U)
            cb, vb, constb, _, _ = self._lin_point(tr, b, xb, N, S, V, U)
            rows.add(cb + ca + [slack("switch_headway")], vb + [-c for c in va] + [1.0], need - constb + consta, inf)
        for k, x, ready in self.switch_first:
            c, vals, const, _, _ = self._lin_point(tr, k, x, N, S, V, U)
            rows.add(c + [slack("switch_state")], vals + [1.0], ready - const, inf)  # type: ignore[operator]  # `c` is an int earlier in this function
        # the guard's relative braking distance on shared track (linearised at the iterate)
        T, b = p.rbd_reaction_s, p.rbd_decel_mps2
        if T > 0.0:
            for lead, fol, x_common in self.shared:
                i_start = min(int(_passage_time(tr, lead, x_common, dt) // dt), N)
                i = np.arange(i_start, N + 1)
                if i.size == 0:
                    continue
                vf, vl = tr.v[fol, i], tr.v[lead, i]
                af = np.append(tr.u[fol, i[i < N]], np.zeros(int(np.sum(i == N))))
                w = vf + af * T
                need = T * vf + 0.5 * af * T * T + w * w / (2.0 * b) - vl * vl / (2.0 * b) + p.rbd_margin_m
                d_vf = T + w / b
                d_af = 0.5 * T * T + T * w / b
                d_vl = -vl / b
                # s_l − d_l − s_f + d_f − L − [need + d_vf(v_f − v̄_f) + d_af(u_f − ū_f) + d_vl(v_l − v̄_l)] + σ ≥ extra
                lo = (
                    qp.rbd_margin_m
                    + p.pred_length_m
                    + self.d_m[lead]
                    - self.d_m[fol]
                    + need
                    - d_vf * vf
                    - d_af * af
                    - d_vl * vl
                )
                u_cols = np.where(i < N, U[fol, np.minimum(i, N - 1)], S[fol, i])  # placeholder where no u
                u_vals = np.where(i < N, -d_af, 0.0)
                g = slack("relative_braking")
                rows.add_block(
                    np.stack([S[lead, i], S[fol, i], V[fol, i], V[lead, i], u_cols, np.full(i.size, g)], axis=1),
                    np.stack([np.ones(i.size), -np.ones(i.size), -d_vf, -d_vl, u_vals, np.ones(i.size)], axis=1),
                    lo,
                    np.full(i.size, inf),
                )
        # Eqs. 2-3 at the coupling instant N; the leader is not yet past F
        lead0 = self.order[0]
        rows.add([S[lead0, N], slack("coupling_gap")], [-1.0, 1.0], -self.d_F[lead0], inf)
        tol_v, tol_d = qp.coupling_speed_tol_mps, qp.coupling_gap_tol_m
        for a, f in zip(self.order, self.order[1:]):
            g = slack("coupling_speed")
            rows.add([V[a, N], V[f, N], g], [1.0, -1.0, 1.0], -tol_v, inf)
            rows.add([V[a, N], V[f, N], g], [-1.0, 1.0, 1.0], -tol_v, inf)
            # D − S_m = (s_a − d_a) − (s_f − d_f) − margin0 − slope·(v_f − v_a)
            g = slack("coupling_gap")
            base = self.d_m[a] - self.d_m[f] + self.margin0_m
            cols = [S[a, N], S[f, N], V[f, N], V[a, N], g]
            rows.add(cols, [1.0, -1.0, -self.margin_slope_s, self.margin_slope_s, 1.0], base - tol_d, inf)
            rows.add(cols, [-1.0, 1.0, self.margin_slope_s, -self.margin_slope_s, 1.0], -base - tol_d, inf)
        n_var = n_state + len(groups)
        for gi in range(len(groups)):
            rows.add([n_state + gi], [1.0], 0.0, inf)
        A, lo, hi = rows.matrix(n_var)
        # objective: f_c model (linearised T_c, 2nd-order Γ2) + smoothness + slack prices
        Pd = np.zeros(n_var)
        q = np.zeros(n_var)
        off_r: list[int] = []
        off_c: list[int] = []
        off_v: list[float] = []
        for k in range(n):
            Pd[U[k]] += 2.0 * qp.accel_weight * dt
            if N > 1:
                Pd[U[k, 1:]] += 2.0 * qp.smooth_weight
                Pd[U[k, :-1]] += 2.0 * qp.smooth_weight
                off_r += U[k, :-1].tolist()
                off_c += U[k, 1:].tolist()
                off_v += [-2.0 * qp.smooth_weight] * (N - 1)
        c2 = p.weight_speed * 2.0 * p.braking_distance_m
        for k in range(n):
            vb = max(tr.v[k, N] - p.speed_error_mps, 0.3)
            g1, g2 = -c2 / vb**2, 2.0 * c2 / vb**3  # type: ignore[operator]  # vb is a float here
            Pd[V[k, N]] += g2
            q[V[k, N]] += g1 - g2 * tr.v[k, N]
        vl = max(tr.v[lead0, N], 0.3)
        wt = n * p.weight_time
        q[S[lead0, N]] += -wt / vl
        q[V[lead0, N]] += -wt * (self.d_F[lead0] - tr.s[lead0, N]) / vl**2
        q[n_state:] = qp.slack_weight
        mu = 2.0 * qp.proximal_weight
        Pd[V.ravel()] += mu
        q[V.ravel()] -= mu * tr.v.ravel()
        P = sp.csc_matrix(
            (
                np.concatenate([Pd, off_v]),
                (np.concatenate([np.arange(n_var), off_r]), np.concatenate([np.arange(n_var), off_c])),
            ),
            shape=(n_var, n_var),
        )
        solver = osqp.OSQP()
        solver.setup(
            P,
            q,
            A,
            lo,
            hi,
            verbose=False,
            eps_abs=qp.osqp_eps,
            eps_rel=qp.osqp_eps,
            max_iter=4000,
            polishing=True,
            scaling=10,
        )
        z = np.empty(n_var)
        z[S.ravel()] = tr.s.ravel()
        z[V.ravel()] = tr.v.ravel()
        z[U.ravel()] = tr.u.ravel()
        z[n_state:] = 0.0
        solver.warm_start(x=z)
        res = solver.solve(raise_error=False)
        if res.x is None or not np.all(np.isfinite(res.x)):
            return tr, math.inf, math.inf
        zx = res.x
        new = _Traj(zx[S], zx[V], np.clip(zx[U], p.accel_min_mps2, p.accel_max_mps2))
        real = [n_state + gi for name, gi in groups.items() if name != "trust"]
        total_slack = float(np.sum(np.maximum(zx[real], 0.0)))
        v_c = float(np.mean(new.v[:, N]))
        T_c = N * dt + max(self.d_F[lead0] - new.s[lead0, N], 0.0) / max(new.v[lead0, N], 0.1)
        model_cost = n * p.weight_time * T_c + sum(c2 / max(new.v[k, N] - p.speed_error_mps, 0.1) for k in range(n))
        del v_c
        return new, total_slack, model_cost

    def passages(self, tr: _Traj) -> np.ndarray:
        dt = self.qp.step_s
        pts = [x for _, x, _ in self.speed_points]
        ks = [k for k, _, _ in self.speed_points]
        return np.array([_passage_time(tr, k, x, dt) for k, x in zip(ks, pts)])

    def scp(self, tr: _Traj) -> tuple[_Traj, float, bool, int]:
        """Re-linearise and solve until the passage times settle.

        Returns (trajectory, total slack of the last QP, converged, QP solves)."""
        before = self.passages(tr)
        slack, solves, converged = math.inf, 0, False
        for _ in range(self.qp.scp_iterations):
            tr, slack, _cost = self.solve(tr)
            solves += 1
            if not math.isfinite(slack):
                break
            after = self.passages(tr)
            converged = bool(np.max(np.abs(after - before)) < self.qp.converge_s)
            if converged:
                break
            before = after
        return tr, slack, converged, solves


def profile_from_trajectory(problem: Problem, tr: _Traj, dt: float) -> np.ndarray:
    """Distance-segment accelerations through the trajectory's speeds at every breakpoint (exact in speed there).

    Beyond the grid's end the trains hold their last speed (the coupled running after the coupling instant).
    """
    x = np.empty(problem.dimension)
    v_min = problem.params.min_speed_mps
    for k in range(problem.n_trains):
        nk = int(problem.n_segments[k])
        bp = problem.breakpoints_m[k, : nk + 1]
        s, v, u = tr.s[k], tr.v[k], tr.u[k]
        N = tr.steps
        i = np.clip(np.searchsorted(s, bp, side="right") - 1, 0, N - 1)
        d = bp - s[i]
        v2 = np.where(bp > s[N], v[N] ** 2, v[i] ** 2 + 2.0 * u[i] * d)
        v2[0] = problem.trains[k].initial_speed_mps ** 2
        v2 = np.maximum(v2, v_min**2)
        acc = np.diff(v2) / (2.0 * np.diff(bp))
        x[problem.dim_slices[k]] = np.clip(acc, *problem.bounds)
    return x


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
    legs = {k: next(s.leg for s in problem.trains[k].switches if s.switch_id == ms) for k in order}
    t = earliest[order[0]]
    for a, b in zip(order, order[1:]):
        need = p.throw_time_s if (legs[a] != legs[b] or p.headway_all_consecutive) else p.min_time_gap_s
        t = max(earliest[b], t + need)
    last = order[-1]
    run = problem.trains[last].distance_to_F_m - problem.merge_distance_m[last]
    slot = (len(order) - 1) * float(safety_margin_m(p.line_speed_mps, p.line_speed_mps, p))
    t_c = t + max(run - slot, 0.0) / p.line_speed_mps
    n = problem.n_trains
    return n * p.weight_time * t_c + n * p.weight_speed * 2.0 * p.braking_distance_m / (
        p.line_speed_mps - p.speed_error_mps
    )


def _timetable_iterate(problem: Problem, order: tuple[int, ...], dt: float) -> tuple[_Traj, int]:
    """First linearisation point for ``order`` and a coupling-instant guess.

    A timetable: each train's nominal merge time at its present speed (capped at its lowest switch limit), pushed
    later along the order by the switch intervals; each train then changes speed (at 80 % of its bounds) to the
    constant speed that meets its merge time and holds it. The guess is the last train's merge time plus its run
    to F at that speed.
    """
    p = problem.params
    n = problem.n_trains
    ms = problem.merge_switch_id
    cap = [min(p.limit_speed_mps(s.leg) for s in tr.switches) for tr in problem.trains]
    legs = {k: next(s.leg for s in problem.trains[k].switches if s.switch_id == ms) for k in order}
    t_m: dict[int, float] = {}
    prev = None
    for k in order:
        tr = problem.trains[k]
        v0, a_up = tr.initial_speed_mps, 0.5 * p.accel_max_mps2
        v_run = max(min(cap[k], math.sqrt(v0 * v0 + 2.0 * a_up * problem.merge_distance_m[k])), v0)
        t = (v_run - v0) / a_up + (problem.merge_distance_m[k] - (v_run**2 - v0**2) / (2.0 * a_up)) / v_run
        if prev is not None:
            need = p.throw_time_s if (legs[prev] != legs[k] or p.headway_all_consecutive) else 2.0 * p.min_time_gap_s
            t = max(t, t_m[prev] + need + 1.0)
        t_m[k] = t
        prev = k
    last = order[-1]
    v_last = max(min(problem.merge_distance_m[last] / t_m[last], cap[last]), 1.0)
    N = max(
        int(
            math.ceil(
                (t_m[last] + (problem.trains[last].distance_to_F_m - problem.merge_distance_m[last]) / v_last) / dt
            )
        ),
        2,
    )
    v = np.empty((n, N + 1))
    u = np.zeros((n, N))
    for k, tr in enumerate(problem.trains):
        target = float(np.clip(problem.merge_distance_m[k] / t_m[k], 1.0, cap[k]))
        vk = tr.initial_speed_mps
        v[k, 0] = vk
        for i in range(N):
            a = float(np.clip((target - vk) / dt, 0.8 * p.accel_min_mps2, 0.8 * p.accel_max_mps2))
            u[k, i] = a
            vk += a * dt
            v[k, i + 1] = vk
    s = np.concatenate([np.zeros((n, 1)), np.cumsum(v[:, :-1] * dt + 0.5 * u * dt * dt, axis=1)], axis=1)
    return _Traj(s, v, u), N


def _solve_order(
    problem: Problem, order: tuple[int, ...], qp: QpOrderParams, warm: _Traj | None, guess: int | None
) -> tuple[_Traj, int, bool, int]:
    """Coupling-instant search for one order (module docstring).

    Returns (last trajectory — the best feasible one if any, N, whether it is QP-feasible and converged, solves).
    """
    oq = _OrderQP(problem, order, qp)
    dt = qp.step_s
    n_max = int(qp.max_horizon_s / dt)
    if warm is not None and guess is not None:
        base, N = warm, guess
    else:
        base, N = _timetable_iterate(problem, order, dt)
    N = min(N, n_max)
    solves = 0
    best: tuple[_Traj, int] | None = None
    last = (base, N)
    tried_lower, lowered = False, 0
    for _ in range(qp.max_probes):
        tr, slack, converged, k = oq.scp(_resample(base, N, dt))
        solves += k
        last = (tr, N)
        if slack <= qp.feasibility_tol and converged:
            best = (tr, N)
            base = tr
            lead = order[0]
            remaining_s = (oq.d_F[lead] - tr.s[lead, N]) / max(tr.v[lead, N], 0.1)
            jump = int(remaining_s // dt)
            if jump >= 1 and N + jump <= n_max and not tried_lower:
                N += jump
                continue
            # the leader is at F at the coupling instant: try an earlier one (a shorter T_c) while that is feasible
            if lowered >= qp.lower_probes:
                break
            lowered += 1
            tried_lower = True
            N = max(N - max(2, int(0.1 * N)), 2)
        else:
            if tried_lower or N >= n_max:
                break
            base = tr if math.isfinite(slack) else base
            N = min(max(N + 2, int(math.ceil(N * 1.2))), n_max)
    if best is None:
        return last[0], last[1], False, solves
    return best[0], best[1], True, solves


def solve_qp_order(
    problem: Problem, params: QpOrderParams | None = None, warm_x: np.ndarray | None = None
) -> QpOrderResult:
    """Enumerate the passing orders, solve each by SCP over OSQP QPs, verify with the rollout, keep the best.

    ``warm_x`` (distance encoding, e.g. the previous plan shifted by :func:`.planner._warm_start`) is tried first:
    its order leads the enumeration and its trajectory is the first linearisation point and coupling-instant
    guess. ``problem.frozen_order`` restricts the enumeration to that order (a re-plan past the point of no
    return).
    """
    qp = params or QpOrderParams()
    t0 = time.perf_counter()
    n = problem.n_trains
    dt = qp.step_s
    warm_tr: _Traj | None = None
    warm_order: tuple[int, ...] | None = None
    guess: int | None = None
    if warm_x is not None:
        r = rollout(problem, warm_x[None, :])
        if np.isfinite(r.coupling_time_s[0]):
            warm_order = tuple(int(k) for k in r.order[0])
            guess = max(int(round(r.coupling_time_s[0] / dt)), 2)
            warm_tr = trajectory_from_profile(problem, warm_x, guess, dt)
    if problem.frozen_order is not None:
        orders = [tuple(problem.frozen_order)]
    else:
        orders = sorted(itertools.permutations(range(n)), key=lambda o: (order_lower_bound(problem, o), o))
        if warm_order is not None and warm_order in orders:
            orders.remove(warm_order)
            orders.insert(0, warm_order)
    best: tuple[float, float, np.ndarray, tuple[int, ...], int] | None = None  # (violation, cost, x, order, N)
    solves = solved = 0
    for order in orders:
        if best is not None and best[0] <= 0.0 and order_lower_bound(problem, order) >= best[1]:
            continue
        use_warm = warm_tr if order == warm_order or problem.frozen_order is not None else None
        tr, N, _ok, k = _solve_order(problem, order, qp, use_warm, guess if use_warm is not None else None)
        solves += k
        solved += 1
        x = profile_from_trajectory(problem, tr, dt)
        r = rollout(problem, x[None, :])
        viol, cost = float(r.violation[0]), float(r.cost[0])
        if tuple(int(k) for k in r.order[0]) != order and problem.frozen_order is None:
            viol = max(viol, 1e-9)  # the plan does not realise the order it was built for
        key = (viol, cost)
        if (
            best is None
            or (key[0] <= 0.0 and (best[0] > 0.0 or key[1] < best[1]))
            or (best[0] > 0.0 and key[0] < best[0])
        ):
            best = (viol, cost, x, order, N)
    assert best is not None
    viol, cost, x, order, N = best
    return QpOrderResult(
        x=x,
        order=order,
        cost=cost,
        violation=viol,
        feasible=viol <= 0.0,
        iterations=solves,
        orders_solved=solved,
        wall_time_s=time.perf_counter() - t0,
        coupling_step=N,
    )
