"""A train's situation asks for a formation's tail only of a formation's leader, and gets the tail it got.

:meth:`railsim.engine.control.ControlStage._situation` skips :meth:`FormationBook.tail_m` for a train that leads
no formation (``of_leader``): the tail of such a train is 0. Here the book's own ``tail_m``, asked of every train,
is the reference, over random books: chains of formations (a follower that leads another), formations coupling,
coupled, decoupling and free, followers running or not, with and without a policy target gap of their own. The
situation's last field (its tail) must equal it for every train; a broken skip (asked of followers instead of
leaders, or never) is caught (:func:`test_a_broken_skip_is_caught`).
"""

from __future__ import annotations

import sys
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from railsim.engine.control import ControlStage
from railsim.engine.coupling import FormationBook
from railsim.engine.knowledge import ASK

SEEDS, ROUNDS = 10, 60
STATES = ("free", "coupling", "coupled", "decoupling", "decoupled")


class _View:
    length_m = 10_000.0
    line_speed_mps = 20.0

    def gradient_span(self, front_m: float) -> tuple[float, float, float]:
        return 0.0, -np.inf, np.inf

    def limits_window(self, from_m: float, to_m: float) -> tuple[Any, ...]:
        return (), -np.inf, np.inf, -np.inf, np.inf


def _train(tid: str, rng: np.random.Generator) -> SimpleNamespace:
    return SimpleNamespace(
        train_id=tid,
        front_m=float(rng.uniform(0.0, 9_000.0)),
        plant=SimpleNamespace(speed_mps=10.0),
        view=_View(),
        trip=SimpleNamespace(vehicle=SimpleNamespace(length_m=float(rng.choice([60.0, 120.0])))),
        status="running",
        vc_target_gap_m=None,
    )


def _world(seed: int) -> tuple[ControlStage, FormationBook, list[SimpleNamespace], np.random.Generator]:
    rng = np.random.default_rng(seed)
    trains = [_train(f"t{i}", rng) for i in range(8)]
    book = FormationBook.__new__(FormationBook)
    book.of_leader, book.of_follower = {}, {}
    states: dict[str, str] = {}
    by_id = {tr.train_id: tr for tr in trains}
    for k, (lead, fol) in enumerate([(0, 1), (1, 2), (3, 4), (3, 5), (6, 7)]):  # chains, and two followers of t3
        f = SimpleNamespace(id=f"f{k}", follower=by_id[f"t{fol}"], target_gap_m=float(rng.choice([20.0, 30.5])))
        book.of_leader.setdefault(f"t{lead}", []).append(f)
        book.of_follower[f"t{fol}"] = f
        states[f.id] = "free"
    book.manager = SimpleNamespace(state=states.__getitem__, states=states)
    book.fleet = SimpleNamespace(trip_ref=lambda ref, _where: ref)
    stage = ControlStage.__new__(ControlStage)
    stage.formations = book
    stage.stops = SimpleNamespace(current=lambda tr: (None, 0.0))
    stage.dist = SimpleNamespace(position_sd_m=0.0, speed_sd_mps=0.0)
    stage.settings = SimpleNamespace(lookahead_m=2_000.0)
    stage._route_memo = {}
    stage.locks = SimpleNamespace(authority_end_m=lambda tr: 1e9)
    stage.berths = SimpleNamespace(authority_end_m=lambda t, tr, stop, a, authority_m: authority_m)
    return stage, book, trains, rng


def _first_difference(seed: int) -> str | None:
    stage, book, trains, rng = _world(seed)
    for _ in range(ROUNDS):
        for fid in book.manager.states:
            book.manager.states[fid] = str(rng.choice(STATES))
        for tr in trains:
            tr.status = str(rng.choice(["running", "running", "scheduled", "arrived"]))
            tr.vc_target_gap_m = None if rng.random() < 0.5 else float(rng.uniform(10.0, 60.0))
        for tr in trains:
            got = stage._situation(0.0, tr, None, ASK).tail_m  # type: ignore[arg-type]
            want = FormationBook.tail_m(book, tr)  # type: ignore[arg-type]
            if got != want:
                return f"{tr.train_id}: {got} != {want}"
    return None


@pytest.mark.parametrize("seed", range(SEEDS))
def test_the_situation_s_tail_is_the_book_s(seed: int) -> None:
    assert _first_difference(seed) is None


def test_the_books_have_tails() -> None:
    """Leaders with a coupled follower (a tail), with a chain behind (a longer one), and without (none)."""
    tails = set()
    stage, book, trains, rng = _world(0)
    for _ in range(ROUNDS):
        for fid in book.manager.states:
            book.manager.states[fid] = str(rng.choice(STATES))
        tails |= {round(FormationBook.tail_m(book, tr), 3) for tr in trains}  # type: ignore[arg-type]
    assert 0.0 in tails and len(tails) >= 5


@pytest.mark.parametrize("broken", ["followers", "never"])
def test_a_broken_skip_is_caught(monkeypatch: pytest.MonkeyPatch, broken: str) -> None:
    original = _world

    def world(seed: int) -> Any:
        stage, book, trains, rng = original(seed)
        # the skip reads ``of_leader``; the book's tail_m reads it too: swap it only for the skip's question
        keys = set(book.of_follower) if broken == "followers" else set()
        stage.formations = SimpleNamespace(of_leader=keys, tail_m=lambda tr: FormationBook.tail_m(book, tr))
        return stage, book, trains, rng

    monkeypatch.setattr(sys.modules[__name__], "_world", world)
    assert any(_first_difference(seed) is not None for seed in range(SEEDS))
