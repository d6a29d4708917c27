"""The event layer's clock, log and dispatcher: monotonic time, exact event times, deterministic rows."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from railsim.engine.events import Dispatcher, EventLayer, EventLog


def make_layer(t0_s: float = 0.0, seed: int = 0) -> EventLayer:
    return EventLayer(t0_s, rng=np.random.default_rng(seed))


# ---------------------------------------------------------------- exact times
def test_plain_simpy_cannot_hit_this_time_but_the_layer_does() -> None:
    now, t = 6.144, 28.365
    # No double d gives now + d == t: the sums skip over t (why the layer schedules at absolute times).
    d = t - now
    neighbours = {now + math.nextafter(d, -math.inf), now + d, now + math.nextafter(d, math.inf)}
    assert t not in neighbours
    layer = make_layer(now)
    seen: list[float] = []
    layer.at(t, lambda ts: seen.append(layer.now_s), kind="k", subject="")
    layer.advance_to(t)
    assert seen == [t] and layer.now_s == t
    layer.advance_to(t)  # must not look like going backwards
    assert layer.now_s == t


@settings(max_examples=200, deadline=None)
@given(
    now=st.floats(min_value=0.0, max_value=1e6, allow_nan=False),
    offsets=st.lists(st.floats(min_value=0.0, max_value=1e4, allow_nan=False), min_size=1, max_size=8),
    n_steps=st.integers(min_value=1, max_value=60),
)
def test_events_run_at_exact_times_and_in_time_order(now: float, offsets: list[float], n_steps: int) -> None:
    layer = make_layer(now)
    targets = [now + o for o in offsets]
    seen: list[tuple[float, float]] = []
    for t in targets:
        layer.at(t, lambda ts: seen.append((ts, layer.now_s)), kind="k", subject="")
    horizon = max(targets)
    step = (horizon - now) / n_steps  # engine-like steps t0 + k*dt that rarely coincide with event times
    for k in range(1, n_steps + 1):  # bounded: a step that rounds to 0 must not loop forever
        layer.advance_to(min(now + k * step, horizon))
    layer.advance_to(horizon)  # events due at the current time run even when time does not move
    assert [a for a, _ in seen] == sorted(targets)
    assert all(ts == clock for ts, clock in seen)


# ---------------------------------------------------------------- advance_to
def test_advance_to_backwards_raises_and_same_time_is_noop() -> None:
    layer = make_layer(10.0)
    assert layer.now_s == 10.0
    layer.advance_to(12.5)
    assert layer.now_s == 12.5
    layer.advance_to(12.5)  # no-op
    assert layer.now_s == 12.5
    assert len(layer.log) == 0
    with pytest.raises(ValueError, match="forward"):
        layer.advance_to(12.4)
    with pytest.raises(ValueError):
        layer.advance_to(math.nan)
    assert layer.now_s == 12.5


def test_events_fire_at_exact_times_between_steps_and_on_the_boundary() -> None:
    layer = make_layer(0.0)
    fired: list[tuple[float, float]] = []  # (event time, layer time when it ran)
    for t in (0.3, 0.7, 1.0, 1.0000001):
        layer.at(t, lambda ts: fired.append((ts, layer.now_s)), kind="tick", subject="x")
    steps = [0.5, 1.0]
    layer.advance_to(steps[0])
    assert fired == [(0.3, 0.3)]
    layer.advance_to(steps[1])
    # The event due exactly at the step time has happened when the engine looks at that step.
    assert fired == [(0.3, 0.3), (0.7, 0.7), (1.0, 1.0)]
    assert layer.now_s == 1.0
    assert [r["t_s"] for r in layer.log.rows("tick")] == [0.3, 0.7, 1.0]
    layer.advance_to(2.0)
    assert fired[-1] == (1.0000001, 1.0000001)


def test_many_small_steps_keep_exact_event_time() -> None:
    # Steps computed as k*dt are not multiples of the event time in floating point; the event time is.
    layer = make_layer()
    seen: list[float] = []
    layer.at(0.3, lambda ts: seen.append(layer.now_s), kind="e", subject="")
    for k in range(1, 11):
        layer.advance_to(k * 0.1)
    assert seen == [0.3]
    assert layer.log.rows("e")[0]["t_s"] == 0.3


def test_advance_to_now_runs_zero_delay_consequences() -> None:
    layer = make_layer()
    layer.advance_to(5.0)
    seen: list[float] = []
    layer.at(5.0, seen.append, kind="now", subject="")
    assert seen == []
    layer.advance_to(5.0)  # time does not move, the due event runs
    assert seen == [5.0]
    assert layer.now_s == 5.0


def test_at_in_the_past_raises_and_cancel_works() -> None:
    layer = make_layer()
    layer.advance_to(3.0)
    with pytest.raises(ValueError):
        layer.at(2.0, lambda t: None, kind="k")
    seen: list[float] = []
    handle = layer.at(4.0, seen.append, kind="k", subject="s")
    handle.cancel()
    layer.advance_to(5.0)
    assert seen == [] and layer.log.count("k") == 0


def test_every_has_no_drift_and_stops_on_cancel() -> None:
    layer = make_layer()
    ticks: list[float] = []
    handle = layer.every(0.1, ticks.append, start_s=1.0)
    layer.advance_to(2.0)
    assert ticks == [1.0 + n * 0.1 for n in range(11)]  # computed as start + n*period, exactly
    handle.cancel()
    layer.advance_to(3.0)
    assert len(ticks) == 11
    with pytest.raises(ValueError):
        layer.every(0.0, ticks.append)


def test_rng_must_be_a_generator_and_children_are_deterministic() -> None:
    with pytest.raises(TypeError):
        EventLayer(0.0, rng=42)  # type: ignore[arg-type]
    a, b = make_layer(seed=7), make_layer(seed=7)
    assert a.spawn_rng().random(5).tolist() == b.spawn_rng().random(5).tolist()
    c = make_layer(seed=8)
    assert make_layer(seed=7).spawn_rng().random() != c.spawn_rng().random()


# ---------------------------------------------------------------- log
def test_log_rows_are_sorted_deterministic_and_json() -> None:
    log = EventLog()
    log.record(2.0, "b", "x", gap_m=np.float64(3.5), trains={"T2", "T1"})
    log.record(1.0, "a", "y")
    log.record(2.0, "a", "z", n=1)
    rows = log.rows()
    assert [(r["t_s"], r["kind"], r["subject"]) for r in rows] == [(1.0, "a", "y"), (2.0, "b", "x"), (2.0, "a", "z")]
    assert json.loads(rows[1]["detail"]) == {"gap_m": 3.5, "trains": ["T1", "T2"]}
    assert rows[1]["detail"] == '{"gap_m":3.5,"trains":["T1","T2"]}'
    assert log.count("a") == 2 and log.count("b") == 1 and log.count("c") == 0
    assert [r["subject"] for r in log.rows(kind="a")] == ["y", "z"]
    assert log.entries(subject="x")[0].detail["gap_m"] == 3.5


def test_log_refuses_nan_and_non_json() -> None:
    log = EventLog()
    with pytest.raises(ValueError):
        log.record(1.0, "k", "s", gap_m=math.nan)
    with pytest.raises(ValueError):
        log.record(math.inf, "k", "s")
    with pytest.raises(TypeError):
        log.record(1.0, "k", "s", obj=object())
    assert len(log) == 0


# ---------------------------------------------------------------- dispatch
def test_dispatcher_calls_at_exact_departure_times() -> None:
    layer = make_layer(100.0)
    dispatcher = Dispatcher(layer)
    calls: list[tuple[str, float, float]] = []
    for trip, t in (("T2", 130.25), ("T1", 110.0), ("T3", 200.0)):
        dispatcher.schedule_departure(t, trip, lambda trip_id, ts: calls.append((trip_id, ts, layer.now_s)))
    dispatcher.cancel("T3")
    assert dispatcher.pending() == ("T1", "T2")
    with pytest.raises(ValueError):
        dispatcher.schedule_departure(150.0, "T1", lambda *a: None)
    with pytest.raises(ValueError):
        dispatcher.schedule_departure(50.0, "T9", lambda *a: None)
    t = 100.0
    while t < 300.0:
        t += 1.0
        layer.advance_to(t)
    assert calls == [("T1", 110.0, 110.0), ("T2", 130.25, 130.25)]
    rows = layer.log.rows("departure_due")
    assert [(r["t_s"], r["subject"]) for r in rows] == [(110.0, "T1"), (130.25, "T2")]
    assert dispatcher.pending() == ()
