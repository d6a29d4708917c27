"""Paper A (spec 000 §2.4) car-following laws: enhanced IDM (Eq. 8), CACC (Eq. 10), FVD (Eq. 11–13) and the
original IDM (Eq. 7) / CACC (Eq. 9) they were derived from.

All functions are element-wise numpy: every argument broadcasts, so one call evaluates a law for a whole
population of candidate model sequences (or parameter vectors) in an MPC rollout. Symbols: ``v`` own speed,
``v_pred`` predecessor speed, ``spacing_m`` front-to-front ΔS, ``desired_m`` D^(e) (Eq. 5), ``a_pred`` the
predecessor's acceleration.

The enhanced laws are built so that their equilibrium is exactly ``v = v_pred, ΔS = D^(e)`` with output 0::

    IDM+  (model 1)  a = a_m·(2 − (v/v_pred)^θ1 − (D^(e)/ΔS)^θ2)                                         (8)
    CACC+ (model 2)  a = θ3·a_pred + θ4·(ΔS − D^(e)) + θ5·(v_pred − v)                                   (10)
    FVD+  (model 3)  a = θ6·(v* − v) + θ·(v_pred − v),  θ = θ7 if ΔS ≤ D^(e) else 0                    (11, 12)
                     v* = v_pred·(v_pred + ΔS − D^(e))/v                                                 (13)

Readings of the ambiguities:

* A9/A10 — the law's output is the *control* u (applied specific force), saturated to ``[−b^(c), a^(m)]`` =
  ``[−0.8, 1.0]`` m/s²; the plant subtracts the running resistance. So under resistance each law settles at a
  spacing offset where its output equals ω(v): IDM+ at ``ΔS = D^(e)·(1 − ω/a_m)^(−1/θ2)`` (6.88 m at 220 km/h
  with θ2 = 12.1), CACC+ at ``ΔS − D^(e) = (ω − θ3·a_pred)/θ4``, FVD+ at ``ΔS − D^(e) = ω/θ6``.
* A11 — numerical guards: ΔS ≤ 0 gives maximum braking (IDM+); ``v_pred`` and ``v`` are floored at 0.1 m/s in
  the denominators of (8) and (13); D^(e) < 0 (possible when the predecessor is much faster) counts as 0 in the
  IDM ratio so that a fractional power never sees a negative base; the spacing ratio is capped at 10³ before the
  power (with θ2 ≥ 2 the output is then far below −b^(c) and saturates anyway), which keeps θ2 up to 40 finite.
* A12 — Eq. (13) adds m/s to m; implemented as printed.
* A14 — model indices: 0 = IDM, 1 = CACC, 2 = FVD in code (the paper's 1, 2, 3).
* A35 — the original models' δ (Eq. 7) and t_g (Eq. 9) are not in the paper: δ = 4, t_g = 1.5 s by default.

**Control offsets (ours; not in the paper).** Θ carries three more entries after θ1 … θ7: an offset
``b_m`` [m/s²] per law, added to the law's output before the saturation, ``u = sat(a_m(…; Θ) + b_m)``. With
``b_m = 0`` (the Table values, MCF-DMPC, CF-DMPC) the laws are exactly the paper's. OPO may correct them online
(:mod:`controllers.mcf_dmpc.opo`): under the reading A9 above each law can only hold the running resistance by
sitting at a spacing offset ``ω/gain``, and the J^(DMPC)-optimal gains over the horizon stay moderate (OPO on
θ1 … θ7 alone settles S-D's late phase at ~3.9 m); an online offset lets the same cost remove the offset itself.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

__all__ = [
    "MODEL_CACC",
    "MODEL_FVD",
    "MODEL_IDM",
    "MODEL_NAMES",
    "MODEL_THETA_INDEX",
    "N_THETA",
    "THETA_BOUNDS",
    "THETA_TRAIN2",
    "THETA_TRAIN3",
    "CfTheta",
    "all_models",
    "enhanced_cacc",
    "enhanced_fvd",
    "enhanced_idm",
    "original_cacc",
    "original_idm",
    "saturate",
]

MODEL_IDM, MODEL_CACC, MODEL_FVD = 0, 1, 2
MODEL_NAMES = ("idm", "cacc", "fvd")
# Which entries of Θ = [θ1 … θ7, b_IDM, b_CACC, b_FVD] (0-based) each model uses: the OPO decomposition (Section
# III-B), each law with its own control offset (ours, module docstring).
MODEL_THETA_INDEX: tuple[tuple[int, ...], ...] = ((0, 1, 7), (2, 3, 4, 8), (5, 6, 9))
N_THETA = 10
BIAS_INDEX = 7  # Θ[BIAS_INDEX + m] is law m's control offset

V_FLOOR_MPS = 0.1  # A11 denominator floor [m/s]
RATIO_CAP = 1.0e3  # A11 cap of D^(e)/ΔS before the power θ2


@dataclass(frozen=True)
class CfTheta:
    """Θ = [θ1 … θ7] of the three enhanced laws (units: θ4 1/s², θ5–θ7 1/s, the rest dimensionless)."""

    theta1: float  # IDM velocity exponent
    theta2: float  # IDM spacing exponent
    theta3: float  # CACC predecessor-acceleration gain
    theta4: float  # CACC spacing gain [1/s²]
    theta5: float  # CACC velocity gain [1/s]
    theta6: float  # FVD optimal-velocity gain [1/s]
    theta7: float  # FVD close-range relative-speed gain [1/s]
    bias_idm_mps2: float = 0.0  # control offsets (ours, module docstring): 0 = the paper's laws
    bias_cacc_mps2: float = 0.0
    bias_fvd_mps2: float = 0.0

    def as_array(self) -> np.ndarray:
        return np.array([getattr(self, f.name) for f in fields(self)], dtype=float)

    @classmethod
    def from_array(cls, values: np.ndarray) -> CfTheta:
        return cls(*(float(x) for x in np.asarray(values, dtype=float).ravel()[:N_THETA]))


THETA_TRAIN2 = CfTheta(1.2, 12.1, 0.0, 0.011, 0.013, 0.012, 4.2e-4)  # Θ_2 (Section IV-A)
THETA_TRAIN3 = CfTheta(1.4, 16.7, 0.35, 0.012, 0.015, 0.015, 4.3e-4)  # Θ_3
# OPO search box (lower, upper): θ1 … θ7 the A29 SUGGESTION; the control offsets ±0.2 m/s² (ours: ω(350 km/h)
# = 0.18 m/s², the largest force a law must hold at equilibrium on the flat)
THETA_BOUNDS = np.array(
    [[0.5, 5.0], [2.0, 40.0], [0.0, 1.0], [1e-3, 0.1], [1e-3, 0.1], [1e-3, 0.1], [0.0, 1e-2]] + [[-0.2, 0.2]] * 3
)


def saturate(u: np.ndarray, u_min: float = -0.8, u_max: float = 1.0) -> np.ndarray:
    """Clip to ``[u_min, u_max]`` (A10: the bounds of Eq. 20)."""
    return np.clip(u, u_min, u_max)


def enhanced_idm(
    v,
    v_pred,
    spacing_m,
    desired_m,
    theta1,
    theta2,
    a_max: float = 1.0,
    u_min: float | None = -0.8,
    u_max: float | None = 1.0,
) -> np.ndarray:
    """Enhanced IDM, Eq. (8); ``u_min=None`` returns the unsaturated law (ΔS ≤ 0 then gives −inf)."""
    v = np.maximum(np.asarray(v, dtype=float), 0.0)
    s = np.asarray(spacing_m, dtype=float)
    speed_term = (v / np.maximum(v_pred, V_FLOOR_MPS)) ** np.asarray(theta1, dtype=float)
    positive = s > 0.0
    with np.errstate(over="ignore", divide="ignore"):  # a vanishing ΔS gives inf, capped next
        ratio = np.minimum(np.maximum(desired_m, 0.0) / np.where(positive, s, 1.0), RATIO_CAP)
    spacing_term = ratio ** np.asarray(theta2, dtype=float)
    a = a_max * (2.0 - speed_term - spacing_term)
    a = np.where(positive, a, -np.inf)
    return _maybe_saturate(a, u_min, u_max)


def enhanced_cacc(
    v,
    v_pred,
    spacing_m,
    desired_m,
    a_pred,
    theta3,
    theta4,
    theta5,
    u_min: float | None = -0.8,
    u_max: float | None = 1.0,
) -> np.ndarray:
    """Enhanced CACC, Eq. (10): feed-forward + spacing error to D^(e) + relative speed."""
    a = (
        theta3 * np.asarray(a_pred, dtype=float)
        + theta4 * (np.asarray(spacing_m, dtype=float) - desired_m)
        + theta5 * (np.asarray(v_pred, dtype=float) - v)
    )
    return _maybe_saturate(a, u_min, u_max)


def enhanced_fvd(
    v, v_pred, spacing_m, desired_m, theta6, theta7, u_min: float | None = -0.8, u_max: float | None = 1.0
) -> np.ndarray:
    """Enhanced FVD, Eq. (11)–(13): optimal velocity v* of Eq. (13), close-range gain θ7 only when ΔS ≤ D^(e)."""
    v = np.asarray(v, dtype=float)
    vp = np.asarray(v_pred, dtype=float)
    s = np.asarray(spacing_m, dtype=float)
    v_star = vp * (vp + s - desired_m) / np.maximum(v, V_FLOOR_MPS)
    close_gain = np.where(s <= desired_m, theta7, 0.0)
    a = theta6 * (v_star - v) + close_gain * (vp - v)
    return _maybe_saturate(a, u_min, u_max)


def original_idm(
    v,
    desired_speed_mps,
    spacing_m,
    desired_m,
    a_max: float = 1.0,
    delta: float = 4.0,
    u_min: float | None = -0.8,
    u_max: float | None = 1.0,
) -> np.ndarray:
    """Original IDM as printed in Eq. (7): at v = v^(d), ΔS = D^(e) it gives −a_m (why it cannot couple)."""
    v = np.maximum(np.asarray(v, dtype=float), 0.0)
    s = np.asarray(spacing_m, dtype=float)
    positive = s > 0.0
    with np.errstate(over="ignore", divide="ignore"):
        ratio = np.minimum(np.maximum(desired_m, 0.0) / np.where(positive, s, 1.0), RATIO_CAP)
    a = a_max * (1.0 - (v / np.maximum(desired_speed_mps, V_FLOOR_MPS)) ** delta - ratio**2)
    return _maybe_saturate(np.where(positive, a, -np.inf), u_min, u_max)


def original_cacc(
    v,
    v_pred,
    spacing_m,
    a_pred,
    theta3,
    theta4,
    theta5,
    pred_length_m: float,
    safety_margin_m: float,
    time_gap_s: float = 1.5,
    u_min: float | None = -0.8,
    u_max: float | None = 1.0,
) -> np.ndarray:
    """Original constant-time-gap CACC, Eq. (9): spacing target ``t_g·v + L^(t)_{i−1} + L^(s)``."""
    v = np.asarray(v, dtype=float)
    a = (
        theta3 * np.asarray(a_pred, dtype=float)
        + theta4 * (np.asarray(spacing_m, dtype=float) - time_gap_s * v - pred_length_m - safety_margin_m)
        + theta5 * (np.asarray(v_pred, dtype=float) - v)
    )
    return _maybe_saturate(a, u_min, u_max)


def all_models(
    v,
    v_pred,
    spacing_m,
    desired_m,
    a_pred,
    theta: np.ndarray,
    a_max: float = 1.0,
    u_min: float = -0.8,
    u_max: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The three saturated enhanced laws at once, each plus its control offset; ``theta`` is ``(N_THETA,)`` or
    ``(..., N_THETA)`` (broadcast over rows; 7 entries: no offsets)."""
    th = np.asarray(theta, dtype=float)
    t = [th[..., k] for k in range(7)]
    b = [th[..., BIAS_INDEX + m] if th.shape[-1] > BIAS_INDEX + m else 0.0 for m in range(3)]
    laws = (
        enhanced_idm(v, v_pred, spacing_m, desired_m, t[0], t[1], a_max, None, None),
        enhanced_cacc(v, v_pred, spacing_m, desired_m, a_pred, t[2], t[3], t[4], None, None),
        enhanced_fvd(v, v_pred, spacing_m, desired_m, t[5], t[6], None, None),
    )
    return tuple(_maybe_saturate(a + bm, u_min, u_max) for a, bm in zip(laws, b))  # type: ignore[return-value]


def _maybe_saturate(a: np.ndarray, u_min: float | None, u_max: float | None) -> np.ndarray:
    if u_min is None and u_max is None:
        return a
    lo = -np.inf if u_min is None else u_min
    hi = np.inf if u_max is None else u_max
    return np.clip(a, lo, hi)
