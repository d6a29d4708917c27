"""MSMFO fused with the MCF cost and compiled: the per-step sequence search of ``mcf_dmpc`` / ``opo_mcf_dmpc``
in one numba call (issue 19: one OPO-MCF-DMPC step ≤ 20 ms at Table II's budget).

What it is: :func:`controllers.mcf_dmpc.optim.mothflame.run_mothflame` with the MSMFO defaults (cyclic rounding
Eq. 21, chaotic initialisation Eq. 22 "suggested", EOBL Eq. 23 after initialisation and every iteration, flame
count Eq. 24 "suggested", mutation Eq. 25–26 "suggested", modified spiral Eq. 27, greedy refinement Eq. 28, no
evaluation budget) and the fitness of :meth:`controllers.mcf_dmpc.controller.McfDmpc._select` (the rollout and
J^(DMPC) of :func:`controllers.mcf_dmpc.kernels.batch_costs`), written as one compiled loop. It draws the *same*
random numbers from the same :class:`numpy.random.Generator` in the same order (numba runs numpy's bit generator),
so for a given generator state it returns the same best sequence, cost and evaluation count as the Python
optimiser — ``tests/test_paper000_msmfo_jit.py`` pins this — and leaves the generator in the same state.

Why it is fast (measured, see ``benchmarks/controllers_000.py``): the Python optimiser spends ~60 % of a step in
interpreter and numpy call overhead (~400 fitness calls, ~100 iterations of array bookkeeping), and evaluates
~8,800 rows of which about half repeat a row already scored in the same step (moths sitting on their flames, EOBL
opposites, greedy candidates). Here the loop has no interpreter overhead, and a row already scored in this call
is looked up instead of rolled out again (the fitness is deterministic within a step, so the result is the same;
rows are keyed exactly, base ``n`` digits packed in four 64-bit words, so no hash collision can return a wrong
cost); the optimiser still *counts* every evaluation, as the Python one does. Positions are kept as integer
cells in the paper's frame {1, …, n} (cyclic rounding always lands there).

Used when numba is importable and the controller runs the default MSMFO (``optimizer: msmfo``, no custom
sequence optimiser); anything else goes through :func:`controllers.mcf_dmpc.optim.minimize_sequence`.
"""

from __future__ import annotations

import math

import numpy as np

from controllers.mcf_dmpc.kernels import NUMBA_AVAILABLE, batch_costs, desired_base, njit

__all__ = ["NUMBA_AVAILABLE", "msmfo_mcf"]

_KEY_WORDS = 4


@njit(cache=True)
def _key(row, n_values, digits_per_word):  # pragma: no cover - compiled
    """The row packed exactly into four int64 words (base ``n_values``); requires ``D ≤ 4·digits_per_word``."""
    k0 = 0
    k1 = 0
    k2 = 0
    k3 = 0
    for d in range(row.shape[0]):
        w = d // digits_per_word
        if w == 0:
            k0 = k0 * n_values + row[d]
        elif w == 1:
            k1 = k1 * n_values + row[d]
        elif w == 2:
            k2 = k2 * n_values + row[d]
        else:
            k3 = k3 * n_values + row[d]
    return (k0, k1, k2, k3)


@njit(cache=True)
def _cyclic(x, lb, period):  # pragma: no cover - compiled
    """Eq. (21) on one value: ``(⌊x⌋ − lb) mod period + lb`` (non-negative modulo)."""
    f = math.floor(x)
    if not math.isfinite(f):
        raise ValueError("msmfo: non-finite position")
    return (int(f) - lb) % period + lb


@njit(cache=True)
def _score(pos, lb, memo, stats, best, ctx, full):  # pragma: no cover - compiled
    """Costs of the integer positions ``pos (m, D)`` (paper frame); updates the evaluator's best (first found wins
    on ties, strict improvement) and counts ``stats[0]`` evaluations, ``stats[1]`` rollouts.

    Rows not seen before in this call are rolled out together (:func:`~controllers.mcf_dmpc.kernels.batch_costs`);
    a row repeated within the batch is rolled out once.
    """
    theta, x0, v0, xp, vp, ap, base, lp, bp, tr, w, u_prev, ff, n_values, dpw = ctx
    m, dim = pos.shape
    steps = full.shape[1]
    out = np.empty(m)
    slot = np.empty(m, dtype=np.int64)  # -1: known cost in out[r]; else the row of the batch to roll out
    keys = []
    n_new = 0
    pending = dict()
    pending[(-1, -1, -1, -1)] = -1  # fixes the dict's types; no real key is negative
    for r in range(m):
        for d in range(dim):
            full[n_new, d] = pos[r, d] - lb
        key = _key(full[n_new, :dim], n_values, dpw)
        keys.append(key)
        if key in memo:
            out[r] = memo[key]
            slot[r] = -1
        elif key in pending:
            slot[r] = pending[key]
        else:
            for d in range(dim, steps):  # move blocking (decision_dim < Np): hold the last index
                full[n_new, d] = full[n_new, dim - 1]
            pending[key] = n_new
            slot[r] = n_new
            n_new += 1
    if n_new > 0:
        costs = np.empty(n_new)
        thetas = np.empty((n_new, theta.shape[0]))
        for i in range(n_new):
            thetas[i] = theta
        batch_costs(full[:n_new], thetas, x0, v0, xp, vp, ap, base, lp, bp, tr, w, u_prev, ff, costs)
        stats[1] += n_new
        for r in range(m):
            if slot[r] >= 0:
                out[r] = costs[slot[r]]
                memo[keys[r]] = out[r]
    for r in range(m):
        c = out[r]
        if math.isnan(c):
            raise ValueError("msmfo: the fitness returned NaN")
        stats[0] += 1
        if c < best[0]:
            best[0] = c
            for d in range(dim):
                best[1 + d] = pos[r, d]
    return out


