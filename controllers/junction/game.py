"""The cooperative cost game of Paper E (spec 004 §2.6–2.7, Eqs. 24–33): players, queues, marginals, Shapley.

Players are the trains; the passing order at the merge switch makes them a queue ``𝔴 = (w_1, …, w_n)``.
The paper's characteristic function has two phases:

* before the switch (Eq. 24): ``f_c1(P) = λ4 Σ_{k∈P} t_1k``;
* beyond it (Eq. 25): ``f_c2(P) = Σ_{k∈P} [λ2 Γ2(v_k) + λ4 t_2k] + Σ_{k∈P, k≠w_1} [λ1 Γ1(D_{k−1,k}) + λ3 f_cv2(k−1,k)]``,

finite only for **queue-shaped** coalitions (prefixes ``{w_1..w_m}``, m ≥ 2) and ``+∞`` otherwise (∅, singletons,
coalitions that skip a predecessor). The marginal cost of Eq. (31) uses only train k's own terms and those
relative to its predecessor in the platoon, so it does not depend on the coalition, and the Shapley value of
Eqs. (32)–(33) collapses to ``Φ_k = f_cm(k)`` with ``Σ_k Φ_k = f_c(N)`` (spec §2.7, "Key consequence").

Reading used for exact enumeration (spec §6 #25, labelled an extension)
    Shapley sums over ``f_c(P ∪ k) − f_c(P)`` are undefined with the ``+∞`` convention. :func:`additive_game`
    is the finite characteristic function under which Eq. (31) *is* the marginal for every coalition: a train's
    pair terms are relative to its physical predecessor at F (that is what ``D_{k−1,k}`` measures, whether or not
    the predecessor is in P), and ``c(∅) = 0``. On queue prefixes it equals the paper's Eqs. 24–25
    (:func:`paper_coalition_cost`, tested). :func:`shapley_by_subsets` (Eq. 32–33 literally) and
    :func:`shapley_by_orderings` (the n! arrival orders) enumerate any finite game exactly, so the closed form is
    checked rather than assumed.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Hashable, Iterable, Sequence
from dataclasses import dataclass

from controllers.junction.model import JunctionParams, safety_margin_m

Coalition = frozenset


@dataclass(frozen=True)
class PlayerTerms:
    """One train's raw quantities at the coupling time ``T_c`` (all in SI units).

    ``gap_to_pred_m``/``speed_diff_to_pred_mps``/``pred_speed_mps`` are ``None`` for the platoon leader.
    """

    train_id: str
    time_before_switch_s: float  # t_1k (Eq. 20)
    time_after_switch_s: float  # t_2k (Eq. 21)
    coupled_speed_mps: float  # v_k at T_c
    gap_to_pred_m: float | None = None  # D_{k−1,k}, head-to-head
    speed_diff_to_pred_mps: float | None = None  # Δv = v_{k−1} − v_k
    pred_speed_mps: float | None = None


def phase1_cost(t: PlayerTerms, params: JunctionParams) -> float:
    """Eq. (28): ``λ4 · t_1k``."""
    return params.weight_time * t.time_before_switch_s


def phase2_own_cost(t: PlayerTerms, params: JunctionParams) -> float:
    """``λ2 Γ2(f_cv1(k)) + λ4 f_ct2(k)`` (Eqs. 18, 21, 23)."""
    denom = max(t.coupled_speed_mps - params.speed_error_mps, params.min_speed_mps)
    return params.weight_speed * 2.0 * params.braking_distance_m / denom + params.weight_time * t.time_after_switch_s


def pair_cost(t: PlayerTerms, params: JunctionParams) -> float:
    """``λ1 Γ1(f_cd(k−1,k)) + λ3 f_cv2(k−1,k)`` (Eqs. 17, 19, 22), 0 for the leader; Γ1 divides by v_k."""
    if t.gap_to_pred_m is None:
        return 0.0
    margin = float(safety_margin_m(t.pred_speed_mps, t.coupled_speed_mps, params))
    v = max(t.coupled_speed_mps, params.min_speed_mps)
    return params.weight_gap * abs(t.gap_to_pred_m - margin) / v + params.weight_speed_diff * (
        abs(t.speed_diff_to_pred_mps) + params.speed_error_mps
    )


def marginal_cost(t: PlayerTerms, params: JunctionParams) -> float:
    """Eq. (31): ``f_cm(k)`` = phase-1 + phase-2 own + pair terms — the closed-form Shapley value."""
    return phase1_cost(t, params) + phase2_own_cost(t, params) + pair_cost(t, params)


def closed_form_shapley(players: Sequence[PlayerTerms], params: JunctionParams) -> dict[str, float]:
    """``Φ_k = f_cm(k)`` (spec §2.7)."""
    return {t.train_id: marginal_cost(t, params) for t in players}


def is_queue(coalition: Iterable[str], order: Sequence[str]) -> bool:
    """A queue-shaped coalition: a prefix ``{w_1..w_m}`` of the passing order with m ≥ 2 (paper, §2.6)."""
    members = set(coalition)
    m = len(members)
    return m >= 2 and members == set(order[:m])


def paper_coalition_cost(coalition: Iterable[str], players: Sequence[PlayerTerms], params: JunctionParams) -> float:
    """The paper's ``f_c = f_c1 + f_c2`` (Eqs. 24–26): finite on queue prefixes, ``+∞`` otherwise.

    ``players`` must be given in passing order (that defines 𝔴 and the predecessors).
    """
    order = [t.train_id for t in players]
    members = set(coalition)
    if not is_queue(members, order):
        return math.inf
    total = 0.0
    for pos, t in enumerate(players):
        if t.train_id not in members:
            continue
        total += phase1_cost(t, params) + phase2_own_cost(t, params)
        if pos > 0:
            total += pair_cost(t, params)
    return total


def additive_game(players: Sequence[PlayerTerms], params: JunctionParams) -> Callable[[frozenset], float]:
    """The finite characteristic function of the module docstring: ``c(P) = Σ_{k∈P} f_cm(k)``, ``c(∅) = 0``."""
    share = closed_form_shapley(players, params)

    def value(coalition: frozenset) -> float:
        return float(sum(share[k] for k in coalition))

    return value


def shapley_by_subsets(players: Sequence[Hashable], value: Callable[[frozenset], float]) -> dict[Hashable, float]:
    """Eqs. (32)–(33) by enumeration: ``Φ_k = Σ_{P⊆N∖k} θ!(n−θ−1)!/n! · (c(P∪k) − c(P))`` with θ = |P|.

    Exact for any finite game; 2^(n−1) coalitions per player, so intended for n ≤ ~12 (the planner has n ≤ 8).
    """
    players = list(players)
    n = len(players)
    if n == 0:
        return {}
    cache: dict[frozenset, float] = {}

    def c(s: frozenset) -> float:
        if s not in cache:
            cache[s] = float(value(s))
        return cache[s]

    weights = [math.factorial(th) * math.factorial(n - th - 1) / math.factorial(n) for th in range(n)]
    phi: dict[Hashable, float] = {}
    for k in players:
        others = [q for q in players if q != k]
        acc = 0.0
        for th in range(n):
            for sub in itertools.combinations(others, th):
                s = frozenset(sub)
                acc += weights[th] * (c(s | {k}) - c(s))
        phi[k] = acc
    return phi


def shapley_by_orderings(players: Sequence[Hashable], value: Callable[[frozenset], float]) -> dict[Hashable, float]:
    """Shapley value as the mean marginal cost over all n! joining orders (independent of Eq. 33's weights)."""
    players = list(players)
    phi = {k: 0.0 for k in players}
    count = 0
    for perm in itertools.permutations(players):
        s: frozenset = frozenset()
        prev = float(value(s))
        for k in perm:
            s = s | {k}
            cur = float(value(s))
            phi[k] += cur - prev
            prev = cur
        count += 1
    return {k: v / count for k, v in phi.items()}


def players_from_outcome(
    train_ids: Sequence[str],
    order: Sequence[int],
    merge_times_s: Sequence[float],
    coupling_time_s: float,
    speeds_mps: Sequence[float],
    positions_common_m: Sequence[float],
) -> list[PlayerTerms]:
    """Build :class:`PlayerTerms` in passing order from a rollout/simulation (positions in s̃, head-to-head)."""
    out: list[PlayerTerms] = []
    for pos, k in enumerate(order):
        pred = order[pos - 1] if pos > 0 else None
        out.append(
            PlayerTerms(
                train_id=train_ids[k],
                time_before_switch_s=float(merge_times_s[k]),
                time_after_switch_s=float(coupling_time_s - merge_times_s[k]),
                coupled_speed_mps=float(speeds_mps[k]),
                gap_to_pred_m=None if pred is None else float(positions_common_m[pred] - positions_common_m[k]),
                speed_diff_to_pred_mps=None if pred is None else float(speeds_mps[pred] - speeds_mps[k]),
                pred_speed_mps=None if pred is None else float(speeds_mps[pred]),
            )
        )
    return out
