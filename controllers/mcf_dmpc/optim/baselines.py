"""The comparison optimisers of Paper A's benchmark (§4 S-B′): GA, PSO and SA on the model-index problem.

The paper ran MATLAB's toolbox GA, ``particleswarm`` and ``simulannealbnd`` with P = 50, K = 100 and SA with
5,000 iterations. Those are not reproducible outside MATLAB, so each is a textbook version of the same family,
given the same problem and, in the benchmark, the same evaluation budget (spec A31). Choices:

* **GA — native integer operators** (MATLAB's GA supports integer variables): binary tournament selection,
  uniform crossover with probability ``crossover_rate`` (0.8, MATLAB's CrossoverFraction), per-gene mutation
  with probability ``1/D`` that resamples the gene to a *different* value uniformly, and ``⌈0.05 P⌉`` elites
  carried over unchanged (MATLAB's EliteCount default). P − elites new evaluations per generation.
* **PSO — continuous relaxation**: inertia-weight global-best PSO (Shi & Eberhart) with ``w`` falling linearly
  0.9 → 0.4, ``c1 = c2 = 2``, velocity clamp ``0.2·n``. Positions live in the box ``[lb, ub + 1)``, where each
  index owns a cell of width 1; ``rounding="clamp"`` (default) clips positions into the box (velocity zeroed on
  the clipped coordinates, like MATLAB's ``particleswarm``) and floors them for the fitness — inside the box
  this *is* the cyclic rounding of Eq. 21, as spec A31 asks; ``rounding="cyclic"`` leaves positions free and
  applies Eq. 21 inside the fitness.
* **SA — native integer neighbourhood**: a single chain; a move changes one random coordinate to a different
  random value; Metropolis acceptance; geometric cooling ``T = T0·ratio^τ`` from ``T0`` to ``T0·final_ratio``
  (1e-3) over the run. ``T0`` is the mean absolute cost change of a batch of ``population`` random neighbours
  of the start point (counted in the budget). The chain length is ``population × iterations`` evaluations
  (5,000 at the paper's P = 50, K = 100), i.e. the same budget as the population methods.

With an evaluation budget every method runs until the budget is spent (``iterations`` is then ignored) and the
progress ``τ`` driving the PSO inertia and the SA temperature is evaluations/budget; without one it is ``k/K``
— exactly as in :mod:`.mothflame`.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from .evaluation import Evaluator
from .mothflame import LB, check_choice, check_number
from .rounding import clamp_box_upper, cyclic_round


@dataclass(frozen=True)
class GaSettings:
    crossover_rate: float = 0.8
    mutation_rate: float | None = None  # per gene; None = 1/D
    tournament: int = 2
    elite_fraction: float = 0.05

    def __post_init__(self) -> None:
        check_number("crossover_rate", self.crossover_rate, low=0.0, high=1.0)
        check_number("mutation_rate", self.mutation_rate, low=0.0, high=1.0, allow_none=True)
        check_number("tournament", self.tournament, low=1, integer=True)
        check_number("elite_fraction", self.elite_fraction, low=0.0, high=1.0)


@dataclass(frozen=True)
class PsoSettings:
    inertia_start: float = 0.9
    inertia_end: float = 0.4
    c1: float = 2.0
    c2: float = 2.0
    vmax_fraction: float = 0.2  # of the box width n
    rounding: str = "clamp"

    def __post_init__(self) -> None:
        for name in ("inertia_start", "inertia_end", "c1", "c2"):
            check_number(name, getattr(self, name), low=0.0, high=10.0)
        check_number("vmax_fraction", self.vmax_fraction, low=1e-9, high=10.0)
        check_choice("rounding", self.rounding, ("clamp", "cyclic"))


@dataclass(frozen=True)
class SaSettings:
    final_ratio: float = 1e-3
    initial_temperature: float | None = None  # None = estimated from a batch of neighbours

    def __post_init__(self) -> None:
        check_number("final_ratio", self.final_ratio, low=1e-300, high=1.0)
        check_number("initial_temperature", self.initial_temperature, low=0.0, allow_none=True)


def _progress(evaluate: Evaluator, k: int, iterations: int) -> float:
    if evaluate.budget is not None:
        return min(evaluate.evaluations / evaluate.budget, 1.0)
    return min(k / iterations, 1.0)


def _running(evaluate: Evaluator, k: int, iterations: int) -> bool:
    """With a budget the run lasts until it is spent; otherwise ``iterations`` generations."""
    return not evaluate.exhausted and (evaluate.budget is not None or k <= iterations)


def run_ga(
    evaluate: Evaluator,
    dim: int,
    n_values: int,
    population: int,
    iterations: int,
    rng: np.random.Generator,
    init: np.ndarray | None,
    settings: GaSettings,
) -> list[float]:
    P, D = population, dim
    mutation_rate = settings.mutation_rate if settings.mutation_rate is not None else 1.0 / D
    n_elite = min(math.ceil(settings.elite_fraction * P), P - 1)
    n_child = P - n_elite
    pop = rng.integers(0, n_values, size=(P, D))
    if init is not None:
        pop[: init.shape[0]] = init
    fit = evaluate(pop)
    history = [evaluate.best_cost]
    for k in itertools.count(1):
        if not _running(evaluate, k, iterations):
            break
        order = np.argsort(fit, kind="stable")
        contenders = rng.integers(0, P, size=(2 * n_child, settings.tournament))
        winners = contenders[np.arange(2 * n_child), np.argmin(fit[contenders], axis=1)]
        mum, dad = pop[winners[:n_child]], pop[winners[n_child:]]
        cross = (rng.random((n_child, 1)) < settings.crossover_rate) & (rng.random((n_child, D)) < 0.5)
        child = np.where(cross, dad, mum)
        mutate = rng.random((n_child, D)) < mutation_rate
        shift = rng.integers(1, max(n_values, 2), size=(n_child, D))  # 1..n-1: always a different value
        child = np.where(mutate, (child + shift) % n_values, child)
        f_child = evaluate(child)
        pop = np.vstack([pop[order[:n_elite]], child])
        fit = np.concatenate([fit[order[:n_elite]], f_child])
        history.append(evaluate.best_cost)
    return history


def run_pso(
    evaluate: Evaluator,
    dim: int,
    n_values: int,
    population: int,
    iterations: int,
    rng: np.random.Generator,
    init: np.ndarray | None,
    settings: PsoSettings,
) -> list[float]:
    P, D = population, dim
    lb, ub = LB, LB + n_values - 1
    upper = clamp_box_upper(ub)
    clamp = settings.rounding == "clamp"
    vmax = settings.vmax_fraction * n_values

    def fit(x: np.ndarray) -> np.ndarray:
        cells = np.floor(x) if clamp else cyclic_round(x, lb, ub)
        return evaluate(cells.astype(np.int64) - lb)

    x = lb + rng.random((P, D)) * n_values
    if init is not None:
        x[: init.shape[0]] = init + lb + 0.5  # centre of the index's cell
    v = rng.uniform(-vmax, vmax, size=(P, D))
    f = fit(x)
    pbest, f_pbest = x.copy(), f.copy()
    g = int(np.argmin(f_pbest))
    history = [evaluate.best_cost]
    for k in itertools.count(1):
        if not _running(evaluate, k, iterations):
            break
        tau = _progress(evaluate, k, iterations)
        w = settings.inertia_start + (settings.inertia_end - settings.inertia_start) * tau
        r1, r2 = rng.random((P, D)), rng.random((P, D))
        v = w * v + settings.c1 * r1 * (pbest - x) + settings.c2 * r2 * (pbest[g] - x)
        v = np.clip(v, -vmax, vmax)
        x = x + v
        if clamp:
            outside = (x < lb) | (x > upper)
            x = np.clip(x, lb, upper)
            v = np.where(outside, 0.0, v)
        f = fit(x)
        improved = f < f_pbest
        pbest[improved], f_pbest[improved] = x[improved], f[improved]
        g = int(np.argmin(f_pbest))
        history.append(evaluate.best_cost)
    return history


def run_sa(
    evaluate: Evaluator,
    dim: int,
    n_values: int,
    population: int,
    iterations: int,
    rng: np.random.Generator,
    init: np.ndarray | None,
    settings: SaSettings,
) -> list[float]:
    D = dim
    chain = population * iterations if evaluate.budget is None else evaluate.budget
    evaluate.limit = chain

    start = init if init is not None else rng.integers(0, n_values, size=(1, D))
    f_start = evaluate(start)
    j = int(np.argmin(f_start))
    x, fx = np.array(start[j], dtype=np.int64), float(f_start[j])

    def neighbours(center: np.ndarray, count: int) -> np.ndarray:
        out = np.repeat(center[None, :], count, axis=0)
        d = rng.integers(0, D, size=count)
        shift = rng.integers(1, max(n_values, 2), size=count)
        out[np.arange(count), d] = (out[np.arange(count), d] + shift) % n_values
        return out

    t0 = settings.initial_temperature
    if t0 is None:
        probe = evaluate(neighbours(x, min(population, max(int(evaluate.remaining) - 1, 0))))
        deltas = np.abs(probe[np.isfinite(probe)] - fx) if math.isfinite(fx) else np.array([])
        t0 = float(deltas.mean()) if deltas.size and deltas.mean() > 0 else 1.0
    t0 = max(t0, 1e-300)

    history = [evaluate.best_cost]
    since_record = 0
    while not evaluate.exhausted:
        tau = min(evaluate.evaluations / chain, 1.0)
        temperature = t0 * settings.final_ratio**tau
        cand = neighbours(x, 1)
        fc = float(evaluate(cand)[0])
        if fc <= fx:
            accept = True
        else:
            delta = fc - fx
            accept = math.isfinite(delta) and rng.random() < math.exp(-delta / temperature)
        if accept:
            x, fx = cand[0], fc
        since_record += 1
        if since_record == population:
            history.append(evaluate.best_cost)
            since_record = 0
    if since_record:
        history.append(evaluate.best_cost)
    return history
