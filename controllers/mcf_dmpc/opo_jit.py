"""OPO's compass search compiled: :func:`controllers.mcf_dmpc.opo.opo_step` with the MCF fitness in one numba call
(target: one OPO-MCF-DMPC step ≤ 20 ms at Table II's budget).

What it is: the same bounded compass search as :func:`~controllers.mcf_dmpc.opo.opo_step` — the same polls in the
same order, the same acceptance test, the same step halving — scoring its single-model rollouts with
:func:`controllers.mcf_dmpc.kernels.batch_costs`, the kernel the Python path reaches through
:func:`~controllers.mcf_dmpc.cost.sequence_costs`. A row's cost does not depend on the batch it is scored in, so
both paths return the same Θ, costs and counts bit for bit (``tests/unit/test_paper000_opo_jit.py``).

Why: the Python search makes ~10 rollout calls per step (one per iteration), each rebuilding its arguments and
stacking ~20 rows of Θ in numpy — ~1.5 ms per step, against ~0.2 ms of rollouts. Compiled, it is one call.
"""

from __future__ import annotations

import numpy as np

from controllers.mcf_dmpc.cf_models import MODEL_THETA_INDEX
from controllers.mcf_dmpc.kernels import NO_PREFIX, batch_context, batch_costs, njit
from controllers.mcf_dmpc.opo import OpoResult, OpoSettings, box, finish

__all__ = ["opo_step_compiled"]


def _index_table() -> np.ndarray:
    """MODEL_THETA_INDEX as a ``(models, most parameters)`` int array padded with −1 (numba wants a flat type)."""
    width = max(len(k) for k in MODEL_THETA_INDEX)
    return np.array([list(k) + [-1] * (width - len(k)) for k in MODEL_THETA_INDEX], dtype=np.int64)


_PARAMS = _index_table()


@njit(cache=True)
def _compass(z, lo, span, params, iterations, initial_step, min_step, steps, ctx):  # pragma: no cover - compiled
    """The loop of ``opo_step`` on ``z`` (updated in place); returns (model costs, evaluations, batches)."""
    x0, v0, xp, vp, ap, base, lp, bp, tr, w, u_prev, ff = ctx
    n_models, width = params.shape
    n_theta = z.shape[0]
    rows = max(n_models, 2 * n_models * width)
    seq = np.empty((rows, steps), dtype=np.int64)
    thetas = np.empty((rows, n_theta))
    cand = np.empty((rows, n_theta))
    owner = np.empty(rows, dtype=np.int64)
    costs = np.empty(rows)
    for m in range(n_models):  # the single-model sequences at the warm start
        seq[m, :] = m
        for k in range(n_theta):
            thetas[m, k] = lo[k] + min(max(z[k], 0.0), 1.0) * span[k]
    cost = np.empty(n_models)
    batch_costs(
        seq[:n_models], thetas[:n_models], x0, v0, xp, vp, ap, base, lp, bp, tr, w, u_prev, ff, cost, NO_PREFIX, 0
    )
    evaluations = n_models
    batches = 1
    step = np.full(n_models, initial_step)
    for _ in range(iterations):
        n = 0
        for m in range(n_models):
            if step[m] < min_step:
                continue
            for p in range(width):
                k = params[m, p]
                if k < 0 or span[k] == 0.0:
                    continue
                for sign in (1.0, -1.0):
                    moved = z[k] + sign * step[m]
                    moved = 0.0 if 0.0 > moved else moved  # Python's max(moved, 0.0), then min(·, 1.0)
                    moved = 1.0 if 1.0 < moved else moved
                    if moved != z[k]:
                        cand[n, :] = z
                        cand[n, k] = moved
                        owner[n] = m
                        n += 1
        if n == 0:
            break
        for i in range(n):
            seq[i, :] = owner[i]
            for k in range(n_theta):
                thetas[i, k] = lo[k] + min(max(cand[i, k], 0.0), 1.0) * span[k]
        batch_costs(seq[:n], thetas[:n], x0, v0, xp, vp, ap, base, lp, bp, tr, w, u_prev, ff, costs[:n], NO_PREFIX, 0)
        evaluations += n
        batches += 1
        for m in range(n_models):
            best = -1
            for i in range(n):  # np.argmin over this model's polls: the first minimum (a NaN wins, as in numpy)
                if owner[i] != m:
                    continue
                if best < 0 or costs[i] < costs[best] or (np.isnan(costs[i]) and not np.isnan(costs[best])):
                    best = i
            if best < 0:
                if step[m] >= min_step:
                    step[m] = 0.0  # every poll fell outside the box: nothing left to try
                continue
            if costs[best] < cost[m] - 1e-12 * max(1.0, abs(cost[m])):
                for p in range(width):
                    k = params[m, p]
                    if k >= 0:
                        z[k] = cand[best, k]  # only this model's coordinates: sub-problems stay independent
                cost[m] = costs[best]
            else:
                step[m] *= 0.5
    return cost, evaluations, batches


def opo_step_compiled(theta: np.ndarray, fitness_args: tuple, settings: OpoSettings) -> OpoResult:
    """One OPO update from the warm start ``theta``, as :func:`~controllers.mcf_dmpc.opo.opo_step` with the MCF
    fitness. ``fitness_args`` = ``(x0, v0, xp, vp, ap, lp, bp, train_vector, weight_vector, u_prev, feedforward,
    horizon_steps)``."""
    *batch_args, steps = fitness_args
    lo, span, z = box(theta, settings)
    cost, evaluations, batches = _compass(
        z,
        lo,
        span,
        _PARAMS,
        int(settings.iterations),
        float(settings.initial_step),
        float(settings.min_step),
        int(steps),
        batch_context(*batch_args),
    )
    return finish(lo, span, z, cost, evaluations, batches)
