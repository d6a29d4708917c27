"""Paper A's sequence optimisers (controllers.mcf_dmpc.optim): rounding, schedules, determinism, optimality on
problems with a known optimum, evaluation budgets, and every MSMFO switch (spec 000 §2.7, A22–A28, A31)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from controllers.mcf_dmpc.optim import (
    METHODS,
    MSMFO_SETTINGS,
    Evaluator,
    GaSettings,
    chaotic_positions,
    clamp_round,
    cyclic_round,
    flame_count,
    greedy_refine,
    logistic_tent,
    minimize_sequence,
    mutation_probability,
)
from railsim.errors import ConfigError


# ----------------------------------------------------------------------------------------------- fixtures
def separable(dim: int, n_values: int, seed: int):
    """Σ w_d (x_d − t_d)²: known optimum t (cost 0), every coordinate independent."""
    rng = np.random.default_rng(seed)
    target = rng.integers(0, n_values, dim)
    weight = rng.uniform(0.5, 2.0, dim)
    return (lambda x: ((x - target) ** 2 * weight).sum(axis=1)), target


def quadratic(dim: int, n_values: int, seed: int):
    """A dense random quadratic over one-hot encodings: non-separable, many local optima."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(dim * n_values, dim * n_values))
    a = a @ a.T / dim
    offsets = np.arange(dim) * n_values

    def f(x: np.ndarray) -> np.ndarray:
        idx = x + offsets
        return a[idx[:, :, None], idx[:, None, :]].sum(axis=(1, 2))

    return f


class Spy:
    """Counts every evaluated row and checks the range independently of the Evaluator."""

    def __init__(self, f, n_values: int):
        self.f, self.n_values, self.rows = f, n_values, 0

    def __call__(self, x: np.ndarray) -> np.ndarray:
        assert x.dtype.kind == "i" and x.min() >= 0 and x.max() < self.n_values
        self.rows += x.shape[0]
        return self.f(x)


MSMFO_VARIANTS = [
    ("rounding", "clamp"),
    ("chaotic_init", "literal"),
    ("chaotic_init", "off"),
    ("eobl", "init"),
    ("eobl", "off"),
    ("flame_count", "literal"),
    ("flame_count", "linear"),
    ("mutation", "literal"),
    ("mutation", "off"),
    ("spiral", "standard"),
    ("greedy", False),
]


# ----------------------------------------------------------------------------------------------- rounding
def test_cyclic_round_examples_of_eq21():
    # lb = 1, ub = 3: wraps with period 3, the printed Eq. 21 with the general period ub − lb + 1.
    x = np.array([1.0, 2.9, 3.99, 4.0, 5.5, 0.99, 0.0, -1.0, -2.5, 7.0])
    assert cyclic_round(x, 1, 3).tolist() == [1, 2, 3, 1, 2, 3, 3, 2, 3, 1]
    assert clamp_round(x, 1, 3).tolist() == [1, 2, 3, 3, 3, 1, 1, 1, 1, 3]


@settings(max_examples=200)
@given(
    values=st.lists(st.floats(-1e300, 1e300, allow_nan=False), min_size=1, max_size=40),
    lb=st.integers(-5, 5),
    n_values=st.integers(1, 9),
)
def test_rounding_keeps_every_index_in_range(values, lb, n_values):
    ub = lb + n_values - 1
    for fn in (cyclic_round, clamp_round):
        out = fn(np.array(values), lb, ub)
        assert out.dtype == np.int64
        assert out.min() >= lb and out.max() <= ub


@settings(max_examples=100)
@given(
    whole=st.lists(st.integers(-(10**6), 10**6), min_size=1, max_size=20),
    frac=st.sampled_from([0.0, 0.25, 0.5, 0.75]),
    n_values=st.integers(1, 9),
)
def test_cyclic_round_is_periodic_and_identity_in_range(whole, frac, n_values):
    x = np.array(whole) + frac  # exactly representable, so x + n is exact and periodicity is testable
    assert np.array_equal(cyclic_round(x + n_values, 0, n_values - 1), cyclic_round(x, 0, n_values - 1))
    inside = np.arange(n_values, dtype=float) + 0.5
    assert cyclic_round(inside, 0, n_values - 1).tolist() == list(range(n_values))


