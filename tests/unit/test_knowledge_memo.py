"""What a train knows of another, with the frame change remembered per pair, is what the long way gives
(railsim/engine/knowledge.py).

Trains drive along random routes (merging, diverging, some passing an edge twice: the routes of
``tests/unit/test_routeview_memo.py``) and report over a lossy, delayed ground channel; some never report (what is
known of them is their registration, or where they came on the line). Every step every train asks about every
other: :meth:`Knowledge.known_rear_age` and :meth:`Knowledge.known_state` must answer exactly as they do with the
memory switched off (``RouteView.map_body_memo`` replaced by ``map_body`` called as the long way calls it), and
:meth:`Knowledge.ground_rears` (what moving-block separation reads of the train ahead, every train in one compiled
pass over the occupancy's tables) must give ``known_rear_age``'s answer for a train ahead, or leave it to be asked
only where the ground has no report or none of the reported body is on the observer's track, with the ground
channel and without one.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from railsim.engine.events import Channel, DelaySpec, EventLayer
from railsim.engine.knowledge import Knowledge
from railsim.engine.occupancy import Occupancy
from railsim.engine.routeview import RouteView
from tests.unit.test_routeview_memo import _views


def _train(k: int, view: RouteView, rng: np.random.Generator) -> SimpleNamespace:
    front_m = float(rng.uniform(0.0, view.length_m))
    vehicle = SimpleNamespace(
        length_m=float(rng.uniform(20.0, 400.0)), service_decel_mps2=1.0, emergency_decel_mps2=1.2
    )
    return SimpleNamespace(
        train_id=f"t{k}",
        view=view,
        front_m=front_m,
        edge_i=view.edge_at(front_m),
        trip=SimpleNamespace(route=view.route, vehicle=vehicle, start_speed_mps=5.0),
        plant=SimpleNamespace(speed_mps=float(rng.uniform(0.0, 25.0)), applied_accel_mps2=0.0),
        last_plan=None,
        start_front_m=front_m - 30.0,
        inserted_s=0.0,
    )


@contextmanager
def _long_way(observer: SimpleNamespace, other: SimpleNamespace) -> Iterator[None]:
    """What ``observer`` knows of ``other`` the long way: the report mapped from its edges with ``map_body`` — the
    other's edge as the hint, the observer's as the pass — and nothing remembered."""
    memo = RouteView.map_body_memo

    def map_body(
        self: RouteView, memory: Any, key: Any, view: RouteView, front_m: float, length_m: float, *_: Any
    ) -> Any:
        assert self is observer.view and view is other.view and length_m == other.trip.vehicle.length_m
        return self.map_body(view, front_m, length_m, other.edge_i, observer.edge_i)

    RouteView.map_body_memo = map_body  # type: ignore[method-assign]
    try:
        yield
    finally:
        RouteView.map_body_memo = memo  # type: ignore[method-assign]


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("with_ground", [True, False])
def test_known_with_memory_is_the_long_way(seed: int, with_ground: bool) -> None:
    rng = np.random.default_rng(seed)
    layer = EventLayer(0.0, rng=np.random.default_rng(seed))
    ground = Channel(layer, "t2g", DelaySpec("uniform", low_s=0.1, high_s=0.9), loss_prob=0.2)
    book = SimpleNamespace(of_leader={}, follower_of=None)
    channels = {"t2g": ground} if with_ground else {}
    kn = Knowledge(layer, channels, book, SimpleNamespace(t2t_receivers=lambda _id: ()))  # type: ignore[arg-type]
    views = _views(rng)
    trains = [_train(k, views[int(rng.integers(len(views)))], rng) for k in range(14)]
    silent = trains[-3:]  # never report: their registration, or where they came on the line
    kn.registration[(trains[0].train_id, silent[0].train_id)] = (silent[0].view.route.id, 55.0, 3.0, 0.0, 0.0)
    known = on_track = passed = 0
    occ = Occupancy()
    pick = np.random.default_rng(100 + seed)  # which train is "ahead" of which, for the ground's pass
    for step in range(80):
        t = 0.5 * step
        for tr in trains:
            tr.front_m += 0.5 * tr.plant.speed_mps
            tr.edge_i = tr.view.edge_near(tr.front_m, tr.edge_i)
            if rng.random() < 0.02:  # a jump back (a new trip of its unit, a reversal)
                tr.front_m -= float(rng.uniform(0.0, 300.0))
                tr.edge_i = tr.view.edge_at(tr.front_m)
        talking = [tr for tr in trains if tr not in silent]
        kn.communicate(talking, {tr.train_id: Knowledge.report(t, tr) for tr in talking})  # type: ignore[arg-type]
        layer.advance_to(t)
        passed += _ground_rears_are_known_rear_age(kn, occ, trains, pick, t)
        for observer in trains:
            for other in trains:
                if other is observer:
                    continue
                ahead = bool(rng.random() < 0.5)
                args = (observer, other, "t2g", "ground", ahead)
                answers = (kn.known_rear_age(*args), kn.known_state(*args))  # type: ignore[arg-type]
                with _long_way(observer, other):
                    assert repr(answers) == repr((kn.known_rear_age(*args), kn.known_state(*args)))  # type: ignore[arg-type]
                known += answers[0] is not None
                on_track += answers[0] is not None and answers[1].length_m > 0.0  # type: ignore[union-attr]
    assert known > 2000 and on_track > 1000, "too few trains known on the observer's track to test anything"
    assert passed > (100 if with_ground else -1), "the ground's pass answered too few to test anything"


def _ground_rears_are_known_rear_age(
    kn: Knowledge, occ: Occupancy, trains: list[SimpleNamespace], pick: np.random.Generator, t: float
) -> int:
    """:meth:`Knowledge.ground_rears` for a random train "ahead" of each (some none) gives ``known_rear_age``'s
    answer with ``ahead``; where it leaves one to ask (a NaN rear), the ground has no report of that train or none of
    the reported body is on the observer's track. Returns how many the pass answered itself."""
    ids = [tr.train_id for tr in trains]
    occ.update_columns(
        ids,
        [tr.view for tr in trains],
        [tr.front_m for tr in trains],
        [tr.trip.vehicle.length_m for tr in trains],
        [tr.edge_i for tr in trains],
    )
    slots = pick.integers(-1, len(trains), len(trains))
    slots[slots == np.arange(len(trains))] = -1
    occ.ahead_slots = slots
    rears = kn.ground_rears(t, ids, occ.reported_rears)
    answered = 0
    for observer, o, rear in zip(trains, slots.tolist(), rears):
        if o < 0:
            assert math.isnan(rear[0])
            continue
        other = trains[o]
        if math.isnan(rear[0]):
            box = kn.channels["t2g"].mailbox("ground") if "t2g" in kn.channels else {}
            msg = box.get(other.train_id)
            assert msg is None or kn._body_in_frame(observer, other, msg.payload[1]) is None  # type: ignore[arg-type]
            continue
        assert repr(rear) == repr(kn.known_rear_age(observer, other, "t2g", "ground", ahead=True))  # type: ignore[arg-type]
        answered += 1
    return answered
