"""Moth-flame optimisation for model-index sequences: plain MFO and Paper A's MSMFO (Eq. 21–28).

Moth-flame optimisation (Mirjalili 2015) keeps two populations. *Moths* search; *flames* are the best positions
found so far, sorted. Each iteration every moth flies a spiral around "its" flame (moth p follows flame p, moths
beyond the current flame count all follow the last flame), the moths are evaluated, and the flames become the
best P of flames ∪ moths. The flame count shrinks over the run, so the swarm narrows from exploration onto the
best flames.

Paper A (§2.7 of the spec) adds seven strategies; each is a field of :class:`MothFlameSettings` and can be
switched or varied on its own (``options`` of ``minimize_sequence``):

====================  =========  ===================================================================
field                 equation   values (default first)
====================  =========  ===================================================================
``rounding``          (21)       ``"cyclic"`` — positions are Eq. 21-rounded integers after every move;
                                 ``"clamp"`` — continuous positions clipped to the box ``[lb, ub + 1)``,
                                 floored only for the fitness (classical MFO)
``chaotic_init``      (22)       ``"suggested"`` (map taken mod 1, spec A23), ``"literal"`` (map output
                                 rounded by Eq. 21 as printed — collapses onto a few vectors), ``"off"``
                                 (uniform random)
``eobl``              (23)       ``"init+iter"`` (after initialisation and once per iteration, spec A25),
                                 ``"init"``, ``"off"``
``flame_count``       (24)       ``"suggested"`` ``⌊N0 − ½(N0 − 1)[tanh(0.1(τ − ½)N0) + 1]⌋`` (spec A22),
                                 ``"literal"`` as printed (≈ N0/2 all run long), ``"linear"`` (classical)
``mutation``          (25–26)    ``"suggested"`` ``CR(F + r_g(ub − lb)(1 − τ)·U(−1, 1)^D)`` (spec A24),
                                 ``"literal"`` ``CR(r_g(ub − lb)(1 − τ)·F)``, ``"off"``
``spiral``            (27)       ``"modified"`` ``D·e^(α r_s)·sin(2βπ(r_s − r)) + F``, ``"standard"``
                                 ``D·e^(b r_s)·cos(2π r_s) + F`` (Mirjalili)
``greedy``            (28)       ``True``: coordinate descent on the best flame after the main loop
====================  =========  ===================================================================

Readings of the gaps (spec §6): mutation fires per flame with probability ``r_g = 1 − sin(πτ/2)`` and a mutant
replaces its flame only if strictly better (A24); elites are the best ``⌈0.4 P⌉`` moths, ``r2`` is drawn per elite
and dimension, opposites are merged with the moths and the best P kept (A25); ``r_s ~ U[r, 1]`` per moth and
dimension with ``r = −1 − τ`` (A27); the greedy pass visits a fresh random permutation of the coordinates, tests
every value of each, accepts strict improvements, and stops after a pass without change or ``greedy_max_passes``
passes (A28). The chaotic stream is one per dimension, ``r1 ~ U[0, 4]`` once per call, and a coordinate that
falls onto the map's absorbing point 0 is re-seeded uniformly (A23).

The schedule variable ``τ`` is the run's progress: ``k/K`` without a budget. With an evaluation budget the run
lasts until the budget is spent (``iterations`` is then ignored) and ``τ = evaluations/budget``, so every method
spends the same number of evaluations and a budget-limited MSMFO still sweeps its whole schedule (wide flames
and strong mutation early, one flame and no mutation at the end) instead of being cut off mid-exploration.
With greedy on and a budget, ``greedy_reserve`` evaluations (default ``min(budget // 5, 2·D·(n − 1))``, two
full passes) are kept back from the main loop for the refinement.

Internally positions are in the paper's frame ``{lb = 1, …, ub = n}``, so Eq. (23) and (26) mean exactly what
they print; the fitness sees zero-based indices ``position − 1``.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from railsim.errors import ConfigError

from .evaluation import Evaluator
from .rounding import clamp_box_upper, cyclic_round, logistic_tent

SOURCE = "minimize_sequence"
LB = 1  # paper frame lower bound (Paper A: lb = 1)


def check_choice(field: str, value: object, choices: tuple[object, ...]) -> None:
    if value not in choices:
        raise ConfigError(SOURCE, f"options.{field}", f"expected one of {', '.join(map(repr, choices))}, got {value!r}")


def check_number(
    field: str, value: object, *, low: float, high: float = math.inf, integer: bool = False, allow_none: bool = False
) -> None:
    if value is None and allow_none:
        return
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if ok and integer:
        ok = float(value) == int(value)
    if not ok or not (low <= float(value) <= high) or not math.isfinite(float(value)):
        kind = "an integer" if integer else "a number"
        raise ConfigError(SOURCE, f"options.{field}", f"expected {kind} in [{low}, {high}], got {value!r}")


@dataclass(frozen=True)
class MothFlameSettings:
    """Switches and constants of (MS)MFO; defaults are MSMFO with Paper A's Table II / §2.7 values."""

    rounding: str = "cyclic"  # Eq. 21
    chaotic_init: str = "suggested"  # Eq. 22
    eobl: str = "init+iter"  # Eq. 23
    elite_fraction: float = 0.4  # Eq. 23: top 40 %
    flame_count: str = "suggested"  # Eq. 24
    initial_flames: int | None = None  # N0 of Eq. 24; None = population (Table II: 50 = P)
    mutation: str = "suggested"  # Eq. 25–26
    spiral: str = "modified"  # Eq. 27
    alpha: float = 0.5  # Eq. 27 spiral shape α
    beta: float = 4.0  # Eq. 27 spiral shape β
    spiral_b: float = 1.0  # classical MFO log-spiral constant b
    greedy: bool = True  # Eq. 28
    greedy_max_passes: int = 10  # spec A28
    greedy_reserve: int | None = None  # evaluations kept for Eq. 28 under a budget; None = two passes

    def __post_init__(self) -> None:
        check_choice("rounding", self.rounding, ("cyclic", "clamp"))
        check_choice("chaotic_init", self.chaotic_init, ("suggested", "literal", "off"))
        check_choice("eobl", self.eobl, ("init+iter", "init", "off"))
        check_number("elite_fraction", self.elite_fraction, low=0.0, high=1.0)
        check_choice("flame_count", self.flame_count, ("suggested", "literal", "linear"))
        check_number("initial_flames", self.initial_flames, low=1, integer=True, allow_none=True)
        check_choice("mutation", self.mutation, ("suggested", "literal", "off"))
        check_choice("spiral", self.spiral, ("modified", "standard"))
        check_number("alpha", self.alpha, low=-10.0, high=10.0)
        check_number("beta", self.beta, low=-100.0, high=100.0)
        check_number("spiral_b", self.spiral_b, low=-10.0, high=10.0)
        check_choice("greedy", self.greedy, (True, False))
        check_number("greedy_max_passes", self.greedy_max_passes, low=1, integer=True)
        check_number("greedy_reserve", self.greedy_reserve, low=0, integer=True, allow_none=True)