@njit(cache=True)
def _eobl(M, fM, rng, P, lb, ub, period, n_elite, memo, stats, best, ctx, full):  # pragma: no cover
    """Eq. (23): opposites of the best ``n_elite`` moths, merged, best P kept (stable ranking)."""
    dim = M.shape[1]
    order = np.argsort(fM, kind="mergesort")[:n_elite]
    r2 = rng.random((n_elite, dim))
    opp = np.empty((n_elite, dim), dtype=np.int64)
    for e in range(n_elite):
        for d in range(dim):
            opp[e, d] = _cyclic(r2[e, d] * (lb + ub) - M[order[e], d], lb, period)
    f_opp = _score(opp, lb, memo, stats, best, ctx, full)
    pool = np.concatenate((M, opp))
    f_pool = np.concatenate((fM, f_opp))
    keep = np.argsort(f_pool, kind="mergesort")[:P]
    return pool[keep].copy(), f_pool[keep].copy()


@njit(cache=True)
def _flame_count(progress, n0):  # pragma: no cover - compiled
    """Eq. (24), the suggested grouping (:func:`controllers.mcf_dmpc.optim.mothflame.flame_count`)."""
    count = math.floor(n0 - 0.5 * (n0 - 1) * (math.tanh(0.1 * (progress - 0.5) * n0) + 1.0))
    return min(max(count, 1), n0)


@njit(cache=True)
def _search(init, rng, P, K, dim, n_values, alpha, beta, elite_fraction, max_passes, ctx, full):  # pragma: no cover
    lb = 1
    ub = n_values
    period = n_values
    memo = dict()
    memo[(-1, -1, -1, -1)] = 0.0  # fixes the dict's types; no real key is negative
    stats = np.zeros(2, dtype=np.int64)
    best = np.empty(1 + dim)
    best[0] = np.inf
    # --- chaotic initialisation, Eq. (22) (suggested: Logistic–Tent map mod 1, one stream per dimension) ---
    M = np.empty((P, dim), dtype=np.int64)
    r1 = rng.uniform(0.0, 4.0)
    c = rng.random(dim)
    for d in range(dim):
        M[0, d] = _cyclic(lb + c[d] * n_values, lb, period)
    tent = 0.5 * (4.0 - r1)
    for p in range(1, P):
        stuck = 0
        for d in range(dim):
            x = c[d]
            y = r1 * x * (1.0 - x) + tent * (x if x < 0.5 else 1.0 - x)
            c[d] = y % 1.0
            if c[d] <= 1e-12:
                stuck += 1
        if stuck > 0:  # 0 is absorbing: re-seed those streams (same draws as the Python reader)
            fresh = rng.random(stuck)
            k = 0
            for d in range(dim):
                if c[d] <= 1e-12:
                    c[d] = fresh[k]
                    k += 1
        for d in range(dim):
            M[p, d] = _cyclic(lb + c[d] * n_values, lb, period)
    for i in range(init.shape[0]):
        for d in range(dim):
            M[i, d] = init[i, d] + lb
    n_elite = math.ceil(elite_fraction * P)
    fM = _score(M, lb, memo, stats, best, ctx, full)
    if n_elite > 0:
        M, fM = _eobl(M, fM, rng, P, lb, ub, period, n_elite, memo, stats, best, ctx, full)
    order = np.argsort(fM, kind="mergesort")
    F = M[order].copy()
    fF = fM[order].copy()
    spiral = 2.0 * beta * math.pi
    # --- main loop ---
    for k in range(1, K + 1):
        tau = min(k / K, 1.0)
        n_flames = _flame_count(tau, P)
        r = -1.0 - tau
        rs = rng.uniform(r, 1.0, (P, dim))
        for p in range(P):
            t = F[min(p, n_flames - 1)]
            for d in range(dim):
                dist = abs(t[d] - M[p, d])
                if dist == 0:
                    M[p, d] = t[d]  # 0·e^x·sin(y) + F = F: the moth stays on its flame (Eq. 27)
                else:
                    x = dist * math.exp(alpha * rs[p, d]) * math.sin(spiral * (rs[p, d] - r)) + t[d]
                    M[p, d] = _cyclic(x, lb, period)
        fM = _score(M, lb, memo, stats, best, ctx, full)
        if n_elite > 0:
            M, fM = _eobl(M, fM, rng, P, lb, ub, period, n_elite, memo, stats, best, ctx, full)
        pool = np.concatenate((F, M))
        f_pool = np.concatenate((fF, fM))
        keep = np.argsort(f_pool, kind="mergesort")[:P]
        F = pool[keep].copy()
        fF = f_pool[keep].copy()
        # --- adaptive flame mutation, Eq. (25)-(26) (suggested: random term restored) ---
        rg = 1.0 - math.sin(0.5 * math.pi * tau)
        trig = rng.random(n_flames)
        hits = np.flatnonzero(trig <= rg)
        if hits.size > 0:
            scale = rg * (ub - lb) * (1.0 - tau)
            noise = rng.uniform(-1.0, 1.0, (hits.size, dim))
            mutant = np.empty((hits.size, dim), dtype=np.int64)
            for h in range(hits.size):
                for d in range(dim):
                    mutant[h, d] = _cyclic(F[hits[h], d] + scale * noise[h, d], lb, period)
            f_mut = _score(mutant, lb, memo, stats, best, ctx, full)
            changed = False
            for h in range(hits.size):
                if f_mut[h] < fF[hits[h]]:
                    F[hits[h]] = mutant[h]
                    fF[hits[h]] = f_mut[h]
                    changed = True
            if changed:
                order = np.argsort(fF, kind="mergesort")
                F = F[order].copy()
                fF = fF[order].copy()
    # --- greedy coordinate descent on the best, Eq. (28) ---
    m = np.empty((1, dim), dtype=np.int64)
    for d in range(dim):
        m[0, d] = int(best[1 + d])
    cost = best[0]
    cands = np.empty((n_values - 1, dim), dtype=np.int64)
    for _ in range(max_passes):
        changed = False
        for d in rng.permutation(dim):
            i = 0
            for value in range(lb, ub + 1):
                if value != m[0, d]:
                    cands[i] = m[0]
                    cands[i, d] = value
                    i += 1
            costs = _score(cands, lb, memo, stats, best, ctx, full)
            j = np.argmin(costs)
            if costs[j] < cost:
                m[0] = cands[j]
                cost = costs[j]
                changed = True
        if not changed:
            break
    out = np.empty(dim, dtype=np.int64)
    for d in range(dim):
        out[d] = int(best[1 + d]) - lb
    return out, best[0], stats[0], stats[1]


