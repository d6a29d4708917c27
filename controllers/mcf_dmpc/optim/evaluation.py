"""The fitness boundary shared by every optimiser: counting, budget cap, best-so-far, and the result record.

All optimisers in this package talk to the user's fitness only through an :class:`Evaluator`. That single door
gives the guarantees the benchmark of Paper A (§4 S-B′, spec A31) needs to be fair:

* every row handed to the fitness is counted, so ``evaluations`` is exact for every method;
* a budget (``options={"budget": N}``) is a hard cap: a batch that would cross it is cut, only the rows that fit
  are evaluated and the rest come back as ``+inf`` (never chosen), and the method stops at its next check;
* every row is checked to be an index in ``[0, n_values)`` before the fitness sees it (rounding bugs fail loudly
  here, not as a wrong model in a rollout) and handed over read-only;
* a NaN cost is a bug in the fitness and raises; ``+inf`` is allowed (a hard-penalty reading of constraints);
* the best row ever evaluated is kept (first found wins ties), so every method returns its true best.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

Fitness = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class OptimResult:
    """Outcome of one :func:`~controllers.mcf_dmpc.optim.minimize_sequence` call.

    ``best`` is a zero-based index vector (D,) in ``[0, n_values)``; ``history[k]`` is the best cost found after
    iteration ``k`` (``k = 0`` is the initial population; one SA "iteration" is ``population`` chain steps so
    that all methods share the same evaluations-per-entry scale; MSMFO appends one entry after its greedy
    refinement). ``evaluations`` counts fitness rows actually evaluated; ``wall_s`` is the wall time of the call.
    """

    best: np.ndarray
    best_cost: float
    history: np.ndarray
    evaluations: int
    wall_s: float
    method: str


class Evaluator:
    """Counting, budget-capped, range-checked front of a population fitness ``(m, D) int -> (m,) float``."""

    def __init__(self, fitness: Fitness, dim: int, n_values: int, budget: int | None) -> None:
        self._fitness = fitness
        self.dim = dim
        self.n_values = n_values
        self.budget = budget
        # A soft limit below the hard budget; MSMFO lowers it to keep evaluations for its greedy refinement.
        self.limit: float = math.inf if budget is None else float(budget)
        self.evaluations = 0
        self.best: np.ndarray | None = None
        self.best_cost = math.inf

    @property
    def remaining(self) -> float:
        cap = self.limit if self.budget is None else min(self.limit, self.budget)
        return max(cap - self.evaluations, 0)

    @property
    def exhausted(self) -> bool:
        return self.remaining <= 0

    def __call__(self, indices: np.ndarray) -> np.ndarray:
        indices = np.asarray(indices)
        rows = indices.shape[0]
        costs = np.full(rows, np.inf)
        allowed = int(min(rows, self.remaining))
        if allowed <= 0:
            return costs
        batch = np.array(indices[:allowed], dtype=np.int64)  # a private copy: the fitness cannot alter our state
        if batch.shape != (allowed, self.dim):
            raise RuntimeError(f"optimiser produced a batch of shape {batch.shape}, expected (m, {self.dim})")
        if batch.min() < 0 or batch.max() >= self.n_values:
            raise RuntimeError(f"optimiser produced an index outside [0, {self.n_values}) — rounding bug")
        batch.setflags(write=False)
        out = np.asarray(self._fitness(batch), dtype=float).reshape(-1)
        if out.shape != (allowed,):
            raise ValueError(f"fitness returned {out.shape[0]} costs for {allowed} sequences")
        if np.isnan(out).any():
            raise ValueError("fitness returned NaN")
        self.evaluations += allowed
        j = int(np.argmin(out))
        if self.best is None or out[j] < self.best_cost:
            self.best = batch[j].copy()
            self.best_cost = float(out[j])
        costs[:allowed] = out
        return costs
