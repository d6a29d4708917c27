"""Platform berths never cut an authority inside the braking distance (railsim/engine/platforms.py).

The depot day's one emergency brake, constructed without SUMO: a unit that does not stop at Bijin halts with its
body on Bijin's platform (it waits for the points beyond), and the Airport train behind, which stops at Bijin,
is ~155 m from the berth limit at 19.14 m/s. Cutting its authority there asked for more than its service brake
(one step of emergency braking). The rule: a berth limit that appears inside the follower's service braking
distance is not imposed on it (let in; separation keeps it behind the occupant's rear); one that appears in time
is imposed and holds while the occupant stands, also once the follower, braking for it, is inside that distance.

The threshold is checked against the ATO law itself (``Ato.decide``): given an authority at the service braking
distance the law brakes in service; at half of it the law needs its emergency brake (the case the rule avoids).
"""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from controllers.ato import Ato, AtoParams
from railsim.engine.events.log import EventLog
from railsim.engine.occupancy import Ahead
from railsim.engine.platforms import Berths, service_braking_m
from railsim.engine.settings import EngineSettings
from railsim.engine.trips import TripStop
from railsim.physics.vehicle import preset

DT_S = 0.5
VEH = preset("cq3_6car")
PLATFORM_END_M = 54_000.0
PLATFORM_M = 220.0
OVERLAP_M = EngineSettings().protection_margin_m
LIMIT_M = PLATFORM_END_M - PLATFORM_M - OVERLAP_M  # the berth limit in the follower's frame


def _stop(station: str) -> TripStop:
    mark = PLATFORM_END_M - 1.0
    return TripStop(
        station,
        f"{station}.up",
        mark,
        PLATFORM_END_M - 130.0,
        PLATFORM_END_M,
        30.0,
        False,
        False,
        "station",
        None,
        PLATFORM_M,
    )


def _train(tid: str, front_m: float, speed_mps: float, stops: list[TripStop]) -> SimpleNamespace:
    trip = SimpleNamespace(vehicle=VEH, stops=stops)
    return SimpleNamespace(
        train_id=tid, front_m=front_m, plant=SimpleNamespace(speed_mps=speed_mps), trip=trip, next_stop=0
    )


def _setup(follower_front_m: float, follower_v: float) -> tuple[Berths, SimpleNamespace, SimpleNamespace, EventLog]:
    bijin = _stop("bijin")
    follower = _train("airport_up.116", follower_front_m, follower_v, [bijin])
    # the unit ahead runs to the airport without a stop at Bijin: it occupies the platform only while it stands
    unit = _train("unit112.depot_out", PLATFORM_END_M + 40.0, 3.0, [_stop("jiangbei-airport-t2")])
    events = EventLog()
    trains = {follower.train_id: follower, unit.train_id: unit}
    berths = Berths(trains, events, EngineSettings(), lambda _a, _b: False, DT_S)  # type: ignore[arg-type]
    return berths, follower, unit, events


def _authority(berths: Berths, follower: SimpleNamespace, unit: SimpleNamespace, t: float) -> float:
    rear_m = unit.front_m - VEH.length_m
    ahead = Ahead(unit.train_id, unit.front_m, rear_m, rear_m - follower.front_m, 0.0)
    return berths.authority_end_m(t, follower, follower.trip.stops[0], ahead, 1e9)  # type: ignore[arg-type]


def test_a_berth_appearing_inside_the_braking_distance_is_not_imposed() -> None:
    v = 19.14
    berths, follower, unit, events = _setup(LIMIT_M - 155.0, v)
    assert service_braking_m(follower, DT_S) > 155.0 + 1.0  # type: ignore[arg-type]
    assert _authority(berths, follower, unit, 0.0) == 1e9  # the unit moves: the platform is not held
    unit.plant.speed_mps = 0.0  # it halts on the platform: too late for the follower, which is let in
    for k in range(1, 6):
        follower.front_m += v * DT_S
        assert _authority(berths, follower, unit, k * DT_S) == 1e9
    assert not events.rows()


def test_a_berth_in_time_is_imposed_and_holds_while_the_follower_brakes_for_it() -> None:
    berths, follower, unit, _ = _setup(LIMIT_M - 400.0, 19.14)
    unit.plant.speed_mps = 0.0
    assert _authority(berths, follower, unit, 0.0) == pytest.approx(LIMIT_M)
    follower.front_m, follower.plant.speed_mps = LIMIT_M - 25.0, 8.0  # braking for it: 25 m < 36.8 m to stand
    assert _authority(berths, follower, unit, 20.0) == pytest.approx(LIMIT_M)
    unit.plant.speed_mps = 1.0  # the occupant moves off: lifted ...
    assert _authority(berths, follower, unit, 21.0) == 1e9
    unit.plant.speed_mps = 0.0  # ... and it halts again with the follower inside its braking distance: let in
    assert _authority(berths, follower, unit, 22.0) == 1e9


@pytest.mark.parametrize("v", [5.0, 10.0, 15.0, 19.14, 22.0])
def test_the_threshold_is_where_the_ato_law_still_brakes_in_service(v: float) -> None:
    ato = Ato(AtoParams(), VEH)
    tr = SimpleNamespace(plant=SimpleNamespace(speed_mps=v), trip=SimpleNamespace(vehicle=VEH))
    d = service_braking_m(tr, DT_S)  # type: ignore[arg-type]

    def emergency(dist_m: float) -> bool:
        return ato.decide(VEH, DT_S, 0.0, v, 0.0, VEH.length_m, 0.0, 30.0, (), None, dist_m)[1]

    assert not emergency(d)
    assert emergency(0.5 * d)
