"""The condensed MPC quadratic programme over force increments, solved with OSQP (spec §2.13, §7).

One class, :class:`CondensedMpc`, serves SEMPC and both MPC baselines:

* decision ``ΔU = [Δu(k); …; Δu(k+N_c−1)]`` (n per step) plus slacks ``s ≥ 0`` for the soft state rows;
* cost ``Σ_{i=1}^{N_p} ‖ξ(k+i) − ξ_ref(k+i)‖²_{Q̄_i} + ‖ΔU‖²_{R̄}`` with ``Q̄ = blkdiag(I_{N_p−1}⊗Q_ξ, P_term)``
  (A7 default: the terminal weight replaces the last stage weight; MPC-A uses ``P_term = Q_ξ``),
  ``+ ρ₁·1ᵀs + ρ₂·‖s‖²``;
* ``H = 2(GᵀQ̄G + R̄)``, ``g = 2GᵀQ̄(Fξ + D − Ref)`` (Eq. (21) with the spec's errata fixed);
* soft rows ``Xmin ≤ Z_N(Fξ + GΔU + D) ≤ Xmax`` on ``x_1 ∈ [0, x_max]``, ``x_{i,i−1} ∈ −l_d ± l_safe`` and
  ``v_1 ∈ [0, v_max]`` (A4, A21), hard rows ``u_min ≤ u(k−1) + LΔU ≤ u_max`` and
  ``Δu_min·T ≤ ΔU ≤ Δu_max·T`` (rates in N/s times the period, A5).

MPC-B (u as the decision variable, no rate limits, a small penalty ``r_u‖U‖²``) is the same programme in
disguise: ``U = 1⊗u(k−1) + LΔU`` is a bijection, so we keep ΔU as the variable, replace ``R̄`` by ``r_u·LᵀL``
(plus the matching linear term) and drop the Δu rows.

Numerics (spec §7.3, found in the spec's prototype and confirmed here): the weights span 10⁻⁸…10¹², the common
mode of ΔU (uniform acceleration) has tiny curvature and the differential modes enormous curvature. We therefore
solve in scaled variables ``ΔU = M z̃`` with ``M = blkdiag(S·V)·diag(1/√diag(H_V))``, where ``V`` is an
orthonormal n×n basis whose first column is the common mode ``1/√n`` and ``S = Δu_max·T``, and normalise the
whole objective by a constant. ``M`` and the constant are fixed when the solver is set up (nominal
linearisation); each step only the numbers change (``update(Px, Ax, q, l, u)``, same sparsity pattern).

Every answer is projected onto the hard u/Δu box before it is applied, so whatever OSQP returns (including a
max-iteration iterate) the force and force-rate limits hold. A non-finite or infeasible answer triggers the
fallback (the shifted previous plan, else Δu = 0; or a rate-limited brake) and is counted.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import osqp
import scipy.linalg
import scipy.sparse as sp

from controllers.ato_mpc.model import (
    LinearModel,
    affine_map,
    affine_term,
    build_model,
    feedforward_forces_n,
    prediction_matrices,
)
from railsim.physics.multipoint import MultipointParams

TERMINALS = ("none", "dare", "lyapunov")
TERMINAL_BLOCKS = ("x", "full")
DECISIONS = ("increment", "force")
FALLBACKS = ("shifted_plan", "brake")
_INF = 1e30
_ACCEPTED = ("solved", "solved inaccurate")


@dataclass(frozen=True)
class MpcSettings:
    """Tuning of the condensed MPC (defaults: Paper B's single-section set, T = 0.1 s per spec A1)."""

    period_s: float = 0.1
    horizon_p: int = 3
    horizon_c: int = 3
    q_x1: float = 0.5
    q_rel_x: float = 1e12
    q_v1: float = 1e9
    q_rel_v: float = 1e12
    r_du: float = 1e-5
    r_u: float = 1e-5  # MPC-B only: penalty on the force itself [1/N²]
    terminal: str = "dare"
    terminal_blocks: str = "x"
    decision: str = "increment"
    discretisation: str = "zoh"
    relinearise_tol_mps: float = 2.0  # A22 moves by 2c2'·Δv ≈ 4e-6 /s per m/s
    target_coupler_m: float = -1.0  # l_d (< 0: use the coupler's natural length, A4)
    soft_linear: float = 1e6
    soft_quadratic: float = 1e6
    fallback: str = "shifted_plan"
    eps: float = 1e-4
    max_iter: int = 20000

    def __post_init__(self) -> None:
        def req(name: str, ok: bool, exp: str) -> None:
            if not ok:
                raise ValueError(f"{name}: expected {exp}, got {getattr(self, name)!r}")

        req("period_s", self.period_s > 0.0, "a number > 0")
        for name in ("horizon_p", "horizon_c", "max_iter"):
            v = getattr(self, name)
            req(name, v >= 1 and float(v).is_integer(), "an integer >= 1")
            object.__setattr__(self, name, int(v))
        req("horizon_c", self.horizon_c <= self.horizon_p, f"an integer <= horizon_p ({self.horizon_p})")
        for name in ("q_x1", "q_rel_x", "q_v1", "q_rel_v", "soft_linear", "soft_quadratic"):
            req(name, getattr(self, name) >= 0.0, "a number >= 0")
        for name in ("r_du", "r_u", "eps"):
            req(name, getattr(self, name) > 0.0, "a number > 0")
        req("terminal", self.terminal in TERMINALS, f"one of {', '.join(TERMINALS)}")
        req("terminal_blocks", self.terminal_blocks in TERMINAL_BLOCKS, f"one of {', '.join(TERMINAL_BLOCKS)}")
        req("decision", self.decision in DECISIONS, f"one of {', '.join(DECISIONS)}")
        req("discretisation", self.discretisation in ("euler", "zoh"), "one of euler, zoh")
        req("fallback", self.fallback in FALLBACKS, f"one of {', '.join(FALLBACKS)}")


@dataclass(frozen=True)
class ReferenceWindow:
    """What the QP needs from the reference at step k (spec §2.9, A17, A18).

    ``x_ref_m``/``v_ref_mps``: expected displacement/speed of carriage 1 at k+1…k+N_p; ``v_lin_mps``: the
    linearisation speed v_r(k); ``x_max_m``: the stop point (upper position bound); ``v_max_mps``: the speed
    bound held over the horizon; ``gradient_permille``: θ_i at time k (frozen over the horizon).
    """

    x_ref_m: np.ndarray
    v_ref_mps: np.ndarray
    v_lin_mps: float
    x_max_m: float
    v_max_mps: float
    gradient_permille: np.ndarray
    wind_mps2: float = 0.0


@dataclass(frozen=True)
class TerminalIngredients:
    """Terminal weight P, feedback K (ΔU = K·e) and the checks of spec §2.14."""

    p: np.ndarray
    k: np.ndarray
    spectral_radius: float
    lyapunov_residual: float  # ‖(Ã+B̃K)ᵀP(Ã+B̃K) − P + Q + KᵀRK‖ / ‖P‖
    min_eig_p: float


def stage_weight(p: MultipointParams, s: MpcSettings) -> np.ndarray:
    """``Q_ξ = C̃ᵀ Q C̃`` (3n×3n): the spec's A3 mapping, zero on the u-block."""
    n = p.n_cars
    q = np.concatenate(([s.q_x1], np.full(n - 1, s.q_rel_x), [s.q_v1], np.full(n - 1, s.q_rel_v), np.zeros(n)))
    return np.diag(q)


def terminal_ingredients(
    at: np.ndarray, bt: np.ndarray, q: np.ndarray, r: np.ndarray, method: str = "dare", force_scale_n: float = 1.0
) -> TerminalIngredients:
    """Eq. (17)–(20): K and the tail-cost matrix P with ρ(Ã+B̃K) < 1 and P ≻ 0 checked (ValueError if not).

    ``"dare"``: P from the discrete algebraic Riccati equation, K the matching LQR gain (the fixed point of
    the Lyapunov equation for that K). ``"lyapunov"``: the paper's wording — take a stabilising K (the LQR gain
    of a 10× heavier R, deliberately not the optimal one) and solve
    ``(Ã+B̃K)ᵀP(Ã+B̃K) − P + Q + KᵀRK = 0``.

    The weights span 20 orders of magnitude, which makes scipy's QZ-based DARE fail; we solve it in balanced
    coordinates ``ξ = S ξ̂`` with ``S = diag(1/√q_i)`` (``force_scale_n`` for the unweighted u-states) and
    ``Δu = force_scale_n·Δû``, and transform back: ``P = S⁻ᵀ P̂ S⁻¹``, ``K = force_scale_n·K̂ S⁻¹``.
    """
    r_design = r if method == "dare" else 10.0 * r
    w = np.diag(q).astype(float).copy()
    w[w <= 0.0] = 1.0 / force_scale_n**2
    s_vec = 1.0 / np.sqrt(w)
    a_h = at * (s_vec[None, :] / s_vec[:, None])
    b_h = bt * force_scale_n / s_vec[:, None]
    q_h = q * np.outer(s_vec, s_vec)
    r_h = r_design * force_scale_n**2
    p_h = scipy.linalg.solve_discrete_are(a_h, b_h, q_h, r_h)
    k_h = -np.linalg.solve(r_h + b_h.T @ p_h @ b_h, b_h.T @ p_h @ a_h)
    pd = p_h / np.outer(s_vec, s_vec)
    k = force_scale_n * k_h / s_vec[None, :]
    rho = float(np.max(np.abs(np.linalg.eigvals(a_h + b_h @ k_h))))
    if not rho < 1.0:
        raise ValueError(f"terminal: no stabilising feedback found (spectral radius {rho:.9f} >= 1)")
    qk = q + k.T @ r @ k
    if method == "dare":
        p = pd
    else:
        acl_h = a_h + b_h @ k_h
        qk_h = q_h + k_h.T @ (r * force_scale_n**2) @ k_h
        p = scipy.linalg.solve_discrete_lyapunov(acl_h.T, qk_h) / np.outer(s_vec, s_vec)
    p = 0.5 * (p + p.T)
    # Residual and definiteness in the balanced coordinates (the raw entries span 20 decades).
    p_bal = p * np.outer(s_vec, s_vec)
    acl_bal = a_h + b_h @ k_h
    qk_bal = qk * np.outer(s_vec, s_vec)
    resid = float(np.linalg.norm(acl_bal.T @ p_bal @ acl_bal - p_bal + qk_bal) / np.linalg.norm(p_bal))
    min_eig = float(np.min(np.linalg.eigvalsh(p_bal)))
    if not min_eig > 0.0:
        raise ValueError(f"terminal: P is not positive definite (min eigenvalue {min_eig:g} in balanced units)")
    return TerminalIngredients(p, k, rho, resid, min_eig)


def _pattern_indices(mask: np.ndarray) -> tuple[sp.csc_matrix, np.ndarray, np.ndarray]:
    """A CSC matrix whose stored entries are exactly ``mask`` (explicit zeros kept) and its (row, col) order."""
    rows, cols = np.nonzero(mask.T)  # column-major order = CSC storage order
    rows, cols = cols, rows
    mat = sp.csc_matrix((np.ones(rows.size), (rows, cols)), shape=mask.shape)
    mat.sort_indices()
    c = np.repeat(np.arange(mask.shape[1]), np.diff(mat.indptr))
    return mat, mat.indices.copy(), c


@dataclass
class SolveInfo:
    status: str
    fallback: bool
    solve_time_s: float
    iterations: int
    max_slack: float
    cost: float
    du_n: np.ndarray = field(repr=False)


class CondensedMpc:
    """Receding-horizon MPC over force increments for the multi-point train (SEMPC, MPC-A, MPC-B)."""

    def __init__(self, params: MultipointParams, settings: MpcSettings, nominal_speed_mps: float = 20.0) -> None:
        self.p = params
        self.s = settings
        n = params.n_cars
        self.n = n
        self.ns = 3 * n
        self.l_d = params.coupler_length_m if settings.target_coupler_m < 0.0 else settings.target_coupler_m
        self.q_stage = stage_weight(params, settings)
        self.r_step = settings.r_du * np.eye(n)
        nominal = build_model(params, nominal_speed_mps, np.zeros(n), settings.period_s, settings.discretisation)
        self.terminal: TerminalIngredients | None = None
        if settings.terminal != "none":
            self.terminal = terminal_ingredients(
                nominal.at,
                nominal.bt,
                self.q_stage,
                self.r_step,
                settings.terminal,
                params.force_rate_max_n_per_s * settings.period_s,
            )
        self.n_dec = n * settings.horizon_c
        self.n_rows_state = settings.horizon_p * (n + 1)
        self.n_slack = self.n_rows_state
        self._plan_du: np.ndarray | None = None  # last optimal ΔU (for warm start and fallback)
        self._lin: tuple | None = None  # (v_lin, F, G, D_map, H) of the current linearisation
        self._setup(nominal)

    # ---- matrices -------------------------------------------------------------------------------------------
    def _q_bar(self) -> np.ndarray:
        s = self.s
        blocks = [self.q_stage] * (s.horizon_p - 1)
        if self.terminal is None:
            blocks.append(self.q_stage)
        else:
            pt = self.terminal.p.copy()
            if s.terminal_blocks == "x":
                pt[2 * self.n :, :] = 0.0
                pt[:, 2 * self.n :] = 0.0
            blocks.append(pt)
        return scipy.linalg.block_diag(*blocks)

    def _r_bar(self) -> np.ndarray:
        s = self.s
        if s.decision == "force":
            lmat = np.kron(np.tril(np.ones((s.horizon_c, s.horizon_c))), np.eye(self.n))
            return s.r_u * lmat.T @ lmat
        return np.kron(np.eye(s.horizon_c), self.r_step)

    def _select(self) -> np.ndarray:
        """Z_N: picks x_1, x_{i,i−1}, v_1 from every predicted ξ (Eq. (22))."""
        z = np.zeros((self.n + 1, self.ns))
        z[:, : self.n + 1] = np.eye(self.n + 1)
        return np.kron(np.eye(self.s.horizon_p), z)

    def condensed(self, model: LinearModel) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(F, G, D, H) for one linearisation; H = 2(GᵀQ̄G + R̄) in unscaled ΔU [N]."""
        f, g, d = prediction_matrices(model.at, model.bt, model.dt, self.s.horizon_p, self.s.horizon_c)
        h = 2.0 * (g.T @ self.q_bar @ g + self.r_bar)
        return f, g, d, 0.5 * (h + h.T)

    def _setup(self, nominal: LinearModel) -> None:
        s, n = self.s, self.n
        self.q_bar = self._q_bar()
        self.r_bar = self._r_bar()
        self.z_sel = self._select()
        self.l_cum = np.kron(np.tril(np.ones((s.horizon_c, s.horizon_c))), np.eye(n))
        f, g, d, h = self.condensed(nominal)
        # Change of variables ΔU = M z̃: common/differential modes, step scale, Jacobi.
        v = np.linalg.qr(np.column_stack([np.ones(n), np.eye(n)[:, : n - 1]]))[0]
        v[:, 0] = np.abs(v[:, 0])
        scale_n = self.p.force_rate_max_n_per_s * s.period_s
        base = np.kron(np.eye(s.horizon_c), scale_n * v)
        hv = base.T @ h @ base
        jac = 1.0 / np.sqrt(np.maximum(np.diag(hv), 1e-12 * np.max(np.diag(hv))))
        self.m_map = base * jac[None, :]
        self.m_inv = np.linalg.inv(self.m_map)
        self.cost_scale = 1.0 / max(float(np.max(np.abs(self.m_map.T @ h @ self.m_map))), 1e-12)
        nz = self.n_dec + self.n_slack
        # Sparsity patterns (fixed): dense decision block, diagonal slack block.
        p_mask = np.zeros((nz, nz), dtype=bool)
        p_mask[: self.n_dec, : self.n_dec] = np.triu(np.ones((self.n_dec, self.n_dec), dtype=bool))
        p_mask[np.arange(self.n_dec, nz), np.arange(self.n_dec, nz)] = True
        self._p_csc, self._p_rows, self._p_cols = _pattern_indices(p_mask)
        a_dense = self._constraint_matrix(g)
        a_mask = np.zeros_like(a_dense, dtype=bool)
        ro = 2 * self.n_rows_state
        a_mask[:ro, : self.n_dec] = True
        a_mask[: self.n_rows_state, self.n_dec :] = np.eye(self.n_slack, dtype=bool)
        a_mask[self.n_rows_state : ro, self.n_dec :] = np.eye(self.n_slack, dtype=bool)
        a_mask[ro : ro + self.n_slack, self.n_dec :] = np.eye(self.n_slack, dtype=bool)
        a_mask[ro + self.n_slack :, : self.n_dec] = True
        self._a_csc, self._a_rows, self._a_cols = _pattern_indices(a_mask)
        p_full = self._objective_matrix(h)
        self.solver = osqp.OSQP()
        self.solver.setup(
            P=sp.csc_matrix(
                (p_full[self._p_rows, self._p_cols], self._p_csc.indices, self._p_csc.indptr), shape=p_full.shape
            ),
            q=np.zeros(nz),
            A=sp.csc_matrix(
                (a_dense[self._a_rows, self._a_cols], self._a_csc.indices, self._a_csc.indptr), shape=a_dense.shape
            ),
            l=-_INF * np.ones(a_dense.shape[0]),
            u=_INF * np.ones(a_dense.shape[0]),
            eps_abs=s.eps,
            eps_rel=s.eps,
            max_iter=s.max_iter,
            polishing=True,
            verbose=False,
            warm_starting=True,
            check_termination=25,
        )
        self._nominal_h = h

    def _objective_matrix(self, h: np.ndarray) -> np.ndarray:
        nz = self.n_dec + self.n_slack
        out = np.zeros((nz, nz))
        out[: self.n_dec, : self.n_dec] = self.cost_scale * (self.m_map.T @ h @ self.m_map)
        out[np.arange(self.n_dec, nz), np.arange(self.n_dec, nz)] = self.cost_scale * 2.0 * self.s.soft_quadratic
        return out

    def _constraint_matrix(self, g: np.ndarray) -> np.ndarray:
        nd, ns_ = self.n_dec, self.n_slack
        sx = self.z_sel @ g @ self.m_map
        eye_s = np.eye(ns_)
        rows = [
            np.hstack([sx, eye_s]),  # Z(…) + s ≥ Xmin
            np.hstack([sx, -eye_s]),  # Z(…) − s ≤ Xmax
            np.hstack([np.zeros((ns_, nd)), eye_s]),  # s ≥ 0
            np.hstack([self.l_cum @ self.m_map, np.zeros((nd, ns_))]),  # force bounds
        ]
        if self.s.decision == "increment":
            rows.append(np.hstack([self.m_map, np.zeros((nd, ns_))]))  # increment bounds
        else:
            rows.append(np.zeros((nd, nd + ns_)))  # placeholder rows, unbounded (keeps one pattern)
        return np.vstack(rows)

    # ---- one step -------------------------------------------------------------------------------------------
    def reference_stack(self, ref: ReferenceWindow) -> np.ndarray:
        """``Ref = [ξ_ref(k+1); …; ξ_ref(k+N_p)]`` with ``ξ_ref = [x_r, −l_d·1, v_r, 0, u_ref]``."""
        n, s = self.n, self.s
        out = np.zeros(self.ns * s.horizon_p)
        for i in range(s.horizon_p):
            blk = np.zeros(self.ns)
            blk[0] = ref.x_ref_m[i]
            blk[1:n] = -self.l_d
            blk[n] = ref.v_ref_mps[i]
            if self.terminal is not None and s.terminal_blocks == "full" and i == s.horizon_p - 1:
                v_prev = ref.v_ref_mps[i - 1] if i > 0 else ref.v_lin_mps
                acc = (ref.v_ref_mps[i] - v_prev) / s.period_s
                blk[2 * n :] = feedforward_forces_n(self.p, acc, ref.v_ref_mps[i], ref.gradient_permille, ref.wind_mps2)
            out[i * self.ns : (i + 1) * self.ns] = blk
        return out

    def _linearisation(self, v_lin_mps: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool]:
        """(F, G, D_map, H) at ``v_lin`` — cached while v_lin stays within ``relinearise_tol_mps`` (A9).

        ``D_map`` maps the continuous affine term d (2n) to the stacked prediction offset D, so slopes, wind and
        the v_r² term are always current even when the matrices are reused. Returns ``changed``.
        """
        s = self.s
        if self._lin is not None and abs(v_lin_mps - self._lin[0]) <= s.relinearise_tol_mps:
            return (*self._lin[1:], False)
        zero = np.zeros(self.n)
        model = build_model(self.p, v_lin_mps, zero, s.period_s, s.discretisation)
        f, g, _, h = self.condensed(model)
        gamma = affine_map(model.a, s.period_s, s.discretisation)
        # D = Σ_{j<i} Ã^j [Γ d; 0], linear in d.
        d_map = np.zeros((self.ns * s.horizon_p, 2 * self.n))
        acc = np.zeros((self.ns, 2 * self.n))
        inj = np.vstack([gamma, np.zeros((self.n, 2 * self.n))])
        for i in range(s.horizon_p):
            acc = model.at @ acc + inj
            d_map[i * self.ns : (i + 1) * self.ns] = acc
        self._lin = (v_lin_mps, f, g, d_map, h)
        return f, g, d_map, h, True

    def solve(self, rel_state: np.ndarray, u_prev_n: np.ndarray, ref: ReferenceWindow) -> tuple[np.ndarray, SolveInfo]:
        """One receding-horizon step: returns the applied forces ``u(k) = u(k−1) + Δu*(k)`` and diagnostics."""
        s, n, p = self.s, self.n, self.p
        t0 = time.perf_counter()
        f, g, d_map, h, changed = self._linearisation(ref.v_lin_mps)
        d = d_map @ affine_term(p, ref.v_lin_mps, ref.gradient_permille, ref.wind_mps2)
        xi = np.concatenate([np.asarray(rel_state, dtype=float), np.asarray(u_prev_n, dtype=float)])
        free = f @ xi + d
        e0 = free - self.reference_stack(ref)
        grad = 2.0 * g.T @ self.q_bar @ e0
        if s.decision == "force":
            grad = grad + 2.0 * s.r_u * self.l_cum.T @ np.tile(u_prev_n, s.horizon_c)
        q = np.concatenate(
            [self.cost_scale * (self.m_map.T @ grad), self.cost_scale * s.soft_linear * np.ones(self.n_slack)]
        )
        zfree = self.z_sel @ free
        step_min = np.concatenate([[0.0], np.full(n - 1, -self.l_d - p.coupler_slack_m), [0.0]])
        step_max = np.concatenate([[ref.x_max_m], np.full(n - 1, -self.l_d + p.coupler_slack_m), [ref.v_max_mps]])
        xmin = np.tile(step_min, s.horizon_p) - zfree
        xmax = np.tile(step_max, s.horizon_p) - zfree
        u_rep = np.tile(u_prev_n, s.horizon_c)
        nd = self.n_dec
        if s.decision == "increment":
            du_lo = np.full(nd, p.force_rate_min_n_per_s * s.period_s)
            du_hi = np.full(nd, p.force_rate_max_n_per_s * s.period_s)
        else:
            du_lo, du_hi = np.full(nd, -_INF), np.full(nd, _INF)
        lo = np.concatenate(
            [xmin, np.full(self.n_rows_state, -_INF), np.zeros(self.n_slack), p.force_min_n - u_rep, du_lo]
        )
        hi = np.concatenate(
            [np.full(self.n_rows_state, _INF), xmax, np.full(self.n_slack, _INF), p.force_max_n - u_rep, du_hi]
        )
        if changed:
            pm = self._objective_matrix(h)
            am = self._constraint_matrix(g)
            self.solver.update(Px=pm[self._p_rows, self._p_cols], Ax=am[self._a_rows, self._a_cols])
        self.solver.update(q=q, l=lo, u=hi)
        if self._plan_du is not None:
            shifted = np.concatenate([self._plan_du[n:], np.zeros(n)])
            self.solver.warm_start(x=np.concatenate([self.m_inv @ shifted, np.zeros(self.n_slack)]))
        res = self.solver.solve(raise_error=False)
        status = str(res.info.status)
        x = np.asarray(res.x, dtype=float) if res.x is not None else np.full(nd + self.n_slack, np.nan)
        fallback = False
        if status in _ACCEPTED or (status.startswith("maximum") and np.all(np.isfinite(x))):
            du_plan = self.m_map @ x[:nd]
            max_slack = float(np.max(x[nd:])) if self.n_slack else 0.0
        else:
            fallback = True
            max_slack = float("nan")
            du_plan = self._fallback_plan(u_prev_n)
        if not np.all(np.isfinite(du_plan)):
            fallback = True
            du_plan = self._fallback_plan(u_prev_n)
        du0 = self._project(du_plan[:n], u_prev_n)
        self._plan_du = du_plan
        cost = float("nan")
        if not fallback:
            cost = float(0.5 * du_plan @ h @ du_plan + grad @ du_plan + e0 @ self.q_bar @ e0)
        info = SolveInfo(status, fallback, time.perf_counter() - t0, int(res.info.iter), max_slack, cost, du0)
        return np.asarray(u_prev_n, dtype=float) + du0, info

    def _project(self, du: np.ndarray, u_prev: np.ndarray) -> np.ndarray:
        """Clip onto the hard Δu box (increment form) and the force box: the limits hold whatever the solver did."""
        p, s = self.p, self.s
        if s.decision == "increment":
            du = np.clip(du, p.force_rate_min_n_per_s * s.period_s, p.force_rate_max_n_per_s * s.period_s)
        return np.clip(u_prev + du, p.force_min_n, p.force_max_n) - u_prev

    def _fallback_plan(self, u_prev: np.ndarray) -> np.ndarray:
        n, s, p = self.n, self.s, self.p
        if s.fallback == "brake":
            step = np.full(n, p.force_rate_min_n_per_s * s.period_s)
            return np.tile(step, s.horizon_c)
        if self._plan_du is not None and np.all(np.isfinite(self._plan_du)):
            return np.concatenate([self._plan_du[n:], np.zeros(n)])
        return np.zeros(self.n_dec)

    def reset(self) -> None:
        self._plan_du = None

    def dense_problem(self, rel_state: np.ndarray, u_prev_n: np.ndarray, ref: ReferenceWindow) -> dict[str, Any]:
        """The unscaled QP of one step for cross-checks: H, g, constant, F, G, D, Ref (tests, diagnostics)."""
        model = build_model(
            self.p, ref.v_lin_mps, ref.gradient_permille, self.s.period_s, self.s.discretisation, ref.wind_mps2
        )
        xi = np.concatenate([np.asarray(rel_state, dtype=float), np.asarray(u_prev_n, dtype=float)])
        f, g, d, h = self.condensed(model)
        e0 = f @ xi + d - self.reference_stack(ref)
        return {
            "h": h,
            "g": 2.0 * g.T @ self.q_bar @ e0,
            "const": float(e0 @ self.q_bar @ e0),
            "f": f,
            "gm": g,
            "d": d,
            "xi": xi,
            "model": model,
        }
