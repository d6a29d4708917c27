"""Compiled MCF rollout + J^(DMPC) for populations of candidates (spec 000 §2.6 pseudocode, Eq. 14–20, 29).

Why this module exists: one OPO-MCF-DMPC step scores ~9,000 model-index sequences (MSMFO with
Table II's P = 50, K = 100, EOBL, mutation and the greedy pass of Eq. 28) plus ~100 OPO parameter polls, each a
60-step rollout of Eq. (2) under the CF law the sequence selects. The recursion over the horizon is sequential,
so a numpy batch pays ~40 array operations per predicted step whatever the population, and a plain-Python loop
pays ~1 µs per row and step. Here the same arithmetic is compiled with numba (``@njit``, cached on disk), and the
rollout, the cost terms and the constraint penalty are *fused* into one pass (:func:`batch_costs`, no trajectory
arrays). Measured (CPU, loaded 2-core machine): ~35 ns per row-step for a mixed population, 57 ns for IDM+ (its
two fractional powers), 16–18 ns for CACC+/FVD+; a 50-row population ~110 µs — with rows one per inner
iteration; rows in pairs (:func:`batch_costs`) take ~0.82× that on a Table II search's batches. A search with
one Θ may resume every row after its first steps from :func:`prefix_states` (all rows start from one state).

One definition of the physics: every law step is :func:`_control` — the *same* arithmetic, operation for
operation, as :func:`controllers.mcf_dmpc.rollout._rollout_scalar` (guards of A11 included: ΔS ≤ 0 → −∞ for IDM+,
denominators floored at ``V_FLOOR_MPS``, ``D^(e)/ΔS`` capped at ``RATIO_CAP``); :func:`rollout_rows` writes the
trajectories and :func:`batch_costs` scores them on the fly with the terms of
:func:`controllers.mcf_dmpc.cost.cost_terms`::

    J = ξ_v Σ Δv_j² + ξ_s Σ e_j² + ξ_u Σ u_j² + ξ_Δu [Σ (u_j − u_{j−1})² + (u_{−1} − u_0)²]
        + ξ_term (ξ_v Δv_Np² + ξ_s e_Np²) + w Σ [max(0, D^(s)_j − ΔS_j) + max(0, −v_j) + max(0, v_j − v_m)]
        + w Σ [max(0, −b^(c) − u_j) + max(0, u_j − a^(m))]

``tests/unit/test_paper000_kernels.py`` pins both to the scalar reference to 1e-12 (relative) on random inputs.

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


__all__ = [
    "NUMBA_AVAILABLE",
    "batch_context",
    "desired_base",
    "population_costs",
    "rollout_rows",
    "batch_costs",
    "prefix_states",
    "train_vector",
    "weight_vector",
]

N_MODELS = 3  # the laws _control knows: 0 IDM+, 1 CACC+, 2 FVD+
NO_PREFIX = np.zeros((1, 9))  # batch_costs without prefix states (depth 0)

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


@njit(cache=True, inline="always")
def _control(m, th, vj, spacing, de, vpj, apj, omega, tr, feedforward):  # pragma: no cover - compiled
    """The saturated control ``u_j`` of law ``m`` at one predicted step — the arithmetic of ``_rollout_scalar``."""
    if m == 0:  # enhanced IDM, Eq. (8)
        if spacing > 0.0:
            vpos = vj if vj > 0.0 else 0.0
            speed_term = (vpos / (vpj if vpj > V_FLOOR_MPS else V_FLOOR_MPS)) ** th[0]
            ratio = (de if de > 0.0 else 0.0) / spacing
            if ratio > RATIO_CAP:
                ratio = RATIO_CAP
            a = tr[2] * (2.0 - speed_term - ratio ** th[1])
        else:
            a = -math.inf
    elif m == 1:  # enhanced CACC, Eq. (10)
        a = th[2] * apj + th[3] * (spacing - de) + th[4] * (vpj - vj)
    else:  # enhanced FVD, Eq. (11)-(13)
        v_star = vpj * (vpj + spacing - de) / (vj if vj > V_FLOOR_MPS else V_FLOOR_MPS)
        a = th[5] * (v_star - vj) + (th[6] if spacing <= de else 0.0) * (vpj - vj)
    a += th[7 + m]  # the law's control offset (cf_models docstring; 0 = the paper's law)
    if feedforward:  # A9 option: the law gives the net acceleration, saturate u = a + ω
        a += omega
    return tr[1] if a < tr[1] else (tr[2] if a > tr[2] else a)


@njit(cache=True, inline="always")
def _omega(vj, tr):  # pragma: no cover - compiled
    av = abs(vj)
    return tr[5] + tr[6] * av + tr[7] * av * av if av != 0.0 else 0.0


@njit(cache=True)
def _rollout_row(row, th, x0, v0, xp, vp, ap, base, tr, feedforward, u, v, s):  # pragma: no cover - compiled
    """One row of the MCF rollout into ``u (Np,)``, ``v``/``s (Np+1,)`` — the arithmetic of ``_rollout_scalar``."""
    tau = tr[0]
    half_tau2 = 0.5 * tau * tau
    own_k = 1.0 / (2.0 * tr[3])
    vj = v0
    sj = x0
    v[0] = vj
    s[0] = sj
    for j in range(row.shape[0]):
        omega = _omega(vj, tr)
        uj = _control(row[j], th, vj, xp[j] - sj, base[j] + vj * vj * own_k, vp[j], ap[j], omega, tr, feedforward)
        acc = uj - omega
        sj = sj + tau * vj + half_tau2 * acc
        vj = vj + tau * acc
        u[j] = uj
        v[j + 1] = vj
        s[j + 1] = sj


@njit(cache=True, inline="always")
def _accumulate(j, v, s, u, xpn, vpn, pred_part, b_c2, b_m2, u_lo, u_hi, v_m, sdv, se, su, sdu, viol, u_last, u_first):  # noqa: E501  # pragma: no cover
    """The terms of step ``j + 1`` (Eq. 14, 15, the Eq. 20 penalty) and of the control ``u_j`` (Eq. 16, 17) added to
    one row's running sums; returns the sums, ``u_0`` and the last ``Δv``, ``e`` (for Eq. 18)."""
    spacing = xpn - s
    d_v = v - vpn
    e = spacing - (pred_part + v * v / b_c2)
    ds = pred_part + v * v / b_m2
    sdv += d_v * d_v
    se += e * e
    viol += max(ds - spacing, 0.0) + max(-v, 0.0) + max(v - v_m, 0.0)
    su += u * u
    if j > 0:
        d = u - u_last
        sdu += d * d
    else:
        u_first = u
    viol += max(u_lo - u, 0.0) + max(u - u_hi, 0.0)
    return sdv, se, su, sdu, viol, u_first, d_v, e


