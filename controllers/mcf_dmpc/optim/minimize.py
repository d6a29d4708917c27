"""One entry point for all sequence optimisers: :func:`minimize_sequence`.

The caller (MCF-DMPC, Paper A §2.5) has a cost over integer sequences — which car-following law drives each
predicted step — and wants the cheapest sequence. It passes a *population* fitness, ``(m, D) int -> (m,)``
costs, so that rollouts are vectorised over candidates; ``m`` varies between calls (a population, a batch of
elite opposites, the few alternatives of one greedy coordinate, a single SA move).

Indices are **zero-based** at this interface, ``[0, n_values)``; the optimisers work internally in the paper's
frame ``{1, …, n_values}`` (:mod:`.mothflame`). Methods: ``"msmfo"`` (default, Eq. 21–28), ``"mfo"`` (classical
moth-flame on the continuous relaxation), ``"ga"``, ``"pso"``, ``"sa"`` (:mod:`.baselines`). ``options`` holds
per-method switches (the fields of the method's settings dataclass) plus the common ``"budget"``: a hard cap on
fitness evaluations, which is how the benchmark compares methods fairly. With a budget every method runs until
the budget is spent and ``iterations`` is ignored (MSMFO may stop a little short when its greedy refinement
converges before using its reserve). Without a budget a method spends its natural amount: MFO/PSO ``P(K + 1)``, GA ``P + K(P − elites)``, SA ``P·K``, MSMFO about ``1.4P(K + 1)`` plus
mutations plus greedy passes.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from railsim.errors import ConfigError

from .baselines import GaSettings, PsoSettings, SaSettings, run_ga, run_pso, run_sa
from .evaluation import Evaluator, OptimResult
from .mothflame import MFO_SETTINGS, MSMFO_SETTINGS, SOURCE, check_number, run_mothflame

METHODS = ("msmfo", "mfo", "ga", "pso", "sa")
_DEFAULTS: dict[str, Any] = {
    "msmfo": MSMFO_SETTINGS,
    "mfo": MFO_SETTINGS,
    "ga": GaSettings(),
    "pso": PsoSettings(),
    "sa": SaSettings(),
}


def method_settings(method: str, options: Mapping[str, Any] | None) -> tuple[Any, int | None]:
    """The settings dataclass of ``method`` with ``options`` applied, and the budget (None = natural)."""
    if method not in METHODS:
        raise ConfigError(SOURCE, "method", f"expected one of {', '.join(METHODS)}, got {method!r}")
    opts = dict(options or {})
    budget = opts.pop("budget", None)
    check_number("budget", budget, low=1, integer=True, allow_none=True)
    base = _DEFAULTS[method]
    known = {f.name for f in dataclasses.fields(base)}
    unknown = sorted(set(opts) - known)
    if unknown:
        raise ConfigError(
            SOURCE, f"options.{unknown[0]}", f"not an option of {method!r}; known: budget, {', '.join(sorted(known))}"
        )
    return dataclasses.replace(base, **opts), (None if budget is None else int(budget))


def _check_init(init: np.ndarray | None, dim: int, n_values: int, population: int) -> np.ndarray | None:
    if init is None:
        return None
    arr = np.asarray(init)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != dim or arr.shape[0] < 1:
        raise ConfigError(SOURCE, "init", f"expected shape ({dim},) or (k, {dim}), got {np.shape(init)}")
    if arr.shape[0] > population:
        raise ConfigError(SOURCE, "init", f"{arr.shape[0]} warm starts exceed the population {population}")
    if not np.issubdtype(arr.dtype, np.number) or not np.all(np.isfinite(arr)) or np.any(arr != np.round(arr)):
        raise ConfigError(SOURCE, "init", "expected integer model indices")
    if arr.min() < 0 or arr.max() >= n_values:
        raise ConfigError(SOURCE, "init", f"expected indices in [0, {n_values}), got [{arr.min()}, {arr.max()}]")
    return arr.astype(np.int64)


def minimize_sequence(
    fitness: Callable[[np.ndarray], np.ndarray],
    dim: int,
    n_values: int,
    *,
    method: str = "msmfo",
    population: int = 50,
    iterations: int = 100,
    rng: np.random.Generator,
    init: np.ndarray | None = None,
    options: Mapping[str, Any] | None = None,
) -> OptimResult:
    """Minimise ``fitness`` over sequences in ``[0, n_values)^dim`` with ``method``; see the module docstring.

    Default reading of MSMFO: every component on, the *suggested* variants of Eq. (22) (chaos map mod 1),
    Eq. (24) (tanh flame count regrouped) and Eq. (26) (mutation with its random term restored), EOBL after
    initialisation and every iteration; ``options`` selects the literal variants or switches components off
    (:class:`~controllers.mcf_dmpc.optim.mothflame.MothFlameSettings`).

    ``init`` (``(D,)`` or ``(k, D)``, k ≤ population) seeds the first k individuals (SA: starts from the best of
    them). All randomness comes from ``rng``: the same generator state gives the same result.
    """
    t_start = time.perf_counter()
    settings, budget = method_settings(method, options)
    for name, value, low in (
        ("dim", dim, 1),
        ("n_values", n_values, 1),
        ("population", population, 2),
        ("iterations", iterations, 1),
    ):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
            raise ConfigError(SOURCE, name, f"expected an integer >= {low}, got {value!r}")
    if not isinstance(rng, np.random.Generator):
        raise ConfigError(SOURCE, "rng", f"expected a numpy.random.Generator, got {type(rng).__name__}")
    warm = _check_init(init, dim, n_values, population)

    evaluate = Evaluator(fitness, dim, n_values, budget)
    if n_values == 1:  # a single sequence exists; nothing to search
        evaluate(np.zeros((1, dim), dtype=np.int64))
        history = [evaluate.best_cost]
    elif method in ("msmfo", "mfo"):
        _, _, history = run_mothflame(evaluate, dim, n_values, population, iterations, rng, warm, settings)
    elif method == "ga":
        history = run_ga(evaluate, dim, n_values, population, iterations, rng, warm, settings)
    elif method == "pso":
        history = run_pso(evaluate, dim, n_values, population, iterations, rng, warm, settings)
    else:
        history = run_sa(evaluate, dim, n_values, population, iterations, rng, warm, settings)
    assert evaluate.best is not None  # at least one row is always evaluated (budget >= 1)
    return OptimResult(
        best=evaluate.best.copy(),
        best_cost=evaluate.best_cost,
        history=np.asarray(history),
        evaluations=evaluate.evaluations,
        wall_s=time.perf_counter() - t_start,
        method=method,
    )
