"""MSMFO fused with the MCF cost and compiled: the per-step sequence search of ``mcf_dmpc`` / ``opo_mcf_dmpc``
in one numba call (target: one OPO-MCF-DMPC step ≤ 20 ms at Table II's budget).

What it is: :func:`controllers.mcf_dmpc.optim.mothflame.run_mothflame` with the MSMFO defaults (cyclic rounding
Eq. 21, chaotic initialisation Eq. 22 "suggested", EOBL Eq. 23 after initialisation and every iteration, flame
count Eq. 24 "suggested", mutation Eq. 25–26 "suggested", modified spiral Eq. 27, greedy refinement Eq. 28, no
evaluation budget) and the fitness of :meth:`controllers.mcf_dmpc.controller.McfDmpc._select` (the rollout and
J^(DMPC) of :func:`controllers.mcf_dmpc.kernels.batch_costs`), written as one compiled loop. It draws the *same*
random numbers from the same :class:`numpy.random.Generator` in the same order (numba runs numpy's bit generator),
so for a given generator state it returns the same best sequence, cost and evaluation count as the Python
optimiser — ``tests/unit/test_paper000_msmfo_jit.py`` pins this — and leaves the generator in the same state.

Why it is fast (measured, see ``benchmarks/controllers_000.py``): the Python optimiser spends ~60 % of a step in
interpreter and numpy call overhead (~400 fitness calls, ~100 iterations of array bookkeeping), and evaluates
~8,800 rows of which about half repeat a row already scored in the same step (moths sitting on their flames, EOBL
opposites, greedy candidates). Here the loop has no interpreter overhead, and a row already scored in this call
is looked up instead of rolled out again (the fitness is deterministic within a step, so the result is the same;
rows are keyed exactly, base ``n`` digits packed in four 64-bit words, so no hash collision can return a wrong
cost); the optimiser still *counts* every evaluation, as the Python one does. All rows start from the same state,
so their first steps repeat: the states after every model prefix of ``PREFIX_DEPTH`` (7) steps are computed once
per search (:func:`controllers.mcf_dmpc.kernels.prefix_states`, 3,279 steps) and every row resumes from its
prefix's state — the same operations in the same order, so the same costs — skipping 7 of its 60 steps
(measured: search time 0.88–0.98× in three A/B rounds on captured Table II searches). Positions are kept as
integer cells in the paper's frame {1, …, n} (cyclic rounding always lands there).

Used when numba is importable and the controller runs the default MSMFO (``optimizer: msmfo``, no custom
sequence optimiser); anything else goes through :func:`controllers.mcf_dmpc.optim.minimize_sequence`.
"""

from __future__ import annotations

import math

import numpy as np

from controllers.mcf_dmpc.kernels import N_MODELS, NUMBA_AVAILABLE, batch_context, batch_costs, njit, prefix_states

__all__ = ["NUMBA_AVAILABLE", "msmfo_mcf"]


PREFIX_DEPTH = 7  # model prefixes whose states are computed once per search (3**7 = 2,187; ~7 of 60 steps a row)
_SCORED = -1  # an entry whose cost is known; an entry >= 0 is pending: that row of the current batch
_MIX = 0x9E3779B97F4A7C15 - (1 << 64)  # Fibonacci hashing constant as an int64 (the products wrap)


@njit(cache=True)
def _find(index, keys, key, mask):  # pragma: no cover - compiled
    """The slot of ``key`` in the open-addressing ``index`` (linear probing): its entry number (a row of ``keys``),
    or ``-1`` at the free slot where it goes. The index is small (int32, ~2 slots per row the search can score), so
    a probe mostly stays in cache; the keys are read only for a candidate entry."""
    n_words = key.shape[0]
    h = 0
    for w in range(n_words):
        h = (h ^ key[w]) * _MIX
    i = (h ^ (h >> 29)) & mask
    while index[i] >= 0:
        e = index[i]
        same = True
        for w in range(n_words):
            if keys[e, w] != key[w]:
                same = False
                break
        if same:
            return i
        i = (i + 1) & mask
    return i