@njit(cache=True, inline="always")
def _objective(sdv, se, su, sdu, viol, u_first, d_v, e, u_prev, w):  # pragma: no cover - compiled
    """J^(DMPC) + penalty from one row's sums (Eq. 19 with the terminal term of Eq. 18)."""
    first = u_prev - u_first
    total = w[0] * sdv + w[1] * se + w[2] * su + w[3] * (sdu + first * first)
    return total + w[4] * (w[0] * d_v * d_v + w[1] * e * e) + w[5] * viol


@njit(cache=True)
def batch_costs(seq, thetas, x0, v0, xp, vp, ap, base, lp, bp, tr, w, u_prev, feedforward, out, pre, depth):  # noqa: E501  # pragma: no cover
    """J^(DMPC) + penalty of the rows of ``seq (m, Np)`` (``thetas (m, N_THETA)``, or ``(1, N_THETA)``: one Θ for
    every row) into ``out (m,)``: the rollout of ``_rollout_row`` and the terms of
    :func:`controllers.mcf_dmpc.cost.cost_terms`, fused in one pass.

    Rows go in pairs, each row's state and sums in registers: a row's recursion over the horizon is a chain of
    dependent operations (~20 ns per step), and two independent chains side by side let the CPU overlap them
    (measured: 0.83x the time of the former horizon-outer loop over per-row arrays, 0.94x for one row at a time).
    Every row sees exactly the same operations in the same order as on its own, so a row's cost does not depend
    on the batch (an odd batch scores its last row in both lanes).

    ``depth > 0``: every row starts at step ``depth`` from ``pre``, the states of :func:`prefix_states` (the same
    Θ for every row), instead of repeating the first ``depth`` steps its model prefix shares with many rows.
    """
    m = seq.shape[0]
    steps = seq.shape[1]
    theta_step = 1 if thetas.shape[0] == m else 0  # 0: the single row of Θ serves every row
    tau = tr[0]
    half_tau2 = 0.5 * tau * tau
    own_k = 1.0 / (2.0 * tr[3])
    b_c2 = 2.0 * tr[3]
    b_m2 = 2.0 * tr[4]
    u_lo = tr[1]
    u_hi = tr[2]
    v_m = tr[9]
    pred = np.empty(steps)  # the predecessor part of D^(e) and D^(s) at step j + 1
    for j in range(steps):
        pred[j] = tr[8] + lp - vp[j + 1] * vp[j + 1] / (2.0 * bp)
    for ra in range(0, m, 2):
        rb = min(ra + 1, m - 1)
        tha = thetas[ra * theta_step]
        thb = thetas[rb * theta_step]
        va, sa, vb, sb = v0, x0, v0, x0
        a_dv = a_e = a_u = a_du = a_viol = a_last = a_first = a_dvn = a_en = 0.0
        b_dv = b_e = b_u = b_du = b_viol = b_last = b_first = b_dvn = b_en = 0.0
        if depth > 0:  # both rows resume after their model prefix (the state its first ``depth`` steps reach)
            va, sa, a_dv, a_e, a_u, a_du, a_viol, a_last, a_first = _resume(pre, seq[ra], depth)
            vb, sb, b_dv, b_e, b_u, b_du, b_viol, b_last, b_first = _resume(pre, seq[rb], depth)
        for j in range(depth, steps):
            xpj, vpj, apj, basej = xp[j], vp[j], ap[j], base[j]
            oa = _omega(va, tr)
            ob = _omega(vb, tr)
            ua = _control(seq[ra, j], tha, va, xpj - sa, basej + va * va * own_k, vpj, apj, oa, tr, feedforward)
            ub = _control(seq[rb, j], thb, vb, xpj - sb, basej + vb * vb * own_k, vpj, apj, ob, tr, feedforward)
            sa = sa + tau * va + half_tau2 * (ua - oa)
            va = va + tau * (ua - oa)
            sb = sb + tau * vb + half_tau2 * (ub - ob)
            vb = vb + tau * (ub - ob)
            a_dv, a_e, a_u, a_du, a_viol, a_first, a_dvn, a_en = _accumulate(
                j, va, sa, ua, xp[j + 1], vp[j + 1], pred[j], b_c2, b_m2, u_lo, u_hi, v_m,
                a_dv, a_e, a_u, a_du, a_viol, a_last, a_first,
            )  # fmt: skip
            b_dv, b_e, b_u, b_du, b_viol, b_first, b_dvn, b_en = _accumulate(
                j, vb, sb, ub, xp[j + 1], vp[j + 1], pred[j], b_c2, b_m2, u_lo, u_hi, v_m,
                b_dv, b_e, b_u, b_du, b_viol, b_last, b_first,
            )  # fmt: skip
            a_last, b_last = ua, ub
        out[ra] = _objective(a_dv, a_e, a_u, a_du, a_viol, a_first, a_dvn, a_en, u_prev, w)
        out[rb] = _objective(b_dv, b_e, b_u, b_du, b_viol, b_first, b_dvn, b_en, u_prev, w)


