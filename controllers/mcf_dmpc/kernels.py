"""Compiled MCF rollout + J^(DMPC) for populations of candidates (spec 000 §2.6 pseudocode, Eq. 14–20, 29).

Why this module exists (issue #19): one OPO-MCF-DMPC step scores ~9,000 model-index sequences (MSMFO with
Table II's P = 50, K = 100, EOBL, mutation and the greedy pass of Eq. 28) plus ~100 OPO parameter polls, each a
60-step rollout of Eq. (2) under the CF law the sequence selects. The recursion over the horizon is sequential,
so a numpy batch pays ~40 array operations per predicted step whatever the population, and a plain-Python loop
pays ~1 µs per row and step. Here the same arithmetic is compiled with numba (``@njit``, cached on disk): one
row-step costs ~10–20 ns, and the rollout, the cost terms and the constraint penalty are *fused* into one pass
(no intermediate trajectory arrays), so a 50-row population costs ~50 µs.

One definition of the physics: :func:`rollout_rows` is the *same* arithmetic, operation for operation, as
:func:`controllers.mcf_dmpc.rollout._rollout_scalar` (guards of A11 included: ΔS ≤ 0 → −∞ for IDM+, denominators
floored at ``V_FLOOR_MPS``, ``D^(e)/ΔS`` capped at ``RATIO_CAP``), and :func:`population_costs` scores the
trajectory it writes with the terms of :func:`controllers.mcf_dmpc.cost.cost_terms`::

    J = ξ_v Σ Δv_j² + ξ_s Σ e_j² + ξ_u Σ u_j² + ξ_Δu [Σ (u_j − u_{j−1})² + (u_{−1} − u_0)²]
        + ξ_term (ξ_v Δv_Np² + ξ_s e_Np²) + w Σ [max(0, D^(s)_j − ΔS_j) + max(0, −v_j) + max(0, v_j − v_m)]
        + w Σ [max(0, −b^(c) − u_j) + max(0, u_j − a^(m))]

``tests/test_paper000_kernels.py`` pins both to the scalar reference to 1e-12 (relative) on random inputs.

If numba is not importable the functions still run as plain Python (``NUMBA_AVAILABLE`` is False) — correct
but ~100× slower; :mod:`controllers.mcf_dmpc.cost` then keeps using the numpy/scalar rollout instead.
"""

from __future__ import annotations

import math

import numpy as np

from controllers.mcf_dmpc.cf_models import RATIO_CAP, V_FLOOR_MPS

try:  # numba: optional at import time, a declared dependency of the project (pyproject.toml)
    from numba import njit

    NUMBA_AVAILABLE = True
except ImportError:  # pragma: no cover - exercised only in environments without numba
    NUMBA_AVAILABLE = False

    def njit(*args, **kwargs):  # type: ignore[no-redef]
        def wrap(fn):
            return fn

        return wrap(args[0]) if args and callable(args[0]) else wrap


__all__ = ["NUMBA_AVAILABLE", "population_costs", "rollout_rows", "train_vector", "weight_vector"]

# Layout of the scalar parameter vectors handed to the kernels (numba wants flat, typed arguments).
# train_vector: [dt_s, u_lo, u_hi (=a^(m)), |b^(c)|, |b^(m)| own, c0, c1, c2, L^(s), v_m]
# weight_vector: [ξ_v, ξ_s, ξ_u, ξ_Δu, ξ_term, penalty]


def train_vector(train) -> np.ndarray:
    """The :class:`~controllers.mcf_dmpc.spacing.TrainParamsA` fields the kernels need, as a float vector."""
    return np.array(
        [
            train.dt_s,
            -train.service_decel_mps2,
            train.max_accel_mps2,
            train.service_decel_mps2,
            train.emergency_decel_mps2,
            train.davis_c0_mps2,
            train.davis_c1_per_s,
            train.davis_c2_per_m,
            train.safety_margin_m,
            train.max_speed_mps,
        ],
        dtype=float,
    )


def weight_vector(weights) -> np.ndarray:
    """The :class:`~controllers.mcf_dmpc.cost.CostWeights` as a float vector."""
    return np.array(
        [weights.xi_v, weights.xi_s, weights.xi_u, weights.xi_du, weights.xi_term, weights.penalty], dtype=float
    )


