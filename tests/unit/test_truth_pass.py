"""The truth pass (railsim/engine/truth.py, truth_kernel.py): SUMO's reading to chainage, pointer and checks.

Each rule of the pass on a case built by hand — a train in step, one that jumped ahead or back, a reversing unit,
a train missing from a check, an internal junction lane, an edge off the route, a route passing an edge twice, a
speed SUMO imposed — through :class:`TruthPass` with the real occupancy index and safety monitor (the events are
read back), and the compiled kernel held bit for bit to its interpreted form on random states.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from railsim.engine import slots, truth_kernel
from railsim.engine.events.clock import EventLayer
from railsim.engine.occupancy import Occupancy
from railsim.engine.routeview import RouteView
from railsim.engine.safety import SafetyMonitor
from railsim.engine.settings import EngineSettings
from railsim.engine.train import TrainRuntime
from railsim.engine.truth import TruthPass
from tests.helpers import interpreted, route_view, runtime_train

DT_S = 0.5
TOL_M = EngineSettings().desync_tolerance_m


class _Train(TrainRuntime):
    """A train whose adoption of SUMO's speed is recorded (its resident fields write the slot store as any)."""

    adopted: tuple[float, float] | None = None

    def adopt_sumo_speed(self, t: float, speed_mps: float) -> None:
        self.adopted = (t, speed_mps)


def _train(train_id: str, view: RouteView, depart_m: float = 0.0, length_m: float = 50.0) -> _Train:
    return runtime_train(_Train, train_id, view, length_m, depart_chainage_m=depart_m)


class _Reading(SimpleNamespace):
    """A stand-in for the bridge's ``TrainStates`` (the fields the pass reads)."""


def _reading(odo: list[float], speed: list[float], lane_pos: list[float], edges: list[str]) -> _Reading:
    n = len(odo)
    return _Reading(
        odometer_m=np.array(odo, float),
        speed_mps=np.array(speed, float),
        lane_pos_m=np.array(lane_pos, float),
        edge_ids=list(edges),
        stopped=np.zeros(n, bool),
    )


class _World:
    def __init__(self) -> None:
        self.layer = EventLayer(t0_s=0.0, rng=np.random.default_rng(1))
        self.safety = SafetyMonitor({}, self.layer, self.layer.log, EngineSettings())
        self.speed_calls: list[tuple[str, float, float]] = []  # what the monitor is asked to judge

        def spy(t: float, tr: Any, sumo_v: float, railsim_v: float, dt_s: float) -> None:
            self.speed_calls.append((tr.train_id, sumo_v, railsim_v))

        self.safety.speed_imposed = spy  # type: ignore[method-assign]
        self.occupancy = Occupancy()
        self.truth = TruthPass(self.occupancy, self.safety, TOL_M, DT_S)

    def desyncs(self) -> list[dict[str, Any]]:
        return [{"t_s": e.t_s, "train": e.subject, **e.detail} for e in self.layer.log.entries("desync")]


LINE = route_view("line", ("a", "b", "c"), (100.0, 150.0, 200.0))  # a: 0-100, b: 100-250, c: 250-450


def test_a_train_in_step_gets_its_chainage_and_pointer_and_no_event() -> None:
    w = _World()
    tr = _train("T1", LINE, depart_m=20.0)
    w.truth.read(0.0, [tr], _reading([78.0], [10.0], [98.0], ["a"]))
    w.truth.read(0.5, [tr], _reading([83.0], [10.0], [3.0], ["b"]))  # 5 m at 10 m/s in 0.5 s, onto edge b
    assert tr.front_m == 103.0 and tr.edge_i == 1 and tr.sumo_edge == "b"
    assert w.occupancy.ids == ["T1"] and w.occupancy.edge_i.tolist() == [1]
    assert w.desyncs() == [] and w.safety.failure is None


def test_advance_beyond_speed_or_backwards_is_a_desync_with_the_expected_chainage() -> None:
    w = _World()
    tr = _train("T1", LINE)
    w.truth.read(0.0, [tr], _reading([100.0], [10.0], [0.0], ["b"]))
    w.truth.read(0.5, [tr], _reading([105.0], [10.0], [5.0], ["b"]))  # 5 m at 10 m/s in 0.5 s: fine
    assert w.desyncs() == [] and w.safety.failure is None
    w.truth.read(1.0, [tr], _reading([140.0], [10.0], [40.0], ["b"]))  # 35 m: at most 5 (+ tolerance)
    w.truth.read(1.5, [tr], _reading([130.0], [10.0], [30.0], ["b"]))  # 10 m back
    rows = w.desyncs()
    assert [(r["t_s"], r["railsim_m"], r["sumo_m"]) for r in rows] == [
        (1.0, 110.0, 140.0),
        (1.5, 140.0, 130.0),
    ]  # expected: not back at all; SUMO: where it is
    assert w.safety.failure is not None and "T1" in w.safety.failure


def test_a_reversing_unit_and_a_train_missing_from_a_check_are_not_held_to_their_advance() -> None:
    w = _World()
    rev, gone = _train("R", LINE), _train("G", LINE)
    w.truth.read(0.0, [rev, gone], _reading([100.0, 300.0], [0.0, 0.0], [0.0, 50.0], ["b", "c"]))
    rev.reversing = True
    w.truth.read(0.5, [rev], _reading([160.0], [0.0], [60.0], ["b"]))  # G not read in this check
    w.truth.read(1.0, [rev, gone], _reading([160.0, 350.0], [0.0, 0.0], [60.0, 100.0], ["b", "c"]))
    assert w.desyncs() == []
    assert gone.front_m == 350.0 and gone.edge_i == 2


