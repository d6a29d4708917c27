"""Paper B's performance measures (spec §2.16, A12), shared by the numpy runner and the engine's carriage plant.

* ``E_u = Σ_i Σ_k u_i(k)²·T`` [N²·s] (reported ×10⁻¹² as ``e_u_1e12``);
* ``E_v``, ``E_x`` (the paper's tables call E_x "E_d"): mean ``|v_r − v_1|`` and ``|x_r − x_1|`` over the samples
  that count (running, not dwelling), against the *time-indexed* expected profile of the section — the paper's
  metric, whatever reference the controller itself tracks;
* ``E_p``: ``|x_stop − x_1|`` where the law itself first brought the train to rest near the stop (the callers find
  that instant), arithmetic mean over the stops;
* the actuator envelope of Table 1 / Eq. (14)–(15): counts of force-box and force-rate violations (beyond a
  relative 1e-6) on the forces the plant received, the largest rate; the rate of the first sample is taken
  against zero force (a train starts unpowered).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from railsim.physics.multipoint import MultipointParams

TOLERANCE = 1e-6  # relative slack before a sample counts as a violation (float round-off of the clipping)


def actuator_metrics(forces_n: np.ndarray, params: MultipointParams, period_s: float) -> dict[str, Any]:
    """Effort and envelope figures of the per-carriage forces ``forces_n`` (K × n, one row per control period)."""
    u = np.asarray(forces_n, dtype=float).reshape(-1, params.n_cars)
    if u.shape[0] == 0:
        return {
            "e_u_1e12": 0.0,
            "max_force_n": 0.0,
            "min_force_n": 0.0,
            "max_force_rate_n_per_s": 0.0,
            "force_violations": 0,
            "rate_violations": 0,
        }
    rate = np.diff(np.vstack([np.zeros((1, params.n_cars)), u]), axis=0) / period_s
    over = (u > params.force_max_n * (1 + TOLERANCE)) | (u < params.force_min_n * (1 + TOLERANCE))
    fast = (rate > params.force_rate_max_n_per_s * (1 + TOLERANCE)) | (
        rate < params.force_rate_min_n_per_s * (1 + TOLERANCE)
    )
    return {
        "e_u_1e12": float(np.sum(u**2) * period_s / 1e12),
        "max_force_n": float(np.max(u)),
        "min_force_n": float(np.min(u)),
        "max_force_rate_n_per_s": float(np.max(np.abs(rate))),
        "force_violations": int(np.sum(over)),
        "rate_violations": int(np.sum(fast)),
    }


def tracking_metrics(
    x1_m: np.ndarray, v1_mps: np.ndarray, x_ref_m: np.ndarray, v_ref_mps: np.ndarray, counts: np.ndarray
) -> dict[str, float]:
    """``e_v_mps`` and ``e_x_m``: mean absolute speed/displacement errors over the samples where ``counts``."""
    m = np.asarray(counts, dtype=bool)
    if not np.any(m):
        return {"e_v_mps": float("nan"), "e_x_m": float("nan")}
    return {
        "e_v_mps": float(np.mean(np.abs(np.asarray(v_ref_mps) - np.asarray(v1_mps))[m])),
        "e_x_m": float(np.mean(np.abs(np.asarray(x_ref_m) - np.asarray(x1_m))[m])),
    }