def test_rounding_refuses_non_finite_positions():
    with pytest.raises(ValueError, match="non-finite"):
        cyclic_round(np.array([1.0, np.inf]), 1, 3)
    with pytest.raises(ValueError, match="non-finite"):
        clamp_round(np.array([np.nan]), 1, 3)


@settings(max_examples=100)
@given(c=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=20), r1=st.floats(0.0, 4.0))
def test_logistic_tent_stays_in_its_domain(c, r1):
    out = logistic_tent(np.array(c), r1)
    assert np.all((out >= 0.0) & (out < 1.0))
    lit = logistic_tent(np.array(c), r1, variant="literal", lb=1, ub=3)
    assert set(lit.tolist()) <= {1.0, 2.0, 3.0}


@settings(max_examples=60)
@given(
    population=st.integers(1, 60),
    dim=st.integers(1, 30),
    n_values=st.integers(1, 6),
    seed=st.integers(0, 2**32 - 1),
    variant=st.sampled_from(["suggested", "literal"]),
)
def test_chaotic_initialisation_stays_in_range(population, dim, n_values, seed, variant):
    pos = chaotic_positions(population, dim, n_values, np.random.default_rng(seed), variant)
    assert pos.shape == (population, dim)
    assert np.all(pos == np.floor(pos)) and pos.min() >= 1 and pos.max() <= n_values


def test_chaotic_initialisation_is_diverse_and_literal_collapses():
    # The suggested map spreads moths over all values; the literal "Round" collapses the stream (spec A23).
    rng = np.random.default_rng(3)
    sug = chaotic_positions(50, 60, 3, rng, "suggested")
    assert len({tuple(row) for row in sug}) == 50
    assert all(np.unique(sug[:, d]).size == 3 for d in range(60))
    lit = chaotic_positions(50, 60, 3, np.random.default_rng(3), "literal")
    assert len({tuple(row) for row in lit}) < 10


# ----------------------------------------------------------------------------------------------- schedules
def test_flame_count_matches_eq24_readings():
    taus = [0.0, 0.25, 0.5, 0.75, 1.0]
    assert [flame_count(t, 50, "suggested") for t in taus] == [49, 46, 25, 4, 1]  # spec A22
    assert [flame_count(t, 50, "literal") for t in (0.0, 1.0)] == [25, 24]  # degenerate as printed
    assert [flame_count(t, 50, "linear") for t in taus] == [50, 38, 26, 13, 1]  # Mirjalili


@given(tau=st.floats(0.0, 1.0), n0=st.integers(1, 200), variant=st.sampled_from(["suggested", "literal", "linear"]))
def test_flame_count_is_between_one_and_n0(tau, n0, variant):
    assert 1 <= flame_count(tau, n0, variant) <= n0


def test_mutation_probability_eq25():
    ks = [0, 10, 25, 50, 75, 100]
    expected = [1.0, 0.843, 0.617, 0.293, 0.076, 0.0]  # spec §2.7 (5)
    assert [mutation_probability(k / 100) for k in ks] == pytest.approx(expected, abs=1e-3)


# ----------------------------------------------------------------------------------------------- optimality
@pytest.mark.parametrize("method", METHODS)
def test_each_method_finds_the_optimum_of_a_small_separable_problem(method):
    hits = 0
    for seed in range(10):
        f, target = separable(8, 3, seed)
        res = minimize_sequence(f, 8, 3, method=method, rng=np.random.default_rng(100 + seed))
        hits += bool(np.array_equal(res.best, target))
        assert res.best_cost == pytest.approx(f(res.best[None])[0])
    assert hits >= 9


def test_greedy_refinement_is_one_pass_on_a_separable_problem():
    # Coordinates are independent: one pass sets each to its optimum, the second confirms; 2·D·(n − 1) rows.
    dim, n = 12, 4
    f, target = separable(dim, n, 7)
    ev = Evaluator(f, dim, n, None)
    start = (target + 1) % n
    best, cost, converged = greedy_refine(ev, start, float(f(start[None])[0]), n, np.random.default_rng(0))
    assert converged and np.array_equal(best, target) and cost == 0.0
    assert ev.evaluations == 2 * dim * (n - 1)


def _is_coordinatewise_local_optimum(f, x: np.ndarray, n_values: int) -> bool:
    cost = f(x[None])[0]
    for d in range(x.size):
        trial = np.repeat(x[None], n_values, axis=0)
        trial[:, d] = np.arange(n_values)
        if f(trial).min() < cost:
            return False
    return True