@njit(cache=True, inline="always")
def _resume(pre, row, depth):  # pragma: no cover - compiled
    """The lane state :func:`prefix_states` stored for the first ``depth`` models of ``row``."""
    i = 0
    for j in range(depth):
        i = i * N_MODELS + row[j]
    p = pre[i]
    return p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8]


@njit(cache=True)
def prefix_states(theta, x0, v0, xp, vp, ap, base, lp, bp, tr, feedforward, depth):  # pragma: no cover - compiled
    """The lane state of :func:`batch_costs` after the first ``depth`` steps of every model prefix under one Θ:
    ``(N_MODELS**depth, 9)``, row ``Σ_j m_j·N_MODELS^(depth−1−j)`` = (v, s, Σ Δv², Σ e², Σ u², Σ Δu², violations,
    u_{depth−1}, u_0), each step the operations of :func:`batch_costs` in the same order (so a row resumed from
    here gets the same cost bit for bit). Why: all rows start from the same state, so a search's ~5,500 rollouts
    repeat the same 3 first steps, 9 second steps, …; depth 7 (3,279 steps here) saves ~7 of 60 steps per row.
    """
    tau = tr[0]
    half_tau2 = 0.5 * tau * tau
    own_k = 1.0 / (2.0 * tr[3])
    b_c2 = 2.0 * tr[3]
    b_m2 = 2.0 * tr[4]
    cur = np.empty((1, 9))
    cur[0, :] = 0.0
    cur[0, 0] = v0
    cur[0, 1] = x0
    for j in range(depth):
        pred = tr[8] + lp - vp[j + 1] * vp[j + 1] / (2.0 * bp)
        nxt = np.empty((cur.shape[0] * N_MODELS, 9))
        for i in range(cur.shape[0]):
            v, s, sdv, se, su, sdu, viol, last, first = cur[i]
            om = _omega(v, tr)
            for m in range(N_MODELS):
                u = _control(m, theta, v, xp[j] - s, base[j] + v * v * own_k, vp[j], ap[j], om, tr, feedforward)
                s1 = s + tau * v + half_tau2 * (u - om)
                v1 = v + tau * (u - om)
                sums = _accumulate(
                    j, v1, s1, u, xp[j + 1], vp[j + 1], pred, b_c2, b_m2, tr[1], tr[2], tr[9],
                    sdv, se, su, sdu, viol, last, first,
                )  # fmt: skip
                k = i * N_MODELS + m
                nxt[k, 0], nxt[k, 1], nxt[k, 7] = v1, s1, u
                nxt[k, 2], nxt[k, 3], nxt[k, 4], nxt[k, 5], nxt[k, 6], nxt[k, 8] = sums[:6]
        cur = nxt
    return cur


