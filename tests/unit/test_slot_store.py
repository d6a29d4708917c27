"""The slot store (railsim/engine/slots.py) holds what reading every field from the trains would give.

The truth pass reads its inputs from the store, not from the trains; so after any sequence of the events that change
one — a train read for the first time, trains joining and leaving the step, a view handed to a train, a reversal set
up or done, a depart chainage set (insertion, a unit's next trip), the speeds handed to SUMO, the pass's own pointer
— the store's row of every train of a step must equal the row gathered from the train itself
(:meth:`SlotStore.gathered`, the former per-step gather) when the pass reads it, and the fields written on the train
must be in its row at once. Random sequences of those events on real ``TrainRuntime`` objects, with the real truth
pass and occupancy index, checked after every event.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from railsim.engine import slots
from railsim.engine.events.clock import EventLayer
from railsim.engine.occupancy import Occupancy
from railsim.engine.safety import SafetyMonitor
from railsim.engine.settings import EngineSettings
from railsim.engine.slots import SlotStore
from railsim.engine.train import TrainRuntime
from railsim.engine.truth import TruthPass
from tests.helpers import route_view, runtime_train

INPUTS = slice(slots.ROUTE, slots.LENGTH_M + 1)  # the columns gathered() gives


class _Run:
    """Trains, the store, the pass; every event of the module docstring as a method."""

    def __init__(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)
        rng = self.rng
        self.views = []
        for r in range(8):
            n_e = int(rng.integers(2, 7))
            edges = tuple(f"e{x}" for x in rng.integers(0, 15, n_e))
            self.views.append(route_view(f"r{r}", edges, tuple(float(x) for x in rng.uniform(50.0, 400.0, n_e))))
        self.trains = [
            runtime_train(TrainRuntime, f"T{k}", self.views[int(rng.integers(0, 4))], float(rng.uniform(20, 200)))
            for k in range(25)
        ]
        self.occupancy = Occupancy()
        layer = EventLayer(t0_s=0.0, rng=np.random.default_rng(1))
        safety = SafetyMonitor({}, layer, layer.log, EngineSettings())
        safety.speed_imposed = lambda *a: None  # type: ignore[method-assign]
        safety.desync_found = lambda *a: None  # type: ignore[method-assign]  (random readings: out of step)
        self.store = SlotStore(self.occupancy, capacity=4)  # small: it grows while the trains come
        self.truth = TruthPass(self.occupancy, safety, EngineSettings().desync_tolerance_m, 0.5, self.store)
        self.active: list[TrainRuntime] = []
        self.t = 0.0

    def step(self) -> None:
        """A step: the same trains, or some join or leave, in a new order; the pass reads them (pointers written)."""
        rng = self.rng
        if rng.random() < 0.5:  # the same trains (most steps)
            self.active = list(self.active)
        else:
            keep = [tr for tr in self.active if rng.random() < (0.85 if rng.random() < 0.9 else 0.0)]
            new = [tr for tr in self.trains if tr not in keep and rng.random() < 0.15]
            self.active = [*keep, *new]
            if rng.random() < 0.3:
                rng.shuffle(self.active)  # type: ignore[arg-type]
        if not self.active:
            self.store.index([])
            assert (len(self.store.slots), len(self.store.routes), len(self.store.lengths_m)) == (0, 0, 0)
            return
        n = len(self.active)
        reading = SimpleNamespace(
            odometer_m=rng.uniform(0.0, 600.0, n),
            speed_mps=rng.uniform(0.0, 20.0, n),
            lane_pos_m=rng.uniform(0.0, 100.0, n),
            edge_ids=[str(e) for e in rng.choice(["e1", "e3", ":j_0", "zz", "e7"], n)],
            stopped=rng.random(n) < 0.1,
        )
        self.t += 0.5
        self.store.index(self.active)  # what the pass reads first thing: the rows must be the gathered ones now
        self.check_rows(self.active, INPUTS)
        self.truth.read(self.t, self.active, reading)  # type: ignore[arg-type]
        self.check_rows(self.active, INPUTS)  # the pointer written back and in the row alike
        assert self.store.routes.tolist() == self.store.gathered(self.active)[:, slots.ROUTE].tolist()
        assert self.store.lengths_m.tolist() == [tr.trip.vehicle.length_m for tr in self.active]

    def send(self) -> None:
        """Control sets each train's speed and the engine hands the list to SUMO."""
        if not self.active:
            return
        speeds = self.rng.uniform(0.0, 20.0, len(self.active)).tolist()
        for tr, v in zip(self.active, speeds, strict=True):
            tr.sent_speed_mps = v
        self.store.sent(speeds)

    def reverse(self) -> None:
        tr = self.trains[int(self.rng.integers(0, len(self.trains)))]
        tr.reversing = not tr.reversing

    def depart(self) -> None:
        tr = self.trains[int(self.rng.integers(0, len(self.trains)))]
        tr.depart_chainage_m = float(self.rng.uniform(-100.0, 500.0))

    def hand_view(self) -> None:
        tr = self.trains[int(self.rng.integers(0, len(self.trains)))]
        tr.view = self.views[int(self.rng.integers(0, len(self.views)))]  # some never registered before

    def check_rows(self, trains: list[TrainRuntime], columns: slice) -> None:
        slotted = [tr for tr in trains if tr.slot >= 0]
        if not slotted:
            return
        rows = self.store.table[[tr.slot for tr in slotted]]
        want = self.store.gathered(slotted)[:, columns.start - slots.ROUTE : columns.stop - slots.ROUTE]
        assert rows[:, columns].tobytes() == want.tobytes()


@pytest.mark.parametrize("seed", range(8))
def test_the_store_holds_what_the_trains_hold_after_any_sequence_of_events(seed: int) -> None:
    run = _Run(seed)
    events = [run.step, run.send, run.reverse, run.depart, run.hand_view]
    at_once = slice(slots.DEPART_M, slots.LENGTH_M + 1)  # every column but the route, numbered when the pass reads
    for _ in range(400):
        events[int(run.rng.choice(len(events), p=[0.4, 0.3, 0.1, 0.1, 0.1]))]()
        run.check_rows(run.trains, at_once)
    assert run.store.n_slots == len({tr.slot for tr in run.trains if tr.slot >= 0}) > 4  # it grew


def test_a_train_s_fields_reach_its_row_at_once_and_only_its_row() -> None:
    run = _Run(0)
    a, b = run.trains[:2]
    run.active = [a, b]
    run.store.index(run.active)
    a.reversing, a.depart_chainage_m = True, 123.5
    row_a, row_b = run.store.table[a.slot], run.store.table[b.slot]
    assert (row_a[slots.REVERSING], row_a[slots.DEPART_M]) == (1.0, 123.5)
    assert (row_b[slots.REVERSING], row_b[slots.DEPART_M]) == (0.0, 0.0)
    run.store.sent([4.0, 5.0])
    assert (row_a[slots.SENT_MPS], row_b[slots.SENT_MPS]) == (4.0, 5.0)
    c = run.trains[2]
    run.store.index([a, b, c])  # a train read for the first time: nothing sent to it yet
    assert np.isnan(run.store.table[c.slot, slots.SENT_MPS]) and row_a[slots.SENT_MPS] == 4.0