@pytest.mark.parametrize("seed", range(4))
def test_greedy_refinement_returns_a_coordinatewise_local_optimum(seed):
    f = quadratic(10, 3, seed)
    rng = np.random.default_rng(seed)
    start = rng.integers(0, 3, 10)
    ev = Evaluator(f, 10, 3, None)
    best, cost, converged = greedy_refine(ev, start, float(f(start[None])[0]), 3, rng, max_passes=50)
    assert converged
    assert cost == pytest.approx(f(best[None])[0]) and cost <= f(start[None])[0]
    assert _is_coordinatewise_local_optimum(f, best, 3)
    # and through the public entry point (MSMFO ends with the same refinement)
    res = minimize_sequence(f, 10, 3, rng=np.random.default_rng(seed), options={"greedy_max_passes": 50})
    assert _is_coordinatewise_local_optimum(f, res.best, 3)


def test_msmfo_beats_random_sampling_on_a_nonseparable_problem():
    f = quadratic(30, 3, 11)
    budget = 3000
    random_best = f(np.random.default_rng(0).integers(0, 3, (budget, 30))).min()
    res = minimize_sequence(f, 30, 3, rng=np.random.default_rng(0), options={"budget": budget})
    assert res.best_cost < random_best


# ----------------------------------------------------------------------------------------------- determinism
@pytest.mark.parametrize("method", METHODS)
def test_same_seed_same_result_and_different_seeds_differ(method):
    f = quadratic(20, 3, 5)
    kw = dict(method=method, options={"budget": 800})
    a = minimize_sequence(f, 20, 3, rng=np.random.default_rng(42), **kw)
    b = minimize_sequence(f, 20, 3, rng=np.random.default_rng(42), **kw)
    c = minimize_sequence(f, 20, 3, rng=np.random.default_rng(43), **kw)
    assert np.array_equal(a.best, b.best) and a.best_cost == b.best_cost
    assert np.array_equal(a.history, b.history) and a.evaluations == b.evaluations
    assert not (np.array_equal(a.history, c.history) and np.array_equal(a.best, c.best))