MSMFO_SETTINGS = MothFlameSettings()
MFO_SETTINGS = MothFlameSettings(
    rounding="clamp",
    chaotic_init="off",
    eobl="off",
    flame_count="linear",
    mutation="off",
    spiral="standard",
    greedy=False,
)


def flame_count(progress: float, n0: int, variant: str = "suggested") -> int:
    """Eq. (24): number of flames at run progress ``τ = k/K`` ∈ [0, 1], clamped to ``[1, n0]``."""
    if variant == "suggested":
        value = n0 - 0.5 * (n0 - 1) * (math.tanh(0.1 * (progress - 0.5) * n0) + 1.0)
        count = math.floor(value)
    elif variant == "literal":
        count = math.floor(n0 - 0.5 * ((n0 - 1) + math.tanh(0.1 * (progress - 0.5) * n0) + 1.0))
    elif variant == "linear":  # Mirjalili: round(N − l·(N − 1)/T)
        count = round(n0 - progress * (n0 - 1))
    else:
        raise ValueError(f"unknown flame-count variant {variant!r}")
    return int(min(max(count, 1), n0))


def mutation_probability(progress: float) -> float:
    """Eq. (25): ``r_g = 1 − sin(πτ/2)`` — 1 at the start, 0 at the end."""
    return 1.0 - math.sin(0.5 * math.pi * progress)