@njit(cache=True)
def desired_base(vp, lp, bp, tr):  # pragma: no cover - compiled
    """The predecessor part of D^(e) (Eq. 5) per step: ``L^(s) + L_{i−1} − v_{i−1}²/(2|b^(m)_{i−1}|)``."""
    out = np.empty(vp.shape[0])
    for j in range(vp.shape[0]):
        out[j] = tr[8] + lp - vp[j] * vp[j] / (2.0 * bp)
    return out


@njit(cache=True)
def rollout_rows(seq, thetas, x0, v0, xp, vp, ap, lp, bp, tr, feedforward):  # pragma: no cover - compiled
    """Trajectories of ``seq (P, Np)`` under ``thetas (P, N_THETA)``: returns ``u (P, Np)``, ``v``, ``s (P, Np+1)``."""
    pop, steps = seq.shape
    base = desired_base(vp, lp, bp, tr)
    u = np.empty((pop, steps))
    v = np.empty((pop, steps + 1))
    s = np.empty((pop, steps + 1))
    for r in range(pop):
        _rollout_row(seq[r], thetas[r], x0, v0, xp, vp, ap, base, tr, feedforward, u[r], v[r], s[r])
    return u, v, s


@njit(cache=True)
def population_costs(seq, thetas, x0, v0, xp, vp, ap, lp, bp, tr, w, u_prev, feedforward):  # pragma: no cover
    """J^(DMPC) + penalty (Eq. 14–20) of every row of ``seq (P, Np)`` under ``thetas (P, N_THETA)``, shape ``(P,)``."""
    out = np.empty(seq.shape[0])
    batch_costs(
        seq,
        thetas,
        x0,
        v0,
        xp,
        vp,
        ap,
        desired_base(vp, lp, bp, tr),
        lp,
        bp,
        tr,
        w,
        u_prev,
        feedforward,
        out,
        NO_PREFIX,
        0,
    )
    return out


def batch_context(x0, v0, xp, vp, ap, lp, bp, tr, w, u_prev, feedforward) -> tuple:
    """The arguments of :func:`batch_costs` after ``seq, thetas`` and before ``out``, typed and contiguous once per
    step (the compiled searches call it hundreds of times with them)."""
    vp = np.ascontiguousarray(vp, dtype=float)
    return (
        float(x0),
        float(v0),
        np.ascontiguousarray(xp, dtype=float),
        vp,
        np.ascontiguousarray(ap, dtype=float),
        desired_base(vp, float(lp), float(bp), tr),
        float(lp),
        float(bp),
        tr,
        w,
        float(u_prev),
        bool(feedforward),
    )
