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

from controllers.mcf_dmpc import kernels as _kernels, rollout as _rollout
from controllers.mcf_dmpc.cf_models import N_THETA
from controllers.mcf_dmpc.rollout import PredecessorHorizon, Trajectory
from controllers.mcf_dmpc.spacing import TrainParamsA, desired_spacing_m, safe_spacing_m

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


def cost_terms(
    traj: Trajectory, pred: PredecessorHorizon, u_prev_mps2: float, train: TrainParamsA, weights: CostWeights = TABLE_II
) -> dict[str, np.ndarray]:
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
    return {
        "J_v": j_v,
        "J_s": j_s,
        "J_u": j_u,
        "J_du": j_du,
        "J_term": j_term,
        "penalty": penalty,
        "violation": violation,
        "J": total,
    }


def dmpc_cost(
    traj: Trajectory, pred: PredecessorHorizon, u_prev_mps2: float, train: TrainParamsA, weights: CostWeights = TABLE_II
) -> np.ndarray:
    """J^(DMPC) + penalty, shape ``(P,)`` (see :func:`cost_terms`)."""
    return cost_terms(traj, pred, u_prev_mps2, train, weights)["J"]


def sequence_costs(
    seq: np.ndarray,
    x0_m: float,
    v0_mps: float,
    pred: PredecessorHorizon,
    theta: np.ndarray,
    train: TrainParamsA,
    u_prev_mps2: float,
    weights: CostWeights = TABLE_II,
    *,
    resistance_feedforward: bool = False,
) -> np.ndarray:
    """``dmpc_cost(rollout_models(seq, ...), ...)`` — the optimisers' fitness — shape ``(P,)``.

    With numba available the rollout and the cost run fused in the compiled kernel of
    :mod:`controllers.mcf_dmpc.kernels` (the optimisers' hot path: ~9,000 rows per MCF step); otherwise
    :func:`rollout_models` (plain floats for small batches, numpy for large) and :func:`dmpc_cost` score them.
    Both give the same costs to rounding (``tests/unit/test_paper000_kernels.py``).
    """
    seq = np.atleast_2d(np.asarray(seq, dtype=np.int64))
    if seq.shape[1] != pred.steps:
        raise ValueError(f"sequence length {seq.shape[1]} != predecessor horizon {pred.steps}")
    theta = np.asarray(theta, dtype=float)
    if _kernels.NUMBA_AVAILABLE and theta.shape in ((N_THETA,), (seq.shape[0], N_THETA)):
        # compiled fused rollout + cost (same arithmetic, pinned to the scalar path in test_paper000_kernels)
        thetas = np.ascontiguousarray(np.broadcast_to(theta, (seq.shape[0], N_THETA)))
        return _kernels.population_costs(
            np.ascontiguousarray(seq),
            thetas,
            float(x0_m),
            float(v0_mps),
            np.ascontiguousarray(pred.position_m, dtype=float),
            np.ascontiguousarray(pred.speed_mps, dtype=float),
            np.ascontiguousarray(pred.accel_mps2, dtype=float),
            float(pred.length_m),
            float(pred.emergency_decel_mps2),
            _kernels.train_vector(train),
            _kernels.weight_vector(weights),
            float(u_prev_mps2),
            bool(resistance_feedforward),
        )
    traj = _rollout.rollout_models(seq, x0_m, v0_mps, pred, theta, train, resistance_feedforward=resistance_feedforward)
    return dmpc_cost(traj, pred, u_prev_mps2, train, weights)