def msmfo_mcf(
    fitness_args: tuple,
    dim: int,
    n_values: int,
    *,
    population: int,
    iterations: int,
    rng: np.random.Generator,
    init: np.ndarray | None = None,
    alpha: float = 0.5,
    beta: float = 4.0,
    elite_fraction: float = 0.4,
    max_passes: int = 10,
) -> tuple[np.ndarray, float, int, int]:
    """Best zero-based sequence ``(D,)``, its cost, evaluations counted, rollouts actually run.

    ``fitness_args`` = ``(theta (N_THETA,), x0, v0, xp, vp, ap, lp, bp, train_vector, weight_vector, u_prev,
    feedforward, horizon_steps)``: the arguments of :func:`controllers.mcf_dmpc.kernels.population_costs` for one
    Θ, plus the horizon the ``D`` decision variables expand to (move blocking holds the last index).
    """
    theta, x0, v0, xp, vp, ap, lp, bp, tr, w, u_prev, ff, steps = fitness_args
    digits_per_word = int(math.floor(62.0 / math.log2(max(n_values, 2))))
    if dim > _KEY_WORDS * digits_per_word:
        raise ValueError(f"msmfo_mcf: dim {dim} too large for exact row keys (max {_KEY_WORDS * digits_per_word})")
    xp = np.ascontiguousarray(xp, dtype=float)
    vp = np.ascontiguousarray(vp, dtype=float)
    ap = np.ascontiguousarray(ap, dtype=float)
    base = desired_base(vp, float(lp), float(bp), tr)
    ctx = (
        np.ascontiguousarray(theta, dtype=float),
        float(x0),
        float(v0),
        xp,
        vp,
        ap,
        base,
        float(lp),
        float(bp),
        tr,
        w,
        float(u_prev),
        bool(ff),
        int(n_values),
        digits_per_word,
    )
    warm = np.zeros((0, dim), dtype=np.int64) if init is None else np.ascontiguousarray(init, dtype=np.int64)
    full = np.empty((max(population, 2 * n_values), int(steps)), dtype=np.int64)  # the rows of one batch
    best, cost, evaluations, rollouts = _search(
        warm, rng, population, iterations, dim, n_values, alpha, beta, elite_fraction, max_passes, ctx, full
    )
    return best, float(cost), int(evaluations), int(rollouts)
