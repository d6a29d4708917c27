"""The DMPC baseline of Paper A (Section IV-D, "fmincon" in the paper) as a sparse OSQP quadratic program.

Decision variables are the continuous controls ``u_0 … u_{Np−1}`` plus the predicted states ``v_1 … v_Np``,
``s_1 … s_Np`` (sparse, "uncondensed" form: the dynamics are equality rows, so the KKT matrix stays banded and a
refactorisation costs a few tens of microseconds). Positions are relative to the own front at ``t_k``.

The problem Eq. (14)–(20) is not a QP: the resistance ω(v) in Eq. (2) and the v² terms of D^(e)/D^(s) are
nonlinear. Reading used here (A21/A37: the paper's NLP solver replaced by sequential quadratic programming in the
real-time-iteration style): linearise around a *nominal* trajectory — the previous solution shifted by one step,
simulated with the nonlinear model from the current state — and solve the QP

* dynamics: ``v_{j+1} = v_j + τ(u_j − ω̄_j − ω'_j(v_j − v̄_j))``, ``s_{j+1} = s_j + τv_j + τ²/2(u_j − ω̄_j − ω'_j(v_j − v̄_j))``;
* cost: Eq. (14)–(18) exactly as in :mod:`controllers.mcf_dmpc.cost` with ``D^(e)(v) ≈ D^(e)(v̄) + (v̄/|b^(c)|)(v − v̄)``;
* constraints (20) as hard constraints: ``−b^(c) ≤ u ≤ a^(m)``, ``0 ≤ v ≤ v_m`` and the safe spacing
  ``ΔS_j ≥ D^(s)_j`` with ``v_j² ≈ 2v̄_j·v_j − v̄_j²``.

Honesty about the safe-spacing linearisation: ``D^(s)`` is convex in ``v`` and its tangent lies *below* it, so the
linearised constraint is slightly optimistic, by exactly ``(v_j − v̄_j)²/(2|b^(m)|)`` (1 m for a 1.4 m/s deviation
from the nominal). The controller therefore re-simulates the QP solution with the nonlinear model, re-linearises
around it and solves again (up to ``sqp_iterations``) while the linearisation error ``max (v − v̄)²/(2|b^(c)|)`` of
the solution exceeds ``sqp_tol_m`` (0.1 m by default, i.e. |v − v̄| > 0.4 m/s); the
true margin ``min(ΔS − D^(s))`` of the returned plan is reported as ``safety_margin_m`` so a violation is visible,
never hidden. The cost reported (``J``) is the true Eq. (19) on the nonlinear re-simulation.

Warm start: the primal point is the nominal trajectory (feasible for the linearised dynamics), the dual variables
are kept from the previous solve (OSQP ``warm_starting``). Failure (infeasible, max-iterations, non-finite) →
the caller brakes at service rate and counts a fallback.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import osqp
from scipy import sparse

from controllers.mcf_dmpc.cost import TABLE_II, CostWeights, cost_terms
from controllers.mcf_dmpc.rollout import PredecessorHorizon, Trajectory, rollout_controls
from controllers.mcf_dmpc.spacing import TrainParamsA, safe_spacing_m

__all__ = ["DmpcQp", "DmpcSolution", "shift_controls"]

_OK = {osqp.SolverStatus.OSQP_SOLVED, osqp.SolverStatus.OSQP_SOLVED_INACCURATE}


@dataclass(frozen=True)
class DmpcSolution:
    """One DMPC solve: ``ok`` False means the caller must fall back (``status`` says why)."""

    ok: bool
    u: np.ndarray  # (Np,) controls, clipped to the bounds
    trajectory: Trajectory  # nonlinear re-simulation of u (one row)
    J: float
    safety_margin_m: float  # min_j (ΔS_j − D^(s)_j) on the nonlinear trajectory
    status: str
    sqp_iterations: int
    admm_iterations: int
    solve_time_s: float


def shift_controls(u: np.ndarray) -> np.ndarray:
    """Receding-horizon warm start: drop ``u_0``, repeat the last control."""
    return np.append(u[1:], u[-1])


class DmpcQp:
    """The OSQP problem for one follower; keeps the solver (and its factorisation pattern) across steps."""

    def __init__(
        self,
        horizon_steps: int,
        train: TrainParamsA,
        weights: CostWeights = TABLE_II,
        *,
        eps_abs: float = 1e-5,
        eps_rel: float = 1e-5,
        max_iter: int = 4000,
        sqp_iterations: int = 2,
        sqp_tol_m: float = 0.1,
        polish: bool = False,
    ) -> None:
        if horizon_steps < 1:
            raise ValueError(f"horizon_steps: expected an integer >= 1, got {horizon_steps!r}")
        if sqp_iterations < 1:
            raise ValueError(f"sqp_iterations: expected an integer >= 1, got {sqp_iterations!r}")
        self.n_steps = int(horizon_steps)
        self.train = train
        self.weights = weights
        self.settings = dict(
            eps_abs=eps_abs,
            eps_rel=eps_rel,
            max_iter=int(max_iter),
            polishing=polish,
            verbose=False,
            warm_starting=True,
        )
        self.sqp_iterations = int(sqp_iterations)
        self.sqp_tol = float(sqp_tol_m)
        self._solver: osqp.OSQP | None = None
        self._build_pattern()

    # ------------------------------------------------------------------ sparsity patterns (fixed for all steps)
    def _build_pattern(self) -> None:
        n = self.n_steps
        iu, iv, is_ = np.arange(n), n + np.arange(n), 2 * n + np.arange(n)  # u_j, v_{j+1}, s_{j+1}
        j1 = np.arange(1, n)
        rows = [
            np.arange(n),
            j1,
            np.arange(n),  # v-dynamics rows: v_{j+1}, v_j (j≥1), u_j
            n + np.arange(n),
            n + j1,
            n + j1,
            n + np.arange(n),  # s-dynamics: s_{j+1}, s_j, v_j (j≥1), u_j
            2 * n + np.arange(n),
            3 * n + np.arange(n),  # bounds on u, on v
            4 * n + np.arange(n),
            4 * n + np.arange(n),
        ]  # safety: s_{j+1}, v_{j+1}
        cols = [iv, iv[:-1], iu, is_, is_[:-1], iv[:-1], iu, iu, iv, is_, iv]
        self._a_rows, self._a_cols = np.concatenate(rows), np.concatenate(cols)
        p_rows = [iu, iu[:-1], iv, is_, iv]  # u diag, u super-diag, v diag, s diag, v-s cross (upper)
        p_cols = [iu, iu[1:], iv, is_, is_]
        self._p_rows, self._p_cols = np.concatenate(p_rows), np.concatenate(p_cols)
        self._a_perm, self._a_shape = _csc_order(self._a_rows, self._a_cols, (5 * n, 3 * n))
        self._p_perm, self._p_shape = _csc_order(self._p_rows, self._p_cols, (3 * n, 3 * n))

    # ------------------------------------------------------------------ one linearised QP
    def _qp_data(
        self, v0: float, u_prev: float, pred: PredecessorHorizon, sp_rel: np.ndarray, nominal: Trajectory
    ) -> tuple[np.ndarray, ...]:
        n, tr, w = self.n_steps, self.train, self.weights
        tau = tr.dt_s
        vbar = nominal.v[0]  # (n+1,)
        omega = tr.resistance_mps2(vbar[:-1])
        slope = tr.resistance_slope_per_s(vbar[:-1])
        a_coef = 1.0 - tau * slope
        b_coef = tau - 0.5 * tau * tau * slope
        c = -tau * (omega - slope * vbar[:-1])
        d = -0.5 * tau * tau * (omega - slope * vbar[:-1])
        a_vals = np.concatenate(
            [
                np.ones(n),
                -a_coef[1:],
                np.full(n, -tau),
                np.ones(n),
                -np.ones(n - 1),
                -b_coef[1:],
                np.full(n, -0.5 * tau * tau),
                np.ones(n),
                np.ones(n),
                np.ones(n),
                vbar[1:] / tr.emergency_decel_mps2,
            ]
        )
        eq_v = c.copy()
        eq_v[0] += a_coef[0] * v0
        eq_s = d.copy()
        eq_s[0] += b_coef[0] * v0
        vp = pred.speed_mps[1:]
        lp, bp = pred.length_m, pred.emergency_decel_mps2
        safety_ub = (
            sp_rel[1:]
            - tr.safety_margin_m
            - lp
            + vp * vp / (2.0 * bp)
            + vbar[1:] ** 2 / (2.0 * tr.emergency_decel_mps2)
        )
        inf = np.full(n, np.inf)
        lower = np.concatenate([eq_v, eq_s, np.full(n, -tr.service_decel_mps2), np.zeros(n), -inf])
        upper = np.concatenate([eq_v, eq_s, np.full(n, tr.max_accel_mps2), np.full(n, tr.max_speed_mps), safety_ub])
        # cost
        w_v = np.full(n, w.xi_v)
        w_s = np.full(n, w.xi_s)
        w_v[-1] *= 1.0 + w.xi_term
        w_s[-1] *= 1.0 + w.xi_term
        g = vbar[1:] / tr.service_decel_mps2
        de_bar = tr.safety_margin_m + lp + vbar[1:] ** 2 / (2.0 * tr.service_decel_mps2) - vp * vp / (2.0 * bp)
        r = sp_rel[1:] - de_bar + g * vbar[1:]
        count = np.full(n, 2.0)
        count[-1] = 1.0  # u_{Np−1} only appears in one increment (or, for Np = 1, in the u_{−1} term)
        p_vals = np.concatenate(
            [
                2.0 * (w.xi_u + w.xi_du * count),
                np.full(n - 1, -2.0 * w.xi_du),
                2.0 * (w_v + w_s * g * g),
                2.0 * w_s,
                2.0 * w_s * g,
            ]
        )
        q = np.concatenate([np.zeros(n), -2.0 * w_v * vp - 2.0 * w_s * r * g, -2.0 * w_s * r])
        q[0] -= 2.0 * w.xi_du * u_prev
        return p_vals[self._p_perm], q, a_vals[self._a_perm], lower, upper

    def solve(
        self,
        x0_m: float,
        v0_mps: float,
        u_prev_mps2: float,
        pred: PredecessorHorizon,
        nominal_u: np.ndarray | None = None,
    ) -> DmpcSolution:
        """Solve at state ``(x0, v0)``; ``nominal_u`` is the linearisation point (default: cruise at ω(v0))."""
        t0 = time.perf_counter()
        n, tr = self.n_steps, self.train
        if pred.steps != n:
            raise ValueError(f"predecessor horizon has {pred.steps} steps, expected {n}")
        sp_rel = pred.position_m - x0_m
        if nominal_u is None:
            nominal_u = np.full(n, float(tr.resistance_mps2(v0_mps)))
        u_nom = np.clip(np.asarray(nominal_u, dtype=float), -tr.service_decel_mps2, tr.max_accel_mps2)
        status, admm, it = "unsolved", 0, 0
        u_sol = u_nom
        ok = False
        for _it in range(1, self.sqp_iterations + 1):
            nominal = rollout_controls(u_nom, 0.0, v0_mps, tr)
            px, q, ax, lo, hi = self._qp_data(v0_mps, u_prev_mps2, pred, sp_rel, nominal)
            if self._solver is None:
                self._solver = osqp.OSQP()
                self._solver.setup(
                    _csc(px, self._p_perm, self._p_rows, self._p_cols, self._p_shape),
                    q,
                    _csc(ax, self._a_perm, self._a_rows, self._a_cols, self._a_shape),
                    lo,
                    hi,
                    **self.settings,
                )
            else:
                self._solver.update(Px=px, Ax=ax, q=q, l=lo, u=hi)
            self._solver.warm_start(x=np.concatenate([u_nom, nominal.v[0, 1:], nominal.s[0, 1:]]))
            res = self._solver.solve(raise_error=False)  # status handled below (fallback)
            admm += int(res.info.iter)
            status = str(res.info.status)
            ok = res.info.status_val in {int(s) for s in _OK} and bool(np.all(np.isfinite(res.x[:n])))
            if not ok:
                break
            u_sol = np.clip(res.x[:n], -tr.service_decel_mps2, tr.max_accel_mps2)
            # Linearisation error of the solution: D^(e)/D^(s) are off by (v − v̄)²/(2b) metres (the dynamics
            # error c2·(v − v̄)² is ~1e5 times smaller). Re-linearise only if that matters.
            v_sol = rollout_controls(u_sol, 0.0, v0_mps, tr).v[0]
            lin_error_m = float(np.max((v_sol - nominal.v[0]) ** 2)) / (2.0 * tr.service_decel_mps2)
            u_nom = u_sol
            if lin_error_m <= self.sqp_tol:
                break
        traj = rollout_controls(u_sol, x0_m, v0_mps, tr)
        terms = cost_terms(traj, pred, u_prev_mps2, tr, self.weights)
        ds = safe_spacing_m(traj.v[0, 1:], pred.speed_mps[1:], tr, pred.length_m, pred.emergency_decel_mps2)
        margin = float(np.min(pred.position_m[1:] - traj.s[0, 1:] - ds))
        return DmpcSolution(ok, u_sol, traj, float(terms["J"][0]), margin, status, it, admm, time.perf_counter() - t0)

    def reset(self) -> None:
        """Drop the solver (next solve sets it up again, cold)."""
        self._solver = None


def _csc_order(rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, tuple[int, int]]:
    """Permutation from our entry order to OSQP's CSC data order (so values can be updated in place)."""
    marker = sparse.csc_matrix((np.arange(1, len(rows) + 1, dtype=float), (rows, cols)), shape=shape)
    marker.sort_indices()
    if marker.nnz != len(rows):
        raise RuntimeError("duplicate entries in a QP sparsity pattern")
    return marker.data.astype(np.int64) - 1, shape


def _csc(
    data_sorted: np.ndarray, perm: np.ndarray, rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int]
) -> sparse.csc_matrix:
    """A CSC matrix with our fixed pattern and ``data_sorted`` (already in CSC order); zeros stay explicit."""
    marker = sparse.csc_matrix((np.arange(1, len(rows) + 1, dtype=float), (rows, cols)), shape=shape)
    marker.sort_indices()
    marker.data = np.asarray(data_sorted, dtype=float).copy()
    return marker
