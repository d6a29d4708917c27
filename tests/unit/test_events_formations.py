"""Formation state machine: free → coupling → coupled → decoupling → free, failures, invalid commands."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from railsim.engine.events import EventLayer, Formation, FormationManager
from railsim.errors import ConfigError

DT = 0.5


def setup(**kw: float) -> tuple[EventLayer, FormationManager, Formation]:
    layer = EventLayer(0.0, rng=np.random.default_rng(0))
    manager = FormationManager(layer)
    params = dict(target_gap_m=20.0, separation_gap_m=100.0, hold_s=5.0, coupling_timeout_s=60.0)
    params.update(kw)
    formation = Formation("F1", "L", "F", **params)  # type: ignore[arg-type]
    manager.add(formation)
    return layer, manager, formation


def run(layer: EventLayer, manager: FormationManager, until_s: float, gap_of, dv_of=lambda t: 0.0) -> None:
    """Engine-like loop: advance the clock to each step, then report the ground truth at that step."""
    k = round(layer.now_s / DT)
    while layer.now_s < until_s:
        k += 1
        t = k * DT
        layer.advance_to(t)
        manager.observe(t, "F1", gap_of(t), dv_of(t))


def details(layer: EventLayer, kind: str) -> list[tuple[float, dict]]:
    return [(r["t_s"], json.loads(r["detail"])) for r in layer.log.rows(kind)]


def test_couple_after_hold_with_exact_time_to_couple() -> None:
    layer, manager, _ = setup()
    layer.advance_to(10.0)
    manager.request_couple("F1")
    assert manager.state("F1") == "coupling"
    # Gap closes linearly from 80 m at 2 m/s; enters the band (≤ 22 m) at t = 39.0 s, a step time.
    run(layer, manager, 60.0, gap_of=lambda t: max(20.0, 80.0 - 2.0 * (t - 10.0)))
    assert manager.state("F1") == "coupled"
    ((t_c, d),) = details(layer, "coupled")
    assert t_c == 39.0 + 5.0
    assert d["time_to_couple_s"] == 44.0 - 10.0
    stats = manager.stats("F1")
    assert stats.successes == 1 and stats.failures == 0 and stats.time_to_couple_s == (34.0,)
    assert stats.coupled_time_s == pytest.approx(60.0 - 44.0)


def test_lock_in_happens_between_steps_at_exactly_entry_plus_hold() -> None:
    layer, manager, _ = setup(hold_s=2.3)
    manager.request_couple("F1")
    run(layer, manager, 10.0, gap_of=lambda t: 21.0)  # in band from the first observation, t = 0.5
    ((t_c, d),) = details(layer, "coupled")
    assert t_c == 0.5 + 2.3 and d["time_to_couple_s"] == 0.5 + 2.3


def test_leaving_the_band_restarts_the_hold() -> None:
    layer, manager, _ = setup(hold_s=5.0)
    manager.request_couple("F1")
    # In band on [0.5, 3.0], a speed excursion at 3.5, in band again from 4.0.
    run(layer, manager, 20.0, gap_of=lambda t: 20.0, dv_of=lambda t: 1.0 if t == 3.5 else 0.0)
    ((t_c, _),) = details(layer, "coupled")
    assert t_c == 4.0 + 5.0


def test_timeout_fails_and_returns_to_free() -> None:
    layer, manager, _ = setup(coupling_timeout_s=30.0)
    layer.advance_to(5.0)
    manager.request_couple("F1")
    run(layer, manager, 50.0, gap_of=lambda t: 60.0)  # never closes the gap
    assert manager.state("F1") == "free"
    ((t_f, d),) = details(layer, "coupling_failed")
    assert t_f == 35.0 and d["reason"] == "timeout" and d["last_gap_m"] == 60.0
    stats = manager.stats("F1")
    assert (stats.successes, stats.failures, stats.time_to_couple_s) == (0, 1, ())
    # A new attempt after a failure is allowed and can succeed.
    manager.request_couple("F1")
    run(layer, manager, 70.0, gap_of=lambda t: 20.0)
    assert manager.state("F1") == "coupled"
    assert manager.stats("F1").successes == 1


def test_hold_ending_exactly_at_the_deadline_counts_as_success() -> None:
    layer, manager, _ = setup(hold_s=5.0, coupling_timeout_s=10.0)
    manager.request_couple("F1")
    run(layer, manager, 20.0, gap_of=lambda t: 20.0 if t >= 5.0 else 50.0)
    assert details(layer, "coupled")[0][0] == 10.0
    assert layer.log.count("coupling_failed") == 0


def test_decouple_completes_when_separated() -> None:
    layer, manager, _ = setup(hold_s=1.0)
    manager.request_couple("F1")
    run(layer, manager, 5.0, gap_of=lambda t: 20.0)
    assert manager.state("F1") == "coupled"
    manager.request_decouple("F1")
    assert manager.state("F1") == "decoupling"
    assert manager.target_gap_m("F") is None
    # The gap opens at 4 m/s from 20 m; reaches 100 m at t = 25 s.
    run(layer, manager, 40.0, gap_of=lambda t: 20.0 + 4.0 * max(0.0, t - 5.0))
    assert manager.state("F1") == "free"
    ((t_d, d),) = details(layer, "decoupled")
    assert t_d == 25.0 and d["gap_m"] == 100.0
    assert manager.stats("F1").coupled_time_s == pytest.approx(5.0 - 1.5)


def test_scheduled_commands_fire_at_exact_times() -> None:
    layer, manager, _ = setup(hold_s=1.0)
    manager.request_couple("F1", at_s=3.25)
    manager.request_decouple("F1", at_s=12.75)
    with pytest.raises(ValueError):
        manager.request_couple("F1", at_s=-1.0)
    run(layer, manager, 30.0, gap_of=lambda t: 20.0 if t < 15.0 else 150.0)
    assert details(layer, "couple_requested")[0][0] == 3.25
    assert details(layer, "coupled")[0][0] == 3.5 + 1.0  # first in-band observation after the request
    assert details(layer, "coupled")[0][1]["time_to_couple_s"] == 4.5 - 3.25
    assert details(layer, "decouple_requested")[0][0] == 12.75
    assert details(layer, "decoupled")[0][0] == 15.0


def test_invalid_transitions_are_logged_and_ignored() -> None:
    layer, manager, _ = setup(hold_s=1.0)
    manager.request_decouple("F1")  # free: invalid
    assert manager.state("F1") == "free"
    manager.request_couple("F1")
    manager.request_couple("F1")  # already coupling: invalid
    run(layer, manager, 3.0, gap_of=lambda t: 20.0)
    manager.request_couple("F1")  # already coupled: invalid
    assert manager.state("F1") == "coupled"
    manager.request_decouple("F1")
    manager.request_decouple("F1")  # already decoupling: invalid
    assert manager.state("F1") == "decoupling"
    invalid = details(layer, "invalid_request")
    assert [(d["request"], d["state"]) for _, d in invalid] == [
        ("decouple", "free"),
        ("couple", "coupling"),
        ("couple", "coupled"),
        ("decouple", "decoupling"),
    ]
    stats = manager.stats("F1")
    assert stats.invalid_requests == 4 and stats.couple_requests == 3 and stats.decouple_requests == 3
    assert stats.successes == 1
    with pytest.raises(KeyError):
        manager.request_couple("nope")


def test_decouple_while_coupling_aborts() -> None:
    layer, manager, _ = setup(hold_s=5.0)
    manager.request_couple("F1")
    run(layer, manager, 2.0, gap_of=lambda t: 20.0)
    manager.request_decouple("F1")
    run(layer, manager, 20.0, gap_of=lambda t: 20.0)  # the old hold timer must not couple it
    assert manager.state("F1") == "decoupling"
    assert layer.log.count("coupled") == 0 and layer.log.count("coupling_aborted") == 1
    assert manager.stats("F1").aborts == 1


def test_roles_and_target_gap() -> None:
    layer = EventLayer(0.0, rng=np.random.default_rng(0))
    manager = FormationManager(layer)
    manager.add(Formation("A", "T1", "T2", target_gap_m=15.0, separation_gap_m=80.0, hold_s=0.0))
    manager.add(Formation("B", "T2", "T3", target_gap_m=25.0, separation_gap_m=80.0))
    with pytest.raises(ValueError, match="already follows"):
        manager.add(Formation("C", "T9", "T3", target_gap_m=25.0, separation_gap_m=80.0))
    with pytest.raises(ValueError, match="already exists"):
        manager.add(Formation("A", "T8", "T9", target_gap_m=25.0, separation_gap_m=80.0))
    assert manager.role_of("T1") == ("A", "leader", "free")
    assert manager.role_of("T2") == ("A", "follower", "free")  # follower role first
    assert manager.roles_of("T2") == [("A", "follower", "free"), ("B", "leader", "free")]
    assert manager.role_of("T7") is None
    assert manager.target_gap_m("T2") is None
    manager.request_couple("A")
    assert manager.target_gap_m("T2") == 15.0
    assert manager.target_gap_m("T1") is None  # a leader has no target gap
    layer.advance_to(1.0)
    manager.observe(1.0, "A", 15.0, 0.0)
    layer.advance_to(1.0)  # hold_s = 0: coupled at the entry instant
    assert manager.role_of("T2") == ("A", "follower", "coupled")
    assert manager.target_gap_m("T2") == 15.0


def test_bad_parameters_are_config_errors() -> None:
    with pytest.raises(ConfigError, match="target_gap_m"):
        Formation("X", "a", "b", target_gap_m=-1.0, separation_gap_m=50.0)
    with pytest.raises(ConfigError, match="separation_gap_m"):
        Formation("X", "a", "b", target_gap_m=20.0, separation_gap_m=21.0)
    with pytest.raises(ConfigError, match="follow itself"):
        Formation("X", "a", "a", target_gap_m=20.0, separation_gap_m=50.0)


def test_non_finite_observation_raises() -> None:
    layer, manager, _ = setup()
    with pytest.raises(ValueError):
        manager.observe(0.0, "F1", float("nan"), 0.0)


@settings(max_examples=60, deadline=None)
@given(
    entry_step=st.integers(min_value=1, max_value=80),
    hold_s=st.floats(min_value=0.0, max_value=20.0),
    timeout_s=st.floats(min_value=1.0, max_value=60.0),
)
def test_outcome_matches_closed_form(entry_step: int, hold_s: float, timeout_s: float) -> None:
    """Gap in band from step `entry_step` on: coupled at entry + hold if that is ≤ timeout, else failed."""
    layer, manager, _ = setup(hold_s=hold_s, coupling_timeout_s=timeout_s)
    t_entry = entry_step * DT
    manager.request_couple("F1")
    run(layer, manager, 100.0, gap_of=lambda t: 20.0 if t >= t_entry else 40.0)
    if t_entry + hold_s <= timeout_s:
        assert [t for t, _ in details(layer, "coupled")] == [t_entry + hold_s]
        assert layer.log.count("coupling_failed") == 0
    else:
        assert [t for t, _ in details(layer, "coupling_failed")] == [timeout_s]
        assert layer.log.count("coupled") == 0
        assert manager.state("F1") == "free"
