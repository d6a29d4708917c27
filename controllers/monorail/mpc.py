"""The gap-tracking QP shared by the coupling DMPC (Paper D §3.7) and the collision-avoidance MPC (§3.8).

Both controllers solve, at every sampling instant, the reconstructed Eq. (21) for one vehicle and the object
ahead of it (its predecessor or an obstacle), whose predicted trajectory is given::

    min_U  Σ_{k=1..Np} q_g·(g_k − d_ref)² + q_v·(v_ahead,k − v_k)² + ρ·s_k² + ρ₁·s_k
         + Σ_{j=0..Nc−1} r·u_j² + r_Δ·(u_j − u_{j−1})²
    s.t.   own x, v from Eq. (17) with the response lag (vehicle_model.lag_prediction_matrices)
           −a_eb,max ≤ u_j ≤ a_t,max                                     (Eq. 18)
           g_k + s_k ≥ s_min,  s_k ≥ 0                                    (Eq. 20, softened)

The gap constraint is soft (slack ``s`` with a heavy quadratic and linear price) so the QP is always feasible:
an emergency can start inside the constraint. The speed bound ``v ≥ 0`` (Eq. 19) is left to the plant, which
stands rather than reverses. Hessian and constraint matrix depend only on (T, t_r, η, Np, Nc, weights), so OSQP
is set up once and only the vectors are updated afterwards (warm-started).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import osqp
from scipy import sparse

from railsim.physics.monorail import lag_prediction_matrices

_OK = {"solved", "solved inaccurate"}


@dataclass(frozen=True)
class QpWeights:
    q_gap: float = 1.0
    q_speed: float = 1.0
    r_u: float = 0.5
    r_du: float = 1.0
    slack_quadratic: float = 1e4
    slack_linear: float = 1e3


class GapTrackingQp:
    """One vehicle's QP; :meth:`solve` returns the optimal command sequence or ``None`` if OSQP failed."""

    def __init__(
        self, dt_s: float, response_s: float, efficiency: float, horizon: int, control_horizon: int, weights: QpWeights
    ) -> None:
        self.n, self.m = horizon, control_horizon
        self.w = weights
        self.px, self.gx, self.pv, self.gv = lag_prediction_matrices(
            dt_s, response_s, efficiency, horizon, control_horizon
        )
        n, m, w = self.n, self.m, weights
        diff = np.eye(m) - np.eye(m, k=-1)
        h_u = 2.0 * (
            w.q_gap * self.gx.T @ self.gx + w.q_speed * self.gv.T @ self.gv + w.r_u * np.eye(m) + w.r_du * diff.T @ diff
        )
        self._diff = diff
        p_mat = sparse.block_diag([sparse.csc_matrix(h_u), sparse.eye(n) * 2.0 * w.slack_quadratic], format="csc")
        a_mat = sparse.vstack(
            [
                sparse.hstack([sparse.csc_matrix(-self.gx), sparse.eye(n)]),
                sparse.hstack([sparse.eye(m), sparse.csc_matrix((m, n))]),
                sparse.hstack([sparse.csc_matrix((n, m)), sparse.eye(n)]),
            ],
            format="csc",
        )
        self._p, self._a = sparse.triu(p_mat, format="csc"), a_mat
        self._solver: osqp.OSQP | None = None

    def solve(
        self,
        gap0_m: float,
        v0_mps: float,
        a0_mps2: float,
        ahead_dx_m: np.ndarray,
        ahead_v_mps: np.ndarray,
        d_ref_m: float,
        s_min_m: float,
        u_prev_mps2: float,
        u_min_mps2: float,
        u_max_mps2: float,
        offset_mps2: float = 0.0,
    ) -> np.ndarray | None:
        """``ahead_dx_m[k]``/``ahead_v_mps[k]``: the object's displacement from now and speed at steps 1..Np.

        ``offset_mps2``: a command applied on top of the decision over the whole horizon (another role's service
        braking when the decision is an additive increment, A27): the vehicle is predicted under
        ``offset + u_j``, while the weights, ``u_prev`` and the bounds ``[u_min, u_max]`` are on ``u`` alone.
        """
        n, m, w = self.n, self.m, self.w
        s0 = np.array([0.0, v0_mps, a0_mps2])
        c_gap = gap0_m + np.asarray(ahead_dx_m, float) - self.px @ s0 - offset_mps2 * self.gx.sum(axis=1)
        c_v = np.asarray(ahead_v_mps, float) - self.pv @ s0 - offset_mps2 * self.gv.sum(axis=1)
        e1 = np.zeros(m)
        e1[0] = u_prev_mps2
        q_u = (
            -2.0 * w.q_gap * self.gx.T @ (c_gap - d_ref_m)
            - 2.0 * w.q_speed * self.gv.T @ c_v
            - 2.0 * w.r_du * self._diff.T @ e1
        )
        q = np.concatenate([q_u, np.full(n, w.slack_linear)])
        lo = np.concatenate([s_min_m - c_gap, np.full(m, u_min_mps2), np.zeros(n)])
        hi = np.concatenate([np.full(n, np.inf), np.full(m, u_max_mps2), np.full(n, np.inf)])
        if self._solver is None:
            self._solver = osqp.OSQP()
            self._solver.setup(
                self._p, q, self._a, lo, hi, verbose=False, eps_abs=1e-5, eps_rel=1e-5, max_iter=4000, polishing=True
            )
        else:
            self._solver.update(q=q, l=lo, u=hi)
        res = self._solver.solve(raise_error=False)
        if str(res.info.status).lower() not in _OK or res.x is None or not np.all(np.isfinite(res.x[:m])):
            return None
        return np.clip(res.x[:m], u_min_mps2, u_max_mps2)


def predict_ahead(v_mps: float, a_mps2: float, dt_s: float, horizon: int) -> tuple[np.ndarray, np.ndarray]:
    """Displacement and speed of an object ahead at steps 1..N under constant acceleration, stopping at v = 0."""
    t = dt_s * np.arange(1, horizon + 1)
    if a_mps2 < 0.0 and v_mps > 0.0:
        t_stop = v_mps / -a_mps2
        tc = np.minimum(t, t_stop)
        return v_mps * tc + 0.5 * a_mps2 * tc * tc, np.maximum(v_mps + a_mps2 * t, 0.0)
    v = max(v_mps, 0.0)
    return v * t + 0.5 * a_mps2 * t * t, v + a_mps2 * t
