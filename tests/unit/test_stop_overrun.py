"""A stop a train cannot make is a missed stop, never a halt SUMO imposes.

SUMO halts a controlled train at the end of its stop *at once*, from any speed (4.5 and 11.3 m/s found, one step
to 0). The engine used to adopt that speed and count the stop served: an overrun hidden behind an impossible
deceleration. Now the stop book declares the stop missed as soon as even the emergency brake applied at once could
not stop the front within the window (:func:`railsim.engine.stops.surely_overruns_m`), and a speed SUMO imposes
beyond the brakes anyway is a ``desync`` and a run failure (:meth:`SafetyMonitor.speed_imposed`). The dangerous
case is built on the mini line: a train starts 50 m before B's stopping mark at 54 km/h (it needs ~90 m).
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from railsim.engine.stops import surely_overruns_m
from railsim.physics import dynamics
from railsim.physics.vehicle import VehicleParams

BARE = VehicleParams("bare", 100.0, 2.0e5, emergency_decel_mps2=1.25)  # no Davis terms: v²/(2 b_e) exactly


class _FlatView:
    def __init__(self, grade: float = 0.0) -> None:
        self.grade = grade

    def gradient_at(self, _chainage_m: float) -> float:
        return self.grade


def _train(front_m: float, vehicle: VehicleParams = BARE, grade: float = 0.0) -> object:
    return SimpleNamespace(front_m=front_m, trip=SimpleNamespace(vehicle=vehicle), view=_FlatView(grade))


def test_least_stop_distance_is_the_closed_form_and_drag_and_grade_shorten_it() -> None:
    assert dynamics.least_stop_distance_m(BARE, 10.0) == pytest.approx(100.0 / 2.5, rel=1e-12)
    assert dynamics.least_stop_distance_m(BARE, 10.0, 20.0) < 40.0  # uphill helps
    assert dynamics.least_stop_distance_m(BARE, 10.0, -20.0) > 40.0  # downhill does not
    assert dynamics.least_stop_distance_m(BARE, 10.0, -200.0) == math.inf  # steeper than the brake


@pytest.mark.parametrize("v", [2.0, 10.0, 20.0])
def test_a_stop_is_surely_missed_exactly_when_the_least_distance_passes_the_tolerance(v: float) -> None:
    end_m, tol_m = 1000.0, 0.5
    least_m = v * v / 2.5
    at_edge = end_m + tol_m - least_m  # the front from which it can just stop at end + tolerance
    assert surely_overruns_m(_train(at_edge - 0.01), end_m, tol_m, v) is None  # type: ignore[arg-type]
    over = surely_overruns_m(_train(at_edge + 0.01), end_m, tol_m, v)  # type: ignore[arg-type]
    assert over == pytest.approx(tol_m + 0.01, abs=1e-9)
    assert surely_overruns_m(_train(at_edge + 5.0, grade=-200.0), end_m, tol_m, v) == math.inf  # type: ignore[arg-type]


def _monitor() -> tuple[object, object]:
    from railsim.engine.events.log import EventLog
    from railsim.engine.safety import SafetyMonitor
    from railsim.engine.settings import EngineSettings

    events = EventLog()
    return SafetyMonitor({}, None, events, EngineSettings()), events  # type: ignore[arg-type]


def _running(sumo_stopped: bool = False, window_end_m: float = 501.0) -> object:
    trip = SimpleNamespace(
        vehicle=BARE, stops=(SimpleNamespace(station_id="c", window_end_m=window_end_m, served_end_m=window_end_m),)
    )
    return SimpleNamespace(
        train_id="x", front_m=500.0, trip=trip, view=_FlatView(), next_stop=0, sumo_stopped=sumo_stopped, sumo_edge="e1"
    )


def test_sumo_stopping_a_train_harder_than_its_brakes_is_a_desync_and_a_failure() -> None:
    """The backstop: SUMO took 4.47 m/s off a running train in one 0.2 s step 1 m before its window's end (the
    fuzz case): it needed at least 8 m."""
    safety, events = _monitor()
    safety.speed_imposed(493.0, _running(), 0.0, 4.47, 0.2)  # type: ignore[attr-defined]
    rows = events.rows("desync")  # type: ignore[attr-defined]
    assert len(rows) == 1 and '"railsim_mps":4.47' in rows[0]["detail"] and '"next_stop":"c"' in rows[0]["detail"]
    assert safety.failure is not None and "harder than its emergency brake" in safety.failure  # type: ignore[attr-defined]


@pytest.mark.parametrize(
    ("sumo_stopped", "railsim_v", "sumo_v"),
    [(True, 4.47, 0.0), (False, 0.2, 0.0), (False, 0.9, 0.0), (False, 4.47, 4.3)],
    ids=["dwelling", "within-the-brake", "within-the-tolerance", "small-cut"],
)
def test_speeds_sumo_may_impose_are_no_desync(sumo_stopped: bool, railsim_v: float, sumo_v: float) -> None:
    """Holding a dwelling train, a cut the brakes could make in the step, or a halt hiding less run than the stop
    tolerance (0.9 m/s: 0.32 m)."""
    safety, events = _monitor()
    safety.speed_imposed(10.0, _running(sumo_stopped), sumo_v, railsim_v, 0.2)  # type: ignore[attr-defined]
    assert events.rows("desync") == [] and safety.failure is None  # type: ignore[attr-defined]


def test_an_early_halt_inside_the_window_is_an_event_not_a_failure() -> None:
    """SUMO halts a short train (40 m on a 220 m platform) ~5 m before its mark from ~2.3 m/s: it could have
    stopped inside the window, so no overrun is hidden; the halt is a ``sumo_forced_halt`` event."""
    safety, events = _monitor()
    safety.speed_imposed(298.5, _running(window_end_m=506.2), 0.0, 2.27, 0.5)  # type: ignore[attr-defined]
    assert safety.failure is None and events.rows("desync") == []  # type: ignore[attr-defined]
    rows = events.rows("sumo_forced_halt")  # type: ignore[attr-defined]
    assert len(rows) == 1 and '"railsim_mps":2.27' in rows[0]["detail"]


def _euler_emergency_stop_m(v: float, decel: float, dt: float) -> float:
    """How far SUMO's Euler positions carry a train braking at ``decel`` from ``v``: each step advances by the new
    speed times the step."""
    run_m = 0.0
    while v > 0.0:
        v = max(v - decel * dt, 0.0)
        run_m += v * dt
    return run_m


@pytest.mark.parametrize("v", [0.9, 3.754, 7.0, 12.3, 20.0])
@pytest.mark.parametrize("dt", [0.1, 0.5, 1.0])
def test_with_euler_positions_a_stop_is_missed_only_when_the_euler_run_passes_the_tolerance(
    v: float, dt: float
) -> None:
    """The bound for Euler positions is never longer than the run SUMO gives (a miss declared is a miss) and
    within half a step's advance of it."""
    end_m, tol_m = 1000.0, 0.5
    run_m = _euler_emergency_stop_m(v, 1.25, dt)
    assert v * v / 2.5 - 0.5 * v * dt <= run_m + 1e-9 <= v * v / 2.5 + 1e-9
    can_m = end_m + tol_m - run_m  # the front from which the Euler run just stops at end + tolerance
    assert surely_overruns_m(_train(can_m - 1e-6), end_m, tol_m, v, dt) is None  # type: ignore[arg-type]
    assert surely_overruns_m(_train(can_m + 0.5 * v * dt + 1e-6), end_m, tol_m, v, dt) is not None  # type: ignore[arg-type]


def test_dresden_zschertnitz_a_tram_on_its_service_brake_is_not_declared_past_its_stop() -> None:
    """The case found: 3.754 m/s, 4.745 m short of the platform's end, 0.5 s steps. The continuous bound (5.64 m)
    called the stop missed by 0.52 m; on the service brake with its running resistance (1.2 m/s² net) SUMO's Euler
    positions stop it 0.22 m past the end, within the tolerance."""
    front_m, end_m, v, dt = 995.255, 1000.0, 3.754, 0.5
    assert surely_overruns_m(_train(front_m), end_m, 0.5, v) is not None  # type: ignore[arg-type]
    assert surely_overruns_m(_train(front_m), end_m, 0.5, v, dt) is None  # type: ignore[arg-type]
    assert front_m + _euler_emergency_stop_m(v, 1.2, dt) == pytest.approx(end_m + 0.217, abs=1e-3)
