"""Paper E game layer: Shapley enumeration vs the closed form Φ_k = f_cm(k) and the Shapley axioms."""

from __future__ import annotations

import itertools
import math

import numpy as np
from hypothesis import given, settings, strategies as st

from controllers.junction.game import (
    PlayerTerms,
    additive_game,
    closed_form_shapley,
    is_queue,
    paper_coalition_cost,
    shapley_by_orderings,
    shapley_by_subsets,
)
from controllers.junction.model import JunctionParams

PARAMS = JunctionParams()

finite = st.floats(min_value=-50.0, max_value=50.0, allow_nan=False, allow_infinity=False)


@st.composite
def games(draw, max_players: int = 5):
    """A random finite cost game: players 0..n-1, arbitrary coalition values, c(∅) = 0."""
    n = draw(st.integers(min_value=1, max_value=max_players))
    players = list(range(n))
    values = {frozenset(): 0.0}
    for size in range(1, n + 1):
        for sub in itertools.combinations(players, size):
            values[frozenset(sub)] = draw(finite)
    return players, values


@st.composite
def platoons(draw):
    """Random physical terms for 2..8 trains in passing order."""
    n = draw(st.integers(min_value=2, max_value=8))
    out = []
    for k in range(n):
        t1 = draw(st.floats(0.0, 120.0))
        t2 = draw(st.floats(0.0, 60.0))
        v = draw(st.floats(0.5, 20.0))
        if k == 0:
            out.append(PlayerTerms(f"T{k}", t1, t2, v))
        else:
            out.append(
                PlayerTerms(
                    f"T{k}",
                    t1,
                    t2,
                    v,
                    draw(st.floats(0.0, 300.0)),
                    out[-1].coupled_speed_mps - v,
                    out[-1].coupled_speed_mps,
                )
            )
    return out


@settings(max_examples=60)
@given(games())
def test_subset_formula_equals_permutation_average_and_is_efficient(game):
    players, values = game
    phi_s = shapley_by_subsets(players, values.__getitem__)
    phi_o = shapley_by_orderings(players, values.__getitem__)
    for k in players:
        assert math.isclose(phi_s[k], phi_o[k], rel_tol=1e-9, abs_tol=1e-9)
    # efficiency: Σ Φ_k = c(N) − c(∅)
    assert math.isclose(sum(phi_s.values()), values[frozenset(players)], rel_tol=1e-9, abs_tol=1e-9)


@settings(max_examples=60)
@given(games(max_players=4), st.data())
def test_symmetry_and_null_player(game, data):
    players, values = game
    if len(players) < 2:
        return
    # make players 0 and 1 symmetric: c(S ∪ {0}) = c(S ∪ {1}) for S without both
    sym = dict(values)
    for s in list(sym):
        if 0 in s and 1 not in s:
            sym[s] = sym[(s - {0}) | {1}]
    phi = shapley_by_subsets(players, sym.__getitem__)
    assert math.isclose(phi[0], phi[1], rel_tol=1e-9, abs_tol=1e-9)
    # make the last player a null player: adding it never changes the value
    z = players[-1]
    null = {s: (values[s - {z}] if z in s else values[s]) for s in values}
    phi = shapley_by_subsets(players, null.__getitem__)
    assert abs(phi[z]) < 1e-9


@settings(max_examples=40)
@given(platoons())
def test_enumeration_equals_closed_form_and_efficiency(players):
    closed = closed_form_shapley(players, PARAMS)
    game = additive_game(players, PARAMS)
    ids = [p.train_id for p in players]
    enumerated = shapley_by_subsets(ids, game)
    for k in ids:
        assert math.isclose(enumerated[k], closed[k], rel_tol=1e-9, abs_tol=1e-9)
    grand = paper_coalition_cost(ids, players, PARAMS)
    assert math.isclose(sum(closed.values()), grand, rel_tol=1e-9)


@settings(max_examples=40)
@given(platoons())
def test_paper_characteristic_function_queue_shape(players):
    ids = [p.train_id for p in players]
    game = additive_game(players, PARAMS)
    assert paper_coalition_cost([], players, PARAMS) == math.inf
    assert paper_coalition_cost(ids[:1], players, PARAMS) == math.inf
    for m in range(2, len(ids) + 1):  # queue prefixes: finite and equal to the finite extension
        assert is_queue(ids[:m], ids)
        assert math.isclose(paper_coalition_cost(ids[:m], players, PARAMS), game(frozenset(ids[:m])), rel_tol=1e-9)
    if len(ids) >= 3:  # skipping a predecessor is not a queue
        skip = [ids[0], ids[2]]
        assert not is_queue(skip, ids)
        assert paper_coalition_cost(skip, players, PARAMS) == math.inf


def test_shapley_weights_sum_to_one():
    # the identity behind Φ_k = f_cm(k): Σ_θ C(n−1,θ) θ!(n−θ−1)!/n! = 1
    for n in range(1, 9):
        total = sum(
            math.comb(n - 1, th) * math.factorial(th) * math.factorial(n - th - 1) / math.factorial(n)
            for th in range(n)
        )
        assert math.isclose(total, 1.0)


def test_leader_bears_no_pair_terms_and_gap_error_costs_the_follower():
    lead = PlayerTerms("A", 10.0, 20.0, 10.0)
    exact = PlayerTerms("B", 20.0, 10.0, 10.0, gap_to_pred_m=10.0, speed_diff_to_pred_mps=0.0, pred_speed_mps=10.0)
    far = PlayerTerms("B", 20.0, 10.0, 10.0, gap_to_pred_m=60.0, speed_diff_to_pred_mps=0.0, pred_speed_mps=10.0)
    base = closed_form_shapley([lead, exact], PARAMS)
    worse = closed_form_shapley([lead, far], PARAMS)
    assert base["A"] == worse["A"]
    # S_m at equal speeds = 2·V_δ·(T1+T2) + S_0 = 10.06 m; Γ1 divides the gap error by the follower's speed
    s_m = 2 * 0.1 * (0.1 + 0.2) + 10.0
    assert np.isclose(worse["B"] - base["B"], (abs(60.0 - s_m) - abs(10.0 - s_m)) / 10.0, atol=1e-12)
