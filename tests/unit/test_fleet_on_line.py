"""The fleet's list of trains on the line (railsim/engine/fleet.py) answers as a scan of every trip would.

The loop asks every step which trains are on the line and how many trips have finished; the fleet answers from
the trains that came on the line (:meth:`Fleet.start`), so a day of thousands of trips costs only the trains on it.
Over random lives — trips started in any order (inserted, or a unit's next trip coming on running), running,
arriving or leaving the line, trips added after set-up — both answers must be the scan's at every point, in
scenario order.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from railsim.engine.fleet import FINISHED, ON_LINE, Fleet
from railsim.engine.train import TrainRuntime


def _add(fleet: Fleet, k: int) -> TrainRuntime:
    tr = TrainRuntime(trip=SimpleNamespace(trip_id=f"t{k}"), view=None, controllers={})  # type: ignore[arg-type]
    fleet.trains[tr.train_id] = tr
    return tr


def _scan(fleet: Fleet) -> tuple[list[str], int]:
    on_line = [tr.train_id for tr in fleet.trains.values() if tr.status in ON_LINE]
    return on_line, sum(1 for tr in fleet.trains.values() if tr.status in FINISHED)


@pytest.mark.parametrize("seed", range(5))
def test_trains_on_the_line_and_finished_trips_are_the_scans(seed: int) -> None:
    rng = np.random.default_rng(seed)
    fleet = Fleet("<test>")
    trains = [_add(fleet, k) for k in range(40)]
    for step in range(300):
        if step == 150:  # trips added after set-up
            trains += [_add(fleet, k) for k in range(40, 50)]
        tr = trains[int(rng.integers(len(trains)))]
        if tr.status == "scheduled":
            fleet.start(tr, "inserting" if rng.random() < 0.7 else "running")
        elif tr.status == "inserting":
            tr.status = "running"
        elif tr.status == "running":
            tr.status = "arrived" if rng.random() < 0.8 else "removed"
        if rng.random() < 0.5:
            assert [t.train_id for t in fleet.active()] == _scan(fleet)[0]
        assert fleet.n_finished() == _scan(fleet)[1]
    assert [t.train_id for t in fleet.active()] == _scan(fleet)[0]


def test_a_train_starts_only_onto_the_line() -> None:
    fleet = Fleet("<test>")
    tr = _add(fleet, 0)
    with pytest.raises(ValueError, match="not 'arrived'"):
        fleet.start(tr, "arrived")
    fleet.start(tr, "inserting")
    fleet.start(tr, "running")  # already on the line: listed once
    assert [t.train_id for t in fleet.active()] == ["t0"]