def test_internal_lane_is_not_checked_and_an_edge_off_the_route_is_a_desync() -> None:
    w = _World()
    tr = _train("T1", LINE)
    w.truth.read(0.0, [tr], _reading([99.0], [0.0], [9999.0], [":j0_0"]))
    assert w.desyncs() == []
    w.truth.read(0.5, [tr], _reading([99.0], [0.0], [99.0], ["x"]))
    (row,) = w.desyncs()
    assert row["sumo_m"] is None and row["edge"] == "x" and row["railsim_m"] == 99.0


def test_on_a_route_passing_an_edge_twice_the_pass_next_to_the_pointer_counts() -> None:
    loop = route_view("loop", ("a", "b", "c", "b", "d"), (100.0, 150.0, 200.0, 150.0, 100.0))  # b at 100 and at 450
    w = _World()
    first, second = _train("F", loop), _train("S", loop)
    w.truth.read(0.0, [first, second], _reading([95.0, 445.0], [10.0, 10.0], [95.0, 195.0], ["a", "c"]))
    w.truth.read(0.5, [first, second], _reading([100.0, 450.0], [10.0, 10.0], [0.0, 0.0], ["b", "b"]))
    w.truth.read(1.0, [first, second], _reading([105.0, 455.0], [10.0, 10.0], [5.0, 5.0], ["b", "b"]))
    assert (first.edge_i, second.edge_i) == (1, 3) and w.desyncs() == []  # each on its own pass of b
    w.truth.read(1.5, [first, second], _reading([110.0, 460.0], [10.0, 10.0], [10.0, 60.0], ["b", "b"]))
    (row,) = w.desyncs()  # the second's lane position puts it 50 m on: its pass of b says 510 m
    assert (row["train"], row["railsim_m"], row["sumo_m"]) == ("S", 460.0, 510.0)


def test_a_speed_sumo_imposed_is_checked_and_adopted_and_an_unsent_one_is_not() -> None:
    w = _World()
    a, b = _train("A", LINE), _train("B", LINE)
    a.sent_speed_mps = 10.0
    w.truth.read(0.0, [a, b], _reading([120.0, 300.0], [9.5, 3.0], [20.0, 50.0], ["b", "c"]))
    assert w.speed_calls == [("A", 9.5, 10.0)] and a.adopted == (0.0, 9.5) and b.adopted is None
    w.truth.slots.sent([9.5, 3.0])  # the speeds handed to SUMO for the step
    w.truth.read(0.5, [a, b], _reading([124.75, 300.0], [9.5 + 1e-7, 3.0], [24.75, 50.0], ["b", "c"]))
    assert len(w.speed_calls) == 1  # within 1e-6 m/s of what was sent


@pytest.mark.parametrize("seed", range(6))
def test_the_compiled_pass_gives_its_interpreted_forms_bits(seed: int) -> None:
    rng = np.random.default_rng(seed)
    ref = interpreted(truth_kernel)
    occ = Occupancy()
    views = []
    for r in range(6):
        n_e = int(rng.integers(2, 9))
        edges = tuple(f"e{x}" for x in rng.integers(0, 12, n_e))
        views.append(route_view(f"r{r}", edges, tuple(float(x) for x in rng.uniform(20.0, 300.0, n_e))))
    n_slots = 40
    table_c = np.zeros((n_slots, slots.N_COLUMNS))
    table_c[:, slots.LENGTH_M] = 50.0
    for check_no in range(1, 5):
        n = int(rng.integers(1, 30))
        rows = rng.permutation(n_slots)[:n]
        table_c[rows, slots.ROUTE] = occ.route_numbers([views[int(x)] for x in rng.integers(0, len(views), n)])
        table_c[rows, slots.DEPART_M] = rng.uniform(-50, 500, n)
        table_c[rows, slots.HINT] = rng.integers(-2, 10, n)
        table_c[rows, slots.REVERSING] = rng.random(n) < 0.2
        table_c[rows, slots.SENT_MPS] = np.where(rng.random(n) < 0.3, np.nan, rng.uniform(0, 25, n))
        if check_no == 1:  # memory of a last check (some of it this check's last)
            table_c[:, slots.PREV_FRONT_M] = rng.uniform(0, 1000, n_slots)
            table_c[:, slots.PREV_SPEED_MPS] = rng.uniform(0, 20, n_slots)
            table_c[:, slots.SEEN] = rng.integers(-2, 2, n_slots)
        table_i = table_c.copy()
        speed = np.where(rng.random(n) < 0.5, table_c[rows, slots.SENT_MPS], rng.uniform(0, 25, n))
        args = (
            rows.astype(np.int64),
            rng.uniform(0, 800, n),
            occ.edge_codes([str(e) for e in rng.choice(["e1", "e3", "e7", ":j_0", "zz", "e11"], n)]),
            rng.uniform(0, 300, n),
            np.nan_to_num(speed),
        )
        outs_c = [np.empty(n), np.empty(n, np.int64), np.empty(n, np.int8), np.empty(n), np.empty(n)]
        outs_i = [np.empty(n), np.empty(n, np.int64), np.empty(n, np.int8), np.empty(n), np.empty(n)]
        tables = occ.route_tables()
        got_c = truth_kernel.truth_pass(*tables, table_c, *args, check_no, DT_S, TOL_M, *outs_c)
        got_i = ref.truth_pass(*tables, table_i, *args, check_no, DT_S, TOL_M, *outs_i)
        assert got_c == got_i
        for c, i in zip([*outs_c, table_c], [*outs_i, table_i], strict=True):
            assert c.tobytes() == i.tobytes()
