"""The stop book's far-from-the-stop screen against the full pass it stands for, over random runs.

:meth:`StopBook.bookkeeping` returns at once for a train whose front is short of its next stop's window, that SUMO
has not registered as stopped and that can still stop in time (``railsim.engine.stops``, "Far from the stop"). The
reference is the same book with the screen off (``screen_far = False``): the full pass every step. Two copies of a
train run the same random drive — cruising, braking, halts in, short of and just past the windows, speeds that
surely overrun a stop, SUMO registering and releasing stops (and registering a moving train), reversal flips, the
trip's stops replaced by new ones (a turnback, a primary delay) and its vehicle changed — and after every step their
state, the event log and the stop records must be the same.
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from railsim.engine.events.log import EventLog
from railsim.engine.settings import EngineSettings
from railsim.engine.stops import StopBook
from railsim.engine.trips import TripStop
from railsim.physics.vehicle import VehicleParams

_VEHICLES = [
    VehicleParams("a", 100.0, 2.0e5, emergency_decel_mps2=1.25),
    VehicleParams("b", 60.0, 1.5e5, emergency_decel_mps2=0.3),  # weak: a stale brake would pass the screen
]


def _stops(rng: np.random.Generator, shift_m: float) -> tuple[TripStop, ...]:
    """An origin, stations (some on platforms shorter than the train, with an overrun), a reversal, a destination."""
    stops, at_m = [], shift_m
    n = int(rng.integers(3, 7))
    for k in range(n):
        length_m = float(rng.choice([10.0, 30.0, 80.0]))
        short = rng.random() < 0.3
        start_m = at_m + float(rng.uniform(150.0, 600.0)) * (k > 0)
        end_m = start_m + length_m
        kind = "reversal" if 0 < k < n - 1 and rng.random() < 0.2 else "station"
        stops.append(
            TripStop(
                station_id=f"S{k}",
                stop_id=f"e{k}",
                mark_m=end_m - 2.0,
                window_start_m=start_m,
                window_end_m=end_m,
                dwell_s=float(rng.choice([0.0, 1.0, 3.0])),
                is_origin=k == 0,
                is_destination=k == n - 1,
                kind=kind,
                lane_stop_m=(0.0, length_m) if short else None,
                platform_m=length_m,
                overrun_m=1.0 if short else 0.0,
            )
        )
        at_m = end_m
    return tuple(stops)


def _train(stops: tuple[TripStop, ...], vehicle: VehicleParams) -> SimpleNamespace:
    trip = SimpleNamespace(stops=stops, vehicle=vehicle, service_id="svc", planned_arrival_s={"S1": 30.0})
    return SimpleNamespace(
        train_id="T", sumo_id="T", trip=trip, view=SimpleNamespace(gradient_at=lambda _m: 0.0),
        plant=SimpleNamespace(speed_mps=0.0), status="running", next_stop=1, front_m=stops[0].window_end_m - 1.0,
        halted_s=None, halt_error_m=None, sumo_stopped=False, sumo_stopped_now=False, dwell_started_s=None,
        dwell_until_s=None, held_for_route=False, departed_s=None, arrived_s=None, stops_served=0, sumo_edge="",
        reversing=False, hold_until_s=None,
    )  # fmt: skip


def _state(tr: SimpleNamespace) -> dict[str, Any]:
    out = {k: v for k, v in vars(tr).items() if k not in ("trip", "view", "plant")}
    out["speed"] = tr.plant.speed_mps
    return out


def _book(screen_far: bool, rng: np.random.Generator) -> tuple[StopBook, EventLog, list[dict[str, Any]]]:
    events, records = EventLog(), []
    formations = SimpleNamespace(
        of_follower={},
        mark_offset_m=lambda tr, stop: 0.0,
        turnback_waits=lambda: (lambda tr: False, lambda t, tr: False),
        on_departed_station=lambda tr, stop: None,
    )
    route_set = np.random.default_rng(int(rng.integers(1 << 30)))  # the same answers for both books
    routes = SimpleNamespace(
        wanted_by_others=lambda tr: False,
        clears_platform=lambda tr, stop: bool(route_set.random() < 0.7),
        release_all=lambda tr: None,
    )
    book = StopBook(formations, routes, events, EngineSettings(), lambda **kw: records.append(kw), None)  # type: ignore[arg-type]
    book.connect(lambda *a: events.record(0.0, "dropped", str(a)))
    book.screen_far = screen_far
    return book, events, records


def _run(seed: int) -> tuple[int, int, float]:
    rng = np.random.default_rng(seed)
    stops = _stops(rng, 0.0)
    trains = [_train(stops, _VEHICLES[0]), _train(stops, _VEHICLES[0])]
    books = [_book(True, np.random.default_rng(seed)), _book(False, np.random.default_rng(seed))]
    dt, fast_steps = 0.5, 0
    full_passes: list[float] = []
    full = books[0][0]._full_pass
    books[0][0]._full_pass = lambda t, tr: (full_passes.append(t), full(t, tr))  # type: ignore[method-assign]
    for step in range(1500):
        t = step * dt
        a = trains[0]
        if a.status == "arrived":
            break
        stop = a.trip.stops[a.next_stop] if a.next_stop < len(a.trip.stops) else None
        v, front = a.plant.speed_mps, a.front_m
        registered_now = a.sumo_stopped_now
        if a.sumo_stopped:  # SUMO holds it for a while, then releases it
            v, registered_now = 0.0, bool(rng.random() < 0.8)
        elif stop is not None and v == 0.0 and stop.window_start_m - 0.5 <= front <= stop.window_end_m + 0.5:
            registered_now = bool(rng.random() < 0.5)  # SUMO registers the halt (~1 s later), or not
        else:
            registered_now = bool(rng.random() < 0.003)  # a spurious registration (a moving train)
            to_go = (stop.mark_m - front) if stop is not None else 1e9
            if to_go < 0.0 or rng.random() < 0.02:
                v = float(rng.choice([0.0, v, 25.0]))  # halts anywhere, a burst of speed
            elif to_go < v * v / 2.0 + 5.0:
                v = max(0.0, v - float(rng.choice([0.4, 0.5, 0.6, 3.0]))) if to_go > 0.3 else 0.0
            else:
                v = min(20.0, v + 0.5)
            front += v * dt
        if rng.random() < 0.01:  # the trip's stops replaced (turnback, primary delay): a new tuple, moved
            back_m = float(rng.choice([5.0, 40.0]))  # the windows come nearer: stale bounds would miss them
            new = tuple(
                dataclasses.replace(
                    s, mark_m=s.mark_m - back_m, window_start_m=s.window_start_m - back_m,
                    window_end_m=s.window_end_m - back_m,
                )
                for s in a.trip.stops
            )  # fmt: skip
            for tr in trains:
                tr.trip.stops = new
        if rng.random() < 0.01:
            vehicle = _VEHICLES[int(rng.integers(0, 2))]
            for tr in trains:
                tr.trip.vehicle = vehicle
        flip = stop is not None and stop.kind == "reversal" and v == 0.0 and rng.random() < 0.3
        for tr in trains:
            tr.plant.speed_mps, tr.front_m, tr.sumo_stopped_now = v, front, registered_now
            tr.sumo_edge = stop.stop_id if flip and stop is not None else "x"
        before = len(books[0][1].rows())
        for (book, _, _), tr in zip(books, trains):
            book.bookkeeping(t, tr)
        assert _state(trains[0]) == _state(trains[1]), f"step {step}"
        assert books[0][1].rows() == books[1][1].rows() and books[0][2] == books[1][2], f"step {step}"
        fast_steps += len(books[0][1].rows()) == before and not a.sumo_stopped
    return fast_steps, len(books[0][1].rows()), 1.0 - len(full_passes) / (step + 1)


@pytest.mark.parametrize("seed", range(60))
def test_far_screen_keeps_every_event_and_record(seed: int) -> None:
    quiet_steps, n_events, screened = _run(seed)
    assert quiet_steps > 20 and n_events > 3, "too little happened: test too weak"
    assert screened > 0.1, "the screen hardly ever acted: test too weak"


def _counted() -> tuple[Any, Any, StopBook, list[float]]:
    """A screened stop book, a train and its stops, and the times at which the book ran its full pass."""
    stops = _stops(np.random.default_rng(3), 0.0)
    tr = _train(stops, _VEHICLES[0])
    book, _, _ = _book(True, np.random.default_rng(0))
    calls: list[float] = []
    full = book._full_pass
    book._full_pass = lambda t, tr: (calls.append(t), full(t, tr))  # type: ignore[method-assign]
    return stops, tr, book, calls


@pytest.mark.parametrize(
    ("to_window_m", "speed_mps", "full_pass"),
    [(200.0, 10.0, False), (-1.0, 10.0, True), (20.0, 15.0, True), (20.0, 0.0, False)],
)
def test_the_screen_returns_early_only_far_from_the_stop(to_window_m: float, speed_mps: float, full_pass: bool) -> None:
    """The screen acts: short of the window and able to stop, the full pass is not run; in the window, or unable
    to stop in time even on the emergency brake (15 m/s needs 90 m), it is."""
    stops, tr, book, calls = _counted()
    tr.plant.speed_mps, tr.front_m = speed_mps, stops[1].window_start_m - to_window_m
    book.bookkeeping(1.0, tr)
    assert calls == ([1.0] if full_pass else [])


def test_the_screen_follows_the_next_stop_and_the_vehicle() -> None:
    """Bounds are worked out anew for the next stop (far from it, the screen acts again) and for a new vehicle (a
    weaker brake that cannot stop in time: the full pass runs)."""
    stops, tr, book, calls = _counted()
    tr.plant.speed_mps, tr.front_m = 5.0, stops[1].window_start_m - 100.0
    book.bookkeeping(1.0, tr)
    tr.next_stop, tr.front_m = 2, stops[2].window_start_m - 100.0  # stop 1 left behind
    book.bookkeeping(2.0, tr)
    assert calls == []
    tr.plant.speed_mps, tr.front_m = 10.0, stops[2].window_start_m - 40.0  # to stop: 40 m on 1.25 m/s², 167 on 0.3
    book.bookkeeping(3.0, tr)
    assert calls == []
    tr.trip.vehicle = _VEHICLES[1]
    book.bookkeeping(4.0, tr)
    assert calls == [4.0]


@pytest.mark.parametrize(("kind", "registered_now", "full_pass"), [
    ("station", True, False), ("station", False, True), ("reversal", True, True),
])  # fmt: skip
def test_a_dwelling_train_skips_the_full_pass_except_at_a_reversal(
    kind: str, registered_now: bool, full_pass: bool
) -> None:
    """A train SUMO holds at its stop has nothing to do till its dwell ends: no full pass — unless its stop is a
    reversal (SUMO flips it there), or SUMO has just let it go (the departure is decided in the full pass)."""
    stops, tr, book, calls = _counted()
    tr.trip.stops = stops[:1] + (dataclasses.replace(stops[1], kind=kind),) + stops[2:]
    tr.front_m, tr.sumo_stopped, tr.sumo_stopped_now = stops[1].mark_m, True, registered_now
    book.bookkeeping(1.0, tr)
    assert calls == ([1.0] if full_pass else [])
