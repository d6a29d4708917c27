"""The berth rule's cheap path (:mod:`railsim.engine.platforms`) decides exactly as the rule did before it.

:class:`~railsim.engine.platforms.Berths` asks the geometry first and looks the train ahead up only once it could
matter, with no closure built per call, and leaves the ``waiting``/imposed books alone when they are empty. The
rule as it was before is kept here word for word (:class:`ReferenceBerths`, :func:`berth_limit_reference_m`) and
both run side by side over random sequences of states: followers before, at and past a platform's limit, running
and standing, heading for station and non-station stops; trains ahead on, short of and beyond the platform,
standing, moving, or heading for a stop there; formations whose follower is coupled behind the train ahead; the
rule switched off. After every call both must give the same authority end and hold the same books (who waits
for whom, which limits are imposed, which ``platform_occupied`` were logged) and the same event log.

:func:`test_a_broken_fast_path_is_caught` breaks the fast path on purpose (a moving occupant counted as
standing, the coupled exemption skipped, the let-in tolerance dropped) and checks the comparison catches it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from railsim.engine import platforms
from railsim.engine.events.log import EventLog
from railsim.engine.occupancy import Ahead
from railsim.engine.platforms import BERTH_WAIT_M, Berths, service_braking_m
from railsim.engine.settings import EngineSettings
from railsim.engine.trips import TripStop
from railsim.physics.vehicle import preset

DT_S = 0.5
VEH = preset("cq3_6car")
STATIONS = ("a", "b", "c")
PLATFORM_M = 220.0
SEEDS, STEPS = 6, 3000


def berth_limit_reference_m(
    front_m: float,
    train_id: str,
    stop: TripStop | None,
    ahead: Ahead | None,
    ahead_standing: Callable[[], bool],
    overlap_m: float,
    coupled_behind: Callable[[str, str], bool],
) -> float | None:
    """``platforms.berth_limit_m`` before the cheap path, word for word."""
    if ahead is None or stop is None or stop.kind != "station":
        return None
    platform_start_m = stop.window_end_m - stop.platform_m
    limit_m = platform_start_m - overlap_m
    if front_m > limit_m + 1e-6:  # already let in (or standing at the platform)
        return None
    if ahead.rear_m >= stop.window_end_m or ahead.front_m <= platform_start_m:
        return None  # the train ahead is clear of the platform (beyond it, or not on it yet)
    if not ahead_standing():
        return None  # a train ahead that is moving draws clear: the follower may run in behind it (separation)
    if coupled_behind(train_id, ahead.train_id):
        return None
    return limit_m


def _stops_at_reference(tr: Any, station_id: str) -> bool:
    return tr.next_stop < len(tr.trip.stops) and tr.trip.stops[tr.next_stop].station_id == station_id


class ReferenceBerths(Berths):
    """``Berths.authority_end_m`` before the cheap path, word for word."""

    def authority_end_m(self, t: float, tr: Any, stop: TripStop | None, a: Ahead | None, authority_m: float) -> float:
        self.waiting.pop(tr.train_id, None)
        if a is None or stop is None or not self.settings.platform_berths:
            if self._imposed:  # no limit now: one given before is no longer held
                self._imposed.pop(tr.train_id, None)
            return authority_m
        occupant = self.trains[a.train_id]

        def standing() -> bool:
            return occupant.plant.speed_mps == 0.0 or _stops_at_reference(occupant, stop.station_id)

        margin_m = self.settings.protection_margin_m
        berth_m = berth_limit_reference_m(tr.front_m, tr.train_id, stop, a, standing, margin_m, self.coupled_behind)
        if berth_m is None:
            self._imposed.pop(tr.train_id, None)
            return authority_m
        if self._imposed.get(tr.train_id) != stop.station_id:
            if berth_m - tr.front_m < service_braking_m(tr, self.dt_s):
                return authority_m  # too late to stop for it: let in (approach locking), separation keeps it back
            self._imposed[tr.train_id] = stop.station_id
        if berth_m >= authority_m:
            return authority_m
        if tr.plant.speed_mps == 0.0 and berth_m - tr.front_m < BERTH_WAIT_M:  # standing at the limit: it waits
            self.waiting[tr.train_id] = (stop.station_id, a.train_id)
            key = (tr.train_id, stop.station_id)
            if key not in self._logged:
                self._logged.add(key)
                self.events.record(t, "platform_occupied", tr.train_id, station=stop.station_id, by=a.train_id)
        return berth_m


def _stop(station: str, end_m: float, kind: str) -> TripStop:
    return TripStop(
        station, f"{station}.up", end_m - 1.0, end_m - 130.0, end_m, 30.0, False, False, kind, None, PLATFORM_M
    )


class World:
    """A few trains near one platform per station, states drawn anew at every step (the books carry over)."""

    def __init__(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)
        self.ends_m = {s: 5_000.0 + 3_000.0 * i for i, s in enumerate(STATIONS)}
        self.trains: dict[str, SimpleNamespace] = {}
        for i in range(5):
            stops = [_stop(s, self.ends_m[s], "station" if k % 3 else "waypoint") for k, s in enumerate(STATIONS)]
            trip = SimpleNamespace(vehicle=VEH, stops=stops)
            self.trains[f"t{i}"] = SimpleNamespace(
                train_id=f"t{i}", front_m=0.0, plant=SimpleNamespace(speed_mps=0.0), trip=trip, next_stop=0
            )
        self.coupled: set[tuple[str, str]] = set()

    def coupled_behind(self, train_id: str, ahead_id: str) -> bool:
        return (train_id, ahead_id) in self.coupled

    def draw(self) -> tuple[Any, TripStop | None, Ahead | None, float]:
        """A follower's state this step (its train moved, its next stop chosen) and its question's inputs."""
        rng = self.rng
        ids = sorted(self.trains)
        tr = self.trains[ids[int(rng.integers(len(ids)))]]
        tr.next_stop = int(rng.integers(len(STATIONS) + 1))
        stop = tr.trip.stops[tr.next_stop] if tr.next_stop < len(STATIONS) else None
        end_m = self.ends_m[STATIONS[min(tr.next_stop, len(STATIONS) - 1)]]
        limit_m = end_m - PLATFORM_M - EngineSettings().protection_margin_m
        near = rng.random()  # just at the limit (the 1e-6 tolerance), within a few metres, or anywhere near
        if near < 0.15:
            tr.front_m = limit_m + float(rng.choice([-2e-6, -1e-6, 0.0, 5e-7, 1e-6, 2e-6]))
        elif near < 0.4:
            tr.front_m = limit_m - float(rng.uniform(0.0, 2 * BERTH_WAIT_M))
        else:
            tr.front_m = limit_m + float(rng.uniform(-600.0, 300.0))
        tr.plant.speed_mps = 0.0 if rng.random() < 0.4 else float(rng.uniform(0.0, 22.0))
        ahead = None
        if rng.random() < 0.85:
            other = self.trains[ids[int(rng.integers(len(ids)))]]
            if other is not tr:
                other.next_stop = int(rng.integers(len(STATIONS) + 1))
                other.plant.speed_mps = 0.0 if rng.random() < 0.5 else float(rng.uniform(0.0, 5.0))
                front_m = end_m + float(rng.uniform(-PLATFORM_M - 150.0, 250.0))
                if rng.random() < 0.1:  # its rear exactly at the window's end, its front at the platform's start
                    front_m = float(rng.choice([end_m + VEH.length_m, end_m - PLATFORM_M]))
                rear_m = front_m - VEH.length_m
                ahead = Ahead(other.train_id, front_m, rear_m, rear_m - tr.front_m, 0.0)
                if rng.random() < 0.1:
                    self.coupled ^= {(tr.train_id, other.train_id)}
        authority_m = float(rng.choice([1e9, end_m - 400.0, end_m - PLATFORM_M - 10.0, end_m + 50.0]))
        return tr, stop, ahead, authority_m


def _books(b: Berths) -> tuple[Any, ...]:
    return dict(b.waiting), dict(b._imposed), set(b._logged), b.events.rows()


@pytest.mark.parametrize("seed", range(SEEDS))
def test_the_cheap_path_decides_as_the_rule_did(seed: int) -> None:
    assert _first_difference(seed) is None


def _first_difference(seed: int, steps: int = STEPS) -> str | None:
    """Run both rules side by side over one random world; the first step where they differ, or None."""
    world = World(seed)
    berths_on = EngineSettings()
    berths_off = dataclasses.replace(berths_on, platform_berths=False)
    new = Berths(world.trains, EventLog(), berths_on, world.coupled_behind, DT_S)  # type: ignore[arg-type]
    ref = ReferenceBerths(world.trains, EventLog(), berths_on, world.coupled_behind, DT_S)  # type: ignore[arg-type]
    for k in range(steps):
        off = k % 500 >= 450  # the rule switched off for a stretch: limits given before are no longer held
        new.settings = ref.settings = berths_off if off else berths_on
        tr, stop, ahead, authority_m = world.draw()
        t = k * DT_S
        got = new.authority_end_m(t, tr, stop, ahead, authority_m)
        want = ref.authority_end_m(t, tr, stop, ahead, authority_m)
        if got != want or _books(new) != _books(ref):
            return f"step {k}: {got} != {want} or books {_books(new)} != {_books(ref)}"
    return None


def test_the_worlds_reach_every_branch() -> None:
    """The random worlds impose limits, let trains in inside the braking distance, make them wait and log it."""
    world = World(0)
    ref = ReferenceBerths(world.trains, EventLog(), EngineSettings(), world.coupled_behind, DT_S)  # type: ignore[arg-type]
    cut = waited = 0
    for k in range(STEPS):
        tr, stop, ahead, authority_m = world.draw()
        if ref.authority_end_m(k * DT_S, tr, stop, ahead, authority_m) < authority_m:
            cut += 1
        waited += tr.train_id in ref.waiting
    assert cut > 50 and waited > 5 and len(ref.events.rows("platform_occupied")) > 3


def _moving_counts_as_standing(
    front_m: float, train_id: str, stop: Any, ahead: Any, trains: Any, overlap_m: float, coupled_behind: Any
) -> float | None:
    if ahead is None or stop is None or stop.kind != "station":
        return None
    platform_start_m = stop.window_end_m - stop.platform_m
    limit_m = platform_start_m - overlap_m
    if front_m > limit_m + 1e-6 or ahead.rear_m >= stop.window_end_m or ahead.front_m <= platform_start_m:
        return None
    return None if coupled_behind(train_id, ahead.train_id) else limit_m


def _coupled_not_exempt(
    front_m: float, train_id: str, stop: Any, ahead: Any, trains: Any, overlap_m: float, coupled_behind: Any
) -> float | None:
    return ORIGINAL(front_m, train_id, stop, ahead, trains, overlap_m, lambda _a, _b: False)


def _no_tolerance(
    front_m: float, train_id: str, stop: Any, ahead: Any, trains: Any, overlap_m: float, coupled_behind: Any
) -> float | None:
    if stop is not None and front_m > stop.window_end_m - stop.platform_m - overlap_m:
        return None
    return ORIGINAL(front_m, train_id, stop, ahead, trains, overlap_m, coupled_behind)


ORIGINAL = platforms.berth_limit_m


@pytest.mark.parametrize("broken", [_moving_counts_as_standing, _coupled_not_exempt, _no_tolerance])
def test_a_broken_fast_path_is_caught(monkeypatch: pytest.MonkeyPatch, broken: Callable[..., Any]) -> None:
    monkeypatch.setattr(platforms, "berth_limit_m", broken)
    assert any(_first_difference(seed) is not None for seed in range(SEEDS))