@njit(cache=True)
def _rollout_row(row, th, x0, v0, xp, vp, ap, base, tr, feedforward, u, v, s):  # pragma: no cover - compiled
    """One row of the MCF rollout into ``u (Np,)``, ``v``/``s (Np+1,)`` — the arithmetic of ``_rollout_scalar``."""
    tau = tr[0]
    half_tau2 = 0.5 * tau * tau
    u_lo = tr[1]
    u_hi = tr[2]
    a_max = tr[2]
    own_k = 1.0 / (2.0 * tr[3])
    c0 = tr[5]
    c1 = tr[6]
    c2 = tr[7]
    th1, th2, th3, th4, th5, th6, th7 = th[0], th[1], th[2], th[3], th[4], th[5], th[6]
    vj = v0
    sj = x0
    v[0] = vj
    s[0] = sj
    for j in range(row.shape[0]):
        m = row[j]
        vpj = vp[j]
        spacing = xp[j] - sj
        de = base[j] + vj * vj * own_k
        if m == 0:  # enhanced IDM, Eq. (8)
            if spacing > 0.0:
                vpos = vj if vj > 0.0 else 0.0
                speed_term = (vpos / (vpj if vpj > V_FLOOR_MPS else V_FLOOR_MPS)) ** th1
                ratio = (de if de > 0.0 else 0.0) / spacing
                if ratio > RATIO_CAP:
                    ratio = RATIO_CAP
                a = a_max * (2.0 - speed_term - ratio**th2)
            else:
                a = -math.inf
        elif m == 1:  # enhanced CACC, Eq. (10)
            a = th3 * ap[j] + th4 * (spacing - de) + th5 * (vpj - vj)
        else:  # enhanced FVD, Eq. (11)-(13)
            v_star = vpj * (vpj + spacing - de) / (vj if vj > V_FLOOR_MPS else V_FLOOR_MPS)
            a = th6 * (v_star - vj) + (th7 if spacing <= de else 0.0) * (vpj - vj)
        av = abs(vj)
        omega = c0 + c1 * av + c2 * av * av if av != 0.0 else 0.0
        if feedforward:  # A9 option: the law gives the net acceleration, saturate u = a + ω
            a += omega
        uj = u_lo if a < u_lo else (u_hi if a > u_hi else a)
        acc = uj - omega
        sj = sj + tau * vj + half_tau2 * acc
        vj = vj + tau * acc
        u[j] = uj
        v[j + 1] = vj
        s[j + 1] = sj


@njit(cache=True)
def _desired_base(vp, lp, bp, tr):  # pragma: no cover - compiled
    """The predecessor part of D^(e) (Eq. 5) per step: ``L^(s) + L_{i−1} − v_{i−1}²/(2|b^(m)_{i−1}|)``."""
    out = np.empty(vp.shape[0])
    for j in range(vp.shape[0]):
        out[j] = tr[8] + lp - vp[j] * vp[j] / (2.0 * bp)
    return out


@njit(cache=True)
def rollout_rows(seq, thetas, x0, v0, xp, vp, ap, lp, bp, tr, feedforward):  # pragma: no cover - compiled
    """Trajectories of ``seq (P, Np)`` under ``thetas (P, 7)``: returns ``u (P, Np)``, ``v``, ``s (P, Np+1)``."""
    pop, steps = seq.shape
    base = _desired_base(vp, lp, bp, tr)
    u = np.empty((pop, steps))
    v = np.empty((pop, steps + 1))
    s = np.empty((pop, steps + 1))
    for r in range(pop):
        _rollout_row(seq[r], thetas[r], x0, v0, xp, vp, ap, base, tr, feedforward, u[r], v[r], s[r])
    return u, v, s


@njit(cache=True)
def population_costs(seq, thetas, x0, v0, xp, vp, ap, lp, bp, tr, w, u_prev, feedforward):  # pragma: no cover
    """J^(DMPC) + penalty (Eq. 14–20) of every row of ``seq (P, Np)`` under ``thetas (P, 7)``, shape ``(P,)``."""
    pop, steps = seq.shape
    base = _desired_base(vp, lp, bp, tr)
    u = np.empty(steps)
    v = np.empty(steps + 1)
    s = np.empty(steps + 1)
    out = np.empty(pop)
    xi_v, xi_s, xi_u, xi_du, xi_term, w_pen = w[0], w[1], w[2], w[3], w[4], w[5]
    b_c2 = 2.0 * tr[3]
    b_m2 = 2.0 * tr[4]
    u_lo = tr[1]
    u_hi = tr[2]
    v_m = tr[9]
    for r in range(pop):
        _rollout_row(seq[r], thetas[r], x0, v0, xp, vp, ap, base, tr, feedforward, u, v, s)
        sum_dv = 0.0
        sum_e = 0.0
        sum_u = 0.0
        sum_du = 0.0
        viol = 0.0
        dv = 0.0
        err = 0.0
        for j in range(1, steps + 1):
            vj = v[j]
            vpj = vp[j]
            spacing = xp[j] - s[j]
            dv = vj - vpj
            pred_part = tr[8] + lp - vpj * vpj / (2.0 * bp)
            err = spacing - (pred_part + vj * vj / b_c2)
            ds = pred_part + vj * vj / b_m2
            sum_dv += dv * dv
            sum_e += err * err
            viol += max(ds - spacing, 0.0) + max(-vj, 0.0) + max(vj - v_m, 0.0)
        for j in range(steps):
            uj = u[j]
            sum_u += uj * uj
            if j > 0:
                d = uj - u[j - 1]
                sum_du += d * d
            viol += max(u_lo - uj, 0.0) + max(uj - u_hi, 0.0)
        first = u_prev - u[0]
        total = xi_v * sum_dv + xi_s * sum_e + xi_u * sum_u + xi_du * (sum_du + first * first)
        total += xi_term * (xi_v * dv * dv + xi_s * err * err) + w_pen * viol
        out[r] = total
    return out
