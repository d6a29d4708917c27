"""OPO — Online Parameter Optimisation of Paper A (Section III-B, Eq. 29–30): re-tune Θ = [θ1 … θ7] every step.

Eq. (30) minimises J^(DMPC) of the MCF rollout over Θ. The paper decomposes it "into model-specific
subproblems"; reading (A29): three independent low-dimensional problems, each scored by a *single-model*
rollout over the horizon with the same cost and constraint penalty —

* IDM+  over (θ1, θ2, b_IDM),   CACC+ over (θ3, θ4, θ5, b_CACC),   FVD+ over (θ6, θ7, b_FVD).

The control offsets ``b_m`` (ours, :mod:`~controllers.mcf_dmpc.cf_models` docstring) are corrected like any other
parameter; a box of zero width ``[0, 0]`` keeps a parameter fixed (the paper's reading: ``opo_bias: false``).
Why the offsets (measured on the numpy S-D platoon, seed 0): on θ1 … θ7 alone OPO settles at θ4 ≈
0.025 s⁻², θ6 ≈ 0.024 s⁻¹, θ2 ≈ 21, i.e. at a late-phase spacing offset ω/gain ≈ 3.9 m for both followers,
because larger gains make the predicted correction of every noise-driven deviation costlier in ξ_u, ξ_Δu than
the offset they would remove; the DMPC baseline (which sets u = ω directly) holds 0.75–0.9 m.

Solver (the paper names none): a **bounded compass (pattern) search** (Kolda, Lewis & Torczon, SIAM Review 2003)
in box-normalised coordinates ``z = (θ − lo)/(hi − lo) ∈ [0, 1]``. Each iteration polls ``z ± h·e_k`` for every
coordinate of every still-active sub-problem — all polls of the three sub-problems in *one* vectorised rollout
batch — moves to the best poll if it lowers that sub-problem's cost, otherwise halves its step ``h``; a
sub-problem stops when ``h < min_step``. Derivative-free (the saturations and the θ7 switch of Eq. 12 make J
non-smooth in Θ), deterministic, and every poll is projected onto the box, so **Θ never leaves its bounds**.
Warm start: the previous step's Θ (initially Table Θ_2 / Θ_3); bounds default to the A29 SUGGESTION box
(:data:`~controllers.mcf_dmpc.cf_models.THETA_BOUNDS`) and are configurable.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from controllers.mcf_dmpc.cf_models import MODEL_THETA_INDEX, N_THETA, THETA_BOUNDS

__all__ = ["OpoResult", "OpoSettings", "box", "finish", "opo_step"]

# (model-index sequences (P, Np), parameter rows (P, N_THETA)) -> costs (P,)
BatchCost = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class OpoSettings:
    """Compass-search budget and the Θ box (rows θ1 … θ7, b_IDM, b_CACC, b_FVD; columns lower/upper)."""

    iterations: int = 8
    initial_step: float = 0.1  # fraction of each parameter's range
    min_step: float = 1e-3
    bounds: np.ndarray = field(default_factory=lambda: THETA_BOUNDS.copy())

    def __post_init__(self) -> None:
        b = np.asarray(self.bounds, dtype=float)
        if b.shape != (N_THETA, 2) or not np.all(np.isfinite(b)) or np.any(b[:, 1] < b[:, 0]):
            raise ValueError(f"bounds: expected {N_THETA} finite (lower <= upper) pairs, got {self.bounds!r}")
        if int(self.iterations) != self.iterations or self.iterations < 0:
            raise ValueError(f"iterations: expected an integer >= 0, got {self.iterations!r}")
        if not (0.0 < self.initial_step <= 1.0):
            raise ValueError(f"initial_step: expected a number in (0, 1], got {self.initial_step!r}")
        if not (0.0 < self.min_step <= self.initial_step):
            raise ValueError(f"min_step: expected a number in (0, initial_step], got {self.min_step!r}")


@dataclass(frozen=True)
class OpoResult:
    theta: np.ndarray  # (N_THETA,) inside the bounds
    model_costs: np.ndarray  # (3,) single-model J at the returned Θ
    evaluations: int  # rollouts evaluated
    batches: int  # vectorised rollout calls


def box(theta: np.ndarray, settings: OpoSettings) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(lo, span, z)``: the box and the warm start projected onto it in normalised coordinates ``z ∈ [0, 1]``."""
    lo, hi = np.asarray(settings.bounds, dtype=float).T
    span = hi - lo
    safe_span = np.where(span > 0.0, span, 1.0)
    z = np.clip((np.asarray(theta, dtype=float) - lo) / safe_span, 0.0, 1.0)
    return lo, span, np.where(span > 0.0, z, 0.0)


def finish(
    lo: np.ndarray, span: np.ndarray, z: np.ndarray, cost: np.ndarray, evaluations: int, batches: int
) -> OpoResult:
    """The result at ``z``; a non-finite Θ is a bug upstream and raises."""
    theta_out = lo + np.clip(z, 0.0, 1.0) * span
    if not np.all(np.isfinite(theta_out)) or not math.isfinite(float(np.sum(span))):
        raise RuntimeError("OPO produced a non-finite parameter vector")
    return OpoResult(theta_out, cost, int(evaluations), int(batches))


def opo_step(
    theta: np.ndarray, batch_cost: BatchCost, horizon_steps: int, settings: OpoSettings = OpoSettings()
) -> OpoResult:
    """One OPO update from the warm start ``theta`` (projected onto the box first)."""
    lo, span, z = box(theta, settings)

    def to_theta(zz: np.ndarray) -> np.ndarray:
        return lo + np.clip(zz, 0.0, 1.0) * span

    models = range(len(MODEL_THETA_INDEX))
    seq_of = [np.full(horizon_steps, m, dtype=np.int64) for m in models]
    cost = batch_cost(np.stack(seq_of), np.tile(to_theta(z), (3, 1)))
    evaluations, batches = 3, 1
    step = np.full(3, float(settings.initial_step))
    for _ in range(int(settings.iterations)):
        rows_z, owners = [], []
        for m in models:
            if step[m] < settings.min_step:
                continue
            for k in MODEL_THETA_INDEX[m]:
                if span[k] == 0.0:
                    continue
                for sign in (1.0, -1.0):
                    zc = z.copy()
                    zc[k] = min(max(zc[k] + sign * step[m], 0.0), 1.0)
                    if zc[k] != z[k]:
                        rows_z.append(zc)
                        owners.append(m)
        if not rows_z:
            break
        cand_z = np.stack(rows_z)
        owners_arr = np.array(owners)
        costs = batch_cost(np.stack([seq_of[m] for m in owners]), to_theta(cand_z))
        evaluations += len(owners)
        batches += 1
        for m in models:
            mine = np.flatnonzero(owners_arr == m)
            if mine.size == 0:
                if step[m] >= settings.min_step:
                    step[m] = 0.0  # every poll fell outside the box: nothing left to try
                continue
            best = mine[int(np.argmin(costs[mine]))]
            if costs[best] < cost[m] - 1e-12 * max(1.0, abs(cost[m])):
                idx = list(MODEL_THETA_INDEX[m])
                z[idx] = cand_z[best, idx]  # only this model's coordinates: sub-problems stay independent
                cost[m] = costs[best]
            else:
                step[m] *= 0.5
    return finish(lo, span, z, cost, evaluations, batches)