# ----------------------------------------------------------------------------------------------- budgets
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("budget", [7, 777, 2500])
def test_budget_is_a_hard_cap_and_is_spent(method, budget):
    dim, n = 15, 3
    spy = Spy(separable(dim, n, 1)[0], n)
    res = minimize_sequence(spy, dim, n, method=method, rng=np.random.default_rng(0), options={"budget": budget})
    assert res.evaluations == spy.rows <= budget
    if method == "msmfo":  # may leave part of its greedy reserve unspent when the refinement converges
        assert res.evaluations >= budget - min(budget // 5, 2 * dim * (n - 1))
    else:
        assert res.evaluations == budget


@pytest.mark.parametrize("method", METHODS)
def test_natural_evaluation_counts(method):
    P, K, dim = 20, 30, 6
    spy = Spy(separable(dim, 3, 2)[0], 3)
    res = minimize_sequence(spy, dim, 3, method=method, population=P, iterations=K, rng=np.random.default_rng(1))
    natural = {
        "mfo": P * (K + 1),
        "pso": P * (K + 1),
        "sa": P * K,
        "ga": P + K * (P - math.ceil(GaSettings().elite_fraction * P)),
    }
    if method == "msmfo":
        # init + EOBL, then per iteration P moths + ⌈0.4P⌉ opposites + up to N_f mutants, plus greedy passes
        base = (P + math.ceil(0.4 * P)) * (K + 1)
        assert base <= res.evaluations <= base + K * P + 10 * dim * 2
        assert len(res.history) == K + 2
    else:
        assert res.evaluations == natural[method]
    assert res.evaluations == spy.rows


# ----------------------------------------------------------------------------------------------- switches
@pytest.mark.parametrize("field,value", MSMFO_VARIANTS)
def test_every_msmfo_component_can_be_switched(field, value):
    dim, n = 12, 4
    spy = Spy(quadratic(dim, n, 2), n)
    res = minimize_sequence(
        spy, dim, n, rng=np.random.default_rng(0), population=20, iterations=30, options={field: value}
    )
    assert res.method == "msmfo" and res.best.shape == (dim,) and res.best.dtype == np.int64
    assert res.best.min() >= 0 and res.best.max() < n
    assert res.best_cost == pytest.approx(spy.f(res.best[None])[0])
    assert np.all(np.diff(res.history) <= 0)  # best-so-far never worsens
    assert res.evaluations == spy.rows


def test_all_components_off_at_once_is_plain_mfo_like():
    off = {
        "rounding": "clamp",
        "chaotic_init": "off",
        "eobl": "off",
        "flame_count": "linear",
        "mutation": "off",
        "spiral": "standard",
        "greedy": False,
    }
    a = minimize_sequence(quadratic(10, 3, 1), 10, 3, rng=np.random.default_rng(9), options=off)
    b = minimize_sequence(quadratic(10, 3, 1), 10, 3, method="mfo", rng=np.random.default_rng(9))
    assert np.array_equal(a.best, b.best) and np.array_equal(a.history, b.history)


@settings(max_examples=40)
@given(
    dim=st.integers(1, 12),
    n_values=st.integers(1, 5),
    seed=st.integers(0, 10_000),
    method=st.sampled_from(METHODS),
    variant=st.sampled_from([None] + MSMFO_VARIANTS),
)
def test_every_evaluated_sequence_is_in_range(dim, n_values, seed, method, variant):
    spy = Spy(quadratic(dim, n_values, seed % 7), n_values)
    options: dict = {"budget": 300}
    if variant is not None and method in ("msmfo", "mfo"):
        options[variant[0]] = variant[1]
    res = minimize_sequence(
        spy, dim, n_values, method=method, population=10, rng=np.random.default_rng(seed), options=options
    )
    assert 0 <= res.best.min() and res.best.max() < n_values and res.evaluations == spy.rows


# ----------------------------------------------------------------------------------------------- warm start / input
@pytest.mark.parametrize("method", METHODS)
def test_warm_start_is_evaluated_first(method):
    f, target = separable(10, 3, 4)
    other = (target + 1) % 3
    res = minimize_sequence(
        f, 10, 3, method=method, rng=np.random.default_rng(0), init=np.stack([other, target]), options={"budget": 2}
    )
    assert np.array_equal(res.best, target) and res.best_cost == 0.0


@pytest.mark.parametrize(
    "kwargs,field",
    [
        ({"method": "de"}, "method"),
        ({"options": {"spiral": "log"}}, "options.spiral"),
        ({"options": {"swarm": 3}}, "options.swarm"),
        ({"options": {"budget": 0}}, "options.budget"),
        ({"options": {"elite_fraction": 1.5}}, "options.elite_fraction"),
        ({"population": 1}, "population"),
        ({"init": np.zeros(5, dtype=int)}, "init"),
        ({"init": np.full(8, 3)}, "init"),
        ({"init": np.full(8, 0.5)}, "init"),
    ],
)
def test_bad_arguments_raise_config_errors(kwargs, field):
    f, _ = separable(8, 3, 0)
    with pytest.raises(ConfigError) as err:
        minimize_sequence(f, 8, 3, rng=np.random.default_rng(0), **kwargs)
    assert err.value.field == field and str(err.value).startswith(f"minimize_sequence: {field}: ")


def test_fitness_contract_violations_are_loud():
    with pytest.raises(ValueError, match="NaN"):
        minimize_sequence(lambda x: np.full(len(x), np.nan), 4, 3, rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="costs for"):
        minimize_sequence(lambda x: np.zeros(1), 4, 3, rng=np.random.default_rng(0))


def test_fitness_cannot_mutate_the_optimiser_state():
    def vandal(x: np.ndarray) -> np.ndarray:
        x[:] = 0  # must fail: the batch is handed over read-only
        return np.zeros(len(x))

    with pytest.raises(ValueError, match="read-only"):
        minimize_sequence(vandal, 4, 3, rng=np.random.default_rng(0))


def test_single_value_problem_has_one_answer():
    res = minimize_sequence(lambda x: x.sum(1).astype(float), 5, 1, rng=np.random.default_rng(0))
    assert res.best.tolist() == [0] * 5 and res.evaluations == 1


def test_defaults_are_the_paper_reading():
    s = MSMFO_SETTINGS
    assert (s.rounding, s.chaotic_init, s.eobl, s.flame_count, s.mutation, s.spiral, s.greedy) == (
        "cyclic",
        "suggested",
        "init+iter",
        "suggested",
        "suggested",
        "modified",
        True,
    )
    assert (s.alpha, s.beta, s.elite_fraction) == (0.5, 4.0, 0.4)