def chaotic_positions(
    population: int, dim: int, n_values: int, rng: np.random.Generator, variant: str = "suggested"
) -> np.ndarray:
    """Eq. (22): ``population`` integer positions in the paper frame ``{1, …, n_values}`` (float array).

    One chaotic stream per dimension; moth p is the stream's p-th value mapped by ``CR(lb + C·n)``
    (suggested) or, literally, the Eq. 21-rounded map output itself.
    """
    ub = LB + n_values - 1
    r1 = rng.uniform(0.0, 4.0)
    c = rng.random(dim)
    out = np.empty((population, dim))
    out[0] = cyclic_round(LB + c * n_values, LB, ub)
    for p in range(1, population):
        if variant == "suggested":
            c = logistic_tent(c, r1, variant="suggested")
            # 0 is absorbing (and float tent maps collapse there); re-seed those streams.
            stuck = c <= 1e-12
            if stuck.any():
                c[stuck] = rng.random(int(stuck.sum()))
            out[p] = cyclic_round(LB + c * n_values, LB, ub)
        elif variant == "literal":
            c = logistic_tent(c, r1, variant="literal", lb=LB, ub=ub)
            out[p] = c
        else:
            raise ValueError(f"unknown chaotic-initialisation variant {variant!r}")
    return out


def greedy_refine(
    evaluate: Evaluator,
    start: np.ndarray,
    start_cost: float,
    n_values: int,
    rng: np.random.Generator,
    max_passes: int = 10,
) -> tuple[np.ndarray, float, bool]:
    """Eq. (28): coordinate descent from ``start`` (zero-based indices) with exhaustive search per coordinate.

    Each pass visits the coordinates in a fresh random permutation and evaluates all other values of one
    coordinate in a single batch; a strictly better value is taken at once. Returns ``(best, cost, converged)``,
    ``converged`` meaning a full pass changed nothing — then ``best`` is a coordinate-wise local optimum.
    Stops early (not converged) when the evaluator's budget runs out.
    """
    m = np.array(start, dtype=np.int64)
    cost = float(start_cost)
    dim = m.shape[0]
    values = np.arange(n_values, dtype=np.int64)
    for _ in range(max_passes):
        changed = False
        for d in rng.permutation(dim):
            if evaluate.exhausted:
                return m, cost, False
            others = values[values != m[d]]
            if others.size == 0:
                continue
            cands = np.repeat(m[None, :], others.size, axis=0)
            cands[:, d] = others
            costs = evaluate(cands)
            j = int(np.argmin(costs))
            if costs[j] < cost:
                m, cost, changed = cands[j].copy(), float(costs[j]), True
        if not changed:
            return m, cost, True
    return m, cost, False