@njit(cache=True)
def _cyclic(x, lb, period):  # pragma: no cover - compiled
    """Eq. (21) on one value: ``(⌊x⌋ − lb) mod period + lb`` (non-negative modulo)."""
    if not math.isfinite(x):  # as cyclic_round: a diverging move is a bug, not a cell
        raise ValueError("msmfo: non-finite position")
    q = int(math.floor(x)) - lb
    if q < -period or q >= 2 * period:  # far outside the box (rare): the general modulo
        return q % period + lb
    # the moves land within one period of the box: two selects (no branch to mispredict, no integer division)
    q = q + period if q < 0 else q
    q = q - period if q >= period else q
    return q + lb


@njit(cache=True)
def _score(pos, lb, table, stats, best, ctx, work):  # pragma: no cover - compiled
    """Costs of the integer positions ``pos (m, D)`` (paper frame); updates the evaluator's best (first found wins
    on ties, strict improvement) and counts ``stats[0]`` evaluations, ``stats[1]`` rollouts.

    Rows not seen before in this call are rolled out together (:func:`~controllers.mcf_dmpc.kernels.batch_costs`);
    a row repeated within the batch is rolled out once. ``table`` = (keys, costs, cells, free cells left) of the
    rows scored so far; ``work`` = (rows of the batch, their costs, the table cell of each row, a key buffer).
    """
    theta, x0, v0, xp, vp, ap, base, lp, bp, tr, w, u_prev, ff, bits, dpw, pre, depth = ctx
    index, keys, state, values, n_entries = table
    full, costs, entry_of, key = work
    m, dim = pos.shape
    steps = full.shape[1]
    n_words = key.shape[0]
    mask = index.shape[0] - 1
    out = np.empty(m)
    n_new = 0
    for r in range(m):
        for k in range(n_words):  # the row's exact key: dpw digits of ``bits`` bits per word (independent ORs)
            word = 0
            for d in range(k * dpw, min(dim, (k + 1) * dpw)):
                word |= (pos[r, d] - lb) << ((d - k * dpw) * bits)
            key[k] = word
        i = _find(index, keys, key, mask)
        if index[i] < 0:  # a new row: a new entry, pending as row n_new of this batch
            e = n_entries[0]
            if e == keys.shape[0]:
                raise ValueError("msmfo: the table of scored rows is full")
            n_entries[0] = e + 1
            index[i] = e
            for k in range(n_words):
                keys[e, k] = key[k]
            state[e] = n_new
            for d in range(dim):
                full[n_new, d] = pos[r, d] - lb
            for d in range(dim, steps):  # move blocking (decision_dim < Np): hold the last index
                full[n_new, d] = full[n_new, dim - 1]
            n_new += 1
        entry_of[r] = index[i]
    if n_new > 0:
        batch_costs(full[:n_new], theta, x0, v0, xp, vp, ap, base, lp, bp, tr, w, u_prev, ff, costs[:n_new], pre, depth)
        stats[1] += n_new
        for r in range(m):
            e = entry_of[r]
            if state[e] >= 0:
                values[e] = costs[state[e]]
                state[e] = _SCORED
    for r in range(m):
        c = values[entry_of[r]]
        out[r] = c
        if math.isnan(c):
            raise ValueError("msmfo: the fitness returned NaN")
        stats[0] += 1
        if c < best[0]:
            best[0] = c
            for d in range(dim):
                best[1 + d] = pos[r, d]
    return out


