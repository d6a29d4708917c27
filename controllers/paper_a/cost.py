"""The DMPC objective of Paper A, J^(DMPC) = J^(v) + J^(s) + J^(u) + J^(Δu) + J^(term) (Eq. 14–19), with the
constraints of Eq. (20) as a penalty (A21), evaluated for a batch of predicted trajectories.

With ``Δv_j = v_j − v_{i−1,j}`` and ``e_j = ΔS_j − D^(e)_j`` (front-to-front, Eq. 5)::

    J^(v)    = ξ_v  Σ_{j=1..Np} Δv_j²                                                (14)
    J^(s)    = ξ_s  Σ_{j=1..Np} e_j²                                                 (15)
    J^(u)    = ξ_u  Σ_{j=0..Np−1} u_j²                    (A20: the "i = k" index typo read as j = k)   (16)
    J^(Δu)   = ξ_Δu [Σ_{j=1..Np−1} (u_j − u_{j−1})² + (u_{−1} − u_0)²]  (A19: the previous-control term once) (17)
    J^(term) = ξ_term [ξ_v Δv_Np² + ξ_s e_Np²]            (A18: the weights ξ_v, ξ_s included)        (18)
    penalty  = w Σ_{j=1..Np} [max(0, D^(s)_j − ΔS_j) + max(0, −v_j) + max(0, v_j − v_m)]
               + w Σ_j [max(0, −b^(c) − u_j) + max(0, u_j − a^(m))]                                 (20, A21)

``u_{−1}`` is the control actually applied at the previous step (A19: 0 before the first step). Weights are
Table II (ξ_v 1, ξ_s 0.05, ξ_u 200, ξ_Δu 400, ξ_term 10); the penalty weight w = 1e6 per metre / (m/s) / (m/s²)
of violation (A21 SUGGESTION).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from controllers.paper_a import rollout as _rollout
from controllers.paper_a.cf_models import RATIO_CAP, V_FLOOR_MPS
from controllers.paper_a.rollout import PredecessorHorizon, Trajectory
from controllers.paper_a.spacing import TrainParamsA, desired_spacing_m, safe_spacing_m

__all__ = ["CostWeights", "TABLE_II", "cost_terms", "dmpc_cost", "sequence_costs"]


@dataclass(frozen=True)
class CostWeights:
    """Table II weights and the A21 penalty weight."""

    xi_v: float = 1.0
    xi_s: float = 0.05
    xi_u: float = 200.0
    xi_du: float = 400.0
    xi_term: float = 10.0
    penalty: float = 1.0e6

    def __post_init__(self) -> None:
        for name in ("xi_v", "xi_s", "xi_u", "xi_du", "xi_term", "penalty"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name}: expected a finite number >= 0, got {value!r}")


TABLE_II = CostWeights()
FUSED_MAX_ROWS = 8  # sequence_costs: one plain-float pass up to this many rows (see there)


def cost_terms(traj: Trajectory, pred: PredecessorHorizon, u_prev_mps2: float, train: TrainParamsA,
               weights: CostWeights = TABLE_II) -> dict[str, np.ndarray]:
    """Each term of Eq. (14)–(18) and the penalty, shape ``(P,)``; ``"J"`` is their sum (Eq. 19 + penalty)."""
    u, v, s = traj.u, traj.v[:, 1:], traj.s[:, 1:]
    vp = pred.speed_mps[1:]
    spacing = pred.position_m[1:] - s
    dv = v - vp
    err = spacing - desired_spacing_m(v, vp, train, pred.length_m, pred.emergency_decel_mps2)
    ds = safe_spacing_m(v, vp, train, pred.length_m, pred.emergency_decel_mps2)
    j_v = weights.xi_v * np.sum(dv * dv, axis=1)
    j_s = weights.xi_s * np.sum(err * err, axis=1)
    j_u = weights.xi_u * np.sum(u * u, axis=1)
    du = np.diff(u, axis=1)
    j_du = weights.xi_du * (np.sum(du * du, axis=1) + (u_prev_mps2 - u[:, 0]) ** 2)
    j_term = weights.xi_term * (weights.xi_v * dv[:, -1] ** 2 + weights.xi_s * err[:, -1] ** 2)
    violation = (np.maximum(ds - spacing, 0.0) + np.maximum(-v, 0.0) + np.maximum(v - train.max_speed_mps, 0.0)).sum(1)
    violation += (np.maximum(-train.service_decel_mps2 - u, 0.0) + np.maximum(u - train.max_accel_mps2, 0.0)).sum(1)
    penalty = weights.penalty * violation
    total = j_v + j_s + j_u + j_du + j_term + penalty
    return {"J_v": j_v, "J_s": j_s, "J_u": j_u, "J_du": j_du, "J_term": j_term, "penalty": penalty,
            "violation": violation, "J": total}


def dmpc_cost(traj: Trajectory, pred: PredecessorHorizon, u_prev_mps2: float, train: TrainParamsA,
              weights: CostWeights = TABLE_II) -> np.ndarray:
    """J^(DMPC) + penalty, shape ``(P,)`` (see :func:`cost_terms`)."""
    return cost_terms(traj, pred, u_prev_mps2, train, weights)["J"]


def sequence_costs(seq: np.ndarray, x0_m: float, v0_mps: float, pred: PredecessorHorizon, theta: np.ndarray,
                   train: TrainParamsA, u_prev_mps2: float, weights: CostWeights = TABLE_II, *,
                   resistance_feedforward: bool = False) -> np.ndarray:
    """``dmpc_cost(rollout_models(seq, ...), ...)`` — the optimisers' fitness — shape ``(P,)``.

    For up to :data:`FUSED_MAX_ROWS` rows it runs the rollout and the cost in one
    plain-float pass (no trajectory stored): the greedy refinement (Eq. 28) scores two sequences per call, a few
    hundred calls per control step, where any per-call numpy overhead dominates (measured 3.4x faster than
    rollout + :func:`dmpc_cost` at 2 rows; no gain from ~8 rows on, where numpy's cost over the stored
    trajectories is cheaper than accumulating in Python). Same arithmetic as the two-pass path; sums are accumulated
    in step order, so results agree to rounding (~1e-12 relative), not bit for bit.
    """
    seq = np.atleast_2d(np.asarray(seq, dtype=np.int64))
    theta = np.asarray(theta, dtype=float)
    pop, steps = seq.shape
    if steps != pred.steps:
        raise ValueError(f"sequence length {steps} != predecessor horizon {pred.steps}")
    if pop > FUSED_MAX_ROWS or theta.shape not in ((7,), (pop, 7)):
        traj = _rollout.rollout_models(seq, x0_m, v0_mps, pred, theta, train,
                                       resistance_feedforward=resistance_feedforward)
        return dmpc_cost(traj, pred, u_prev_mps2, train, weights)
    thetas = np.broadcast_to(theta, (pop, 7)).tolist()
    tau = train.dt_s
    half_tau2 = 0.5 * tau * tau
    u_lo, u_hi = -train.service_decel_mps2, train.max_accel_mps2
    a_max, v_max = train.max_accel_mps2, train.max_speed_mps
    c0, c1, c2 = train.davis_c0_mps2, train.davis_c1_per_s, train.davis_c2_per_m
    k_e = 1.0 / (2.0 * train.service_decel_mps2)  # own term of D^(e), Eq. (5)
    k_s = 1.0 / (2.0 * train.emergency_decel_mps2)  # own term of D^(s), Eq. (6)
    xp = pred.position_m.tolist()
    vp_list = pred.speed_mps.tolist()
    ap = pred.accel_mps2.tolist()
    base = [train.safety_margin_m + pred.length_m - v * v / (2.0 * pred.emergency_decel_mps2) for v in vp_list]
    w = weights
    out = np.empty(pop)
    for r, row in enumerate(seq.tolist()):
        th1, th2, th3, th4, th5, th6, th7 = thetas[r]
        vj, sj = float(v0_mps), float(x0_m)
        j_v = j_s = j_u = j_du = viol = 0.0
        u_last = float(u_prev_mps2)
        dv = err = 0.0
        for j, m in enumerate(row):
            vpj = vp_list[j]
            spacing = xp[j] - sj
            vv = vj * vj
            de = base[j] + vv * k_e
            if m == 0:  # enhanced IDM, Eq. (8)
                if spacing > 0.0:
                    speed_term = ((vj if vj > 0.0 else 0.0) / (vpj if vpj > V_FLOOR_MPS else V_FLOOR_MPS)) ** th1
                    ratio = (de if de > 0.0 else 0.0) / spacing
                    a = a_max * (2.0 - speed_term - (ratio if ratio < RATIO_CAP else RATIO_CAP) ** th2)
                else:
                    a = -math.inf
            elif m == 1:  # enhanced CACC, Eq. (10)
                a = th3 * ap[j] + th4 * (spacing - de) + th5 * (vpj - vj)
            else:  # enhanced FVD, Eq. (11)-(13)
                v_star = vpj * (vpj + spacing - de) / (vj if vj > V_FLOOR_MPS else V_FLOOR_MPS)
                a = th6 * (v_star - vj) + (th7 if spacing <= de else 0.0) * (vpj - vj)
            av = vj if vj >= 0.0 else -vj
            omega = c0 + c1 * av + c2 * vv if av != 0.0 else 0.0
            if resistance_feedforward:  # A9 option: the law gives the net acceleration, saturate u = a + ω
                a += omega
            uj = u_lo if a < u_lo else (u_hi if a > u_hi else a)
            acc = uj - omega
            sj = sj + tau * vj + half_tau2 * acc
            vj = vj + tau * acc
            # cost terms at the new state j + 1 (Eq. 14-17) and the Eq. (20) penalty
            vpn = vp_list[j + 1]
            spacing = xp[j + 1] - sj
            vv = vj * vj
            dv = vj - vpn
            err = spacing - (base[j + 1] + vv * k_e)
            gap_s = base[j + 1] + vv * k_s - spacing
            j_v += dv * dv
            j_s += err * err
            j_u += uj * uj
            d_u = uj - u_last
            j_du += d_u * d_u  # j = 0: (u_{-1} - u_0)^2 once (A19); j >= 1: (u_j - u_{j-1})^2
            u_last = uj
            if gap_s > 0.0:
                viol += gap_s
            if vj < 0.0:
                viol -= vj
            elif vj > v_max:
                viol += vj - v_max
        term = w.xi_term * (w.xi_v * dv * dv + w.xi_s * err * err)
        out[r] = w.xi_v * j_v + w.xi_s * j_s + w.xi_u * j_u + w.xi_du * j_du + term + w.penalty * viol
    return out