def run_mothflame(
    evaluate: Evaluator,
    dim: int,
    n_values: int,
    population: int,
    iterations: int,
    rng: np.random.Generator,
    init: np.ndarray | None,
    settings: MothFlameSettings,
) -> tuple[np.ndarray, float, list[float]]:
    """Run (MS)MFO; returns ``(best zero-based indices, best cost, history)``."""
    lb, ub = LB, LB + n_values - 1
    upper = clamp_box_upper(ub)
    cyclic = settings.rounding == "cyclic"
    P, D = population, dim

    def project(x: np.ndarray) -> np.ndarray:
        # "Round" in Eq. 21–27: integer positions (cyclic) or continuous positions kept in the box (clamp).
        if cyclic:
            return cyclic_round(x, lb, ub).astype(float)
        return np.clip(x, lb, upper)

    def fit(pos: np.ndarray) -> np.ndarray:
        return evaluate(np.floor(pos).astype(np.int64) - lb)

    budget = evaluate.budget
    if settings.greedy and budget is not None:
        reserve = settings.greedy_reserve
        if reserve is None:
            reserve = min(budget // 5, 2 * D * (n_values - 1))
        evaluate.limit = max(budget - reserve, 0)
    main_budget = evaluate.limit

    def progress(k: int) -> float:
        if budget is not None:
            return min(evaluate.evaluations / max(main_budget, 1), 1.0)
        return min(k / iterations, 1.0)

    def eobl(M: np.ndarray, fM: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n_elite = math.ceil(settings.elite_fraction * P)
        if n_elite == 0 or evaluate.exhausted:
            return M, fM
        elite = M[np.argsort(fM, kind="stable")[:n_elite]]
        opposite = project(rng.random(elite.shape) * (lb + ub) - elite)  # Eq. 23
        f_opp = fit(opposite)
        pool, f_pool = np.vstack([M, opposite]), np.concatenate([fM, f_opp])
        keep = np.argsort(f_pool, kind="stable")[:P]
        return pool[keep], f_pool[keep]

    # --- initialisation (Eq. 22) ---
    if settings.chaotic_init == "off":
        M = project(lb + rng.random((P, D)) * n_values)
    else:
        M = chaotic_positions(P, D, n_values, rng, settings.chaotic_init)
        if not cyclic:  # the chaotic values are integer cells; keep them as continuous positions in the box
            M = np.clip(M, lb, upper)
    if init is not None:
        M[: init.shape[0]] = init + lb
    fM = fit(M)
    if settings.eobl != "off":
        M, fM = eobl(M, fM)
    order = np.argsort(fM, kind="stable")
    F, fF = M[order].copy(), fM[order].copy()
    history = [evaluate.best_cost]
    n0 = min(settings.initial_flames or P, P)

    # --- main loop ---
    for k in itertools.count(1):
        if evaluate.exhausted or (budget is None and k > iterations):
            break
        tau = progress(k)
        n_flames = flame_count(tau, n0, settings.flame_count)
        r = -1.0 - tau
        target = F[np.minimum(np.arange(P), n_flames - 1)]
        dist = np.abs(target - M)
        rs = rng.uniform(r, 1.0, size=(P, D))
        if settings.spiral == "modified":  # Eq. 27
            M = dist * np.exp(settings.alpha * rs) * np.sin(2.0 * settings.beta * math.pi * (rs - r)) + target
        else:
            M = dist * np.exp(settings.spiral_b * rs) * np.cos(2.0 * math.pi * rs) + target
        M = project(M)
        fM = fit(M)
        if settings.eobl == "init+iter":
            M, fM = eobl(M, fM)
        pool, f_pool = np.vstack([F, M]), np.concatenate([fF, fM])
        keep = np.argsort(f_pool, kind="stable")[:P]
        F, fF = pool[keep], f_pool[keep]

        if settings.mutation != "off" and not evaluate.exhausted:  # Eq. 25–26
            rg = mutation_probability(tau)
            hit = np.flatnonzero(rng.random(n_flames) <= rg)
            if hit.size:
                scale = rg * (ub - lb) * (1.0 - tau)
                if settings.mutation == "suggested":
                    mutant = project(F[hit] + scale * rng.uniform(-1.0, 1.0, size=(hit.size, D)))
                else:
                    mutant = project(scale * F[hit])
                f_mut = fit(mutant)
                better = f_mut < fF[hit]
                if better.any():
                    F[hit[better]], fF[hit[better]] = mutant[better], f_mut[better]
                    order = np.argsort(fF, kind="stable")
                    F, fF = F[order], fF[order]
        history.append(evaluate.best_cost)

    # The flames hold the best ever evaluated; take the evaluator's copy so that ties resolve the same way
    # everywhere (first found wins) and the greedy start is exactly what the result will report.
    assert evaluate.best is not None
    best, best_cost = evaluate.best.copy(), evaluate.best_cost

    # --- greedy refinement (Eq. 28) ---
    if settings.greedy:
        evaluate.limit = math.inf
        best, best_cost, _ = greedy_refine(evaluate, best, best_cost, n_values, rng, settings.greedy_max_passes)
        history.append(best_cost)
    return best, best_cost, history