@njit(cache=True)
def _eobl(M, fM, rng, P, lb, ub, period, n_elite, table, stats, best, ctx, work):  # pragma: no cover
    """Eq. (23): opposites of the best ``n_elite`` moths, merged, best P kept (stable ranking)."""
    dim = M.shape[1]
    order = np.argsort(fM, kind="mergesort")[:n_elite]
    r2 = rng.random((n_elite, dim))
    opp = np.empty((n_elite, dim), dtype=np.int64)
    for e in range(n_elite):
        for d in range(dim):
            opp[e, d] = _cyclic(r2[e, d] * (lb + ub) - M[order[e], d], lb, period)
    f_opp = _score(opp, lb, table, stats, best, ctx, work)
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
def _search(
    init, rng, P, K, dim, n_values, alpha, beta, elite_fraction, max_passes, ctx, table, work
):  # pragma: no cover
    lb = 1
    ub = n_values
    period = n_values
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
    fM = _score(M, lb, table, stats, best, ctx, work)
    if n_elite > 0:
        M, fM = _eobl(M, fM, rng, P, lb, ub, period, n_elite, table, stats, best, ctx, work)
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
        fM = _score(M, lb, table, stats, best, ctx, work)
        if n_elite > 0:
            M, fM = _eobl(M, fM, rng, P, lb, ub, period, n_elite, table, stats, best, ctx, work)
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
            f_mut = _score(mutant, lb, table, stats, best, ctx, work)
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
            costs = _score(cands, lb, table, stats, best, ctx, work)
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
    theta, *batch_args, steps = fitness_args
    bits = max(1, (int(n_values) - 1).bit_length())  # bits of one zero-based index
    digits_per_word = 63 // bits
    n_words = -(-dim // digits_per_word)  # the int64 words of a row's exact key
    warm = np.zeros((0, dim), dtype=np.int64) if init is None else np.ascontiguousarray(init, dtype=np.int64)
    if warm.size and (warm.min() < 0 or warm.max() >= n_values):  # the row keys hold indices 0 … n − 1 only
        raise ValueError(f"msmfo_mcf: init holds indices outside 0 … {n_values - 1}")
    n_elite = math.ceil(elite_fraction * population)
    # every row the search can score: the initial and EOBL batches, per iteration the moths, their opposites and
    # at most one mutant per flame, and the greedy passes (~2x the distinct rows a search scores)
    bound = (1 + iterations) * (population + n_elite) + iterations * population + max_passes * dim * (n_values - 1)
    theta_row = np.ascontiguousarray(theta, dtype=float).reshape(1, -1)  # one Θ for every row
    batch = batch_context(*batch_args)
    # every row resumes after its first `depth` models (kernels.prefix_states): up to PREFIX_DEPTH, and no more
    # prefixes than rows the search can score (small searches); depth 0 for other model counts
    depth = min(PREFIX_DEPTH, int(steps) - 1) if n_values <= N_MODELS else 0
    while depth > 0 and N_MODELS**depth > bound:
        depth -= 1
    x0, v0, xp, vp, ap, base, lp, bp, tr, _, _, ff = batch
    pre = prefix_states(theta_row[0], x0, v0, xp, vp, ap, base, lp, bp, tr, ff, depth)
    ctx = (theta_row, *batch, bits, digits_per_word, pre, depth)
    table = (
        np.full(1 << int(bound).bit_length(), -1, dtype=np.int32),  # open-addressing index, > bound slots
        np.empty((bound, n_words), dtype=np.int64),  # entry: the row's key,
        np.empty(bound, dtype=np.int64),  # its state (pending batch row or _SCORED)
        np.empty(bound),  # and its cost
        np.zeros(1, dtype=np.int64),  # entries in use
    )
    rows = max(population, n_elite, n_values - 1)  # the largest batch: moths, opposites or greedy candidates
    work = (
        np.empty((rows, int(steps)), dtype=np.int64),
        np.empty(rows),
        np.empty(rows, dtype=np.int64),
        np.empty(n_words, dtype=np.int64),
    )
    best, cost, evaluations, rollouts = _search(
        warm, rng, population, iterations, dim, n_values, alpha, beta, elite_fraction, max_passes, ctx, table, work
    )
    return best, float(cost), int(evaluations), int(rollouts)
