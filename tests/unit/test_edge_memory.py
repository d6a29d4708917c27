"""The SUMO bridge reads a train's edge only where its odometer and lane position cannot vouch for the last one.

:func:`railsim.engine.sumo.edge_kept` is the rule, :class:`railsim.engine.sumo.EdgeMemory` applies it. Here both
against a stand-in for SUMO that moves trains as SUMO does (one step's advance added to the lane position and the
odometer; past a lane's end onto the next lane, the position less the left lane's length) and does what SUMO does
to our trains besides: flips a reversing unit onto its bidi edge at standstill, ``moveTo``, a vehicle removed and
added again under its id, trains coming and going. Every step the memory's edges must be the true ones.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, field

import numpy as np

from railsim.engine.sumo import LANE_END_MARGIN_M, EdgeMemory, edge_kept

LANES = {  # lane id -> (edge id, length): plain edges, a junction's short internal lanes, bidi partners
    "a_0": ("a", 400.0),
    ":j_0_0": (":j_0", 0.1),
    ":j_1_0": (":j_1", 2.5),
    "b_0": ("b", 120.0),
    ":k_0_0": (":k_0", 0.1),
    "c_0": ("c", 900.0),
    "-c_0": ("-c", 900.0),
    "d_0": ("d", 35.0),
}
ROUTE = ["a_0", ":j_0_0", ":j_1_0", "b_0", ":k_0_0", "c_0", "d_0", "a_0"]


@dataclass
class FakeTrain:
    lane_i: int
    pos_m: float
    odometer_m: float = 0.0
    lane_id: str = field(init=False)

    def __post_init__(self) -> None:
        self.lane_id = ROUTE[self.lane_i]


class FakeSumo:
    """Trains on ``ROUTE`` moved the way SUMO moves them; the vehicle getters the bridge calls, counted."""

    def __init__(self) -> None:
        self.trains: dict[str, FakeTrain] = {}
        self.asked = 0

    def getRoadID(self, vid: str) -> str:  # noqa: N802 - libsumo's name
        self.asked += 1
        return LANES[self.trains[vid].lane_id][0]

    def getLaneID(self, vid: str) -> str:  # noqa: N802 - libsumo's name
        return self.trains[vid].lane_id

    def advance(self, tr: FakeTrain, d_m: float) -> None:
        tr.pos_m += d_m
        tr.odometer_m += d_m
        while tr.pos_m > LANES[tr.lane_id][1] and tr.lane_i + 1 < len(ROUTE):
            tr.pos_m -= LANES[tr.lane_id][1]
            tr.lane_i += 1
            tr.lane_id = ROUTE[tr.lane_i]


def _lane_length(lane_id: str) -> float:
    return LANES[lane_id][1]


def test_the_rule_keeps_only_a_train_that_moved_along_its_lane_short_of_its_end() -> None:
    odo0, pos0, length = np.array([100.0] * 6), np.array([50.0] * 6), np.array([400.0] * 6)
    odo = np.array([110.0, 100.0, 110.0, 110.0, 100.0 + 350.0 - LANE_END_MARGIN_M / 2, 110.0])
    pos = np.array([60.0, 50.0, 3.0, 75.0, 400.0 - LANE_END_MARGIN_M / 2, 60.0 + 1e-9])
    kept = edge_kept(odo0, pos0, length, odo, pos).tolist()
    # moved on its lane | standing | on the next lane | jumped (moveTo) | at its lane's end | rounding
    assert kept == [True, False, False, False, False, True]
    assert not edge_kept(np.array([np.nan]), pos0[:1], length[:1], odo[:1], pos[:1])[0]  # unknown: read it


def test_a_train_that_crossed_a_short_internal_lane_is_read_again() -> None:
    # 0.1 m junction lane: 0.05 m in, 0.2 m advance -> 0.15 m onto the next lane; never "kept"
    assert not edge_kept(np.array([0.0]), np.array([0.05]), np.array([0.1]), np.array([0.2]), np.array([0.15]))[0]


def test_the_memory_gives_every_trains_true_edge_every_step_and_asks_for_few() -> None:
    rng = random.Random(3)
    sumo = FakeSumo()
    memory = EdgeMemory(_lane_length)
    next_id, train_steps = 0, 0
    for step in range(3000):
        if len(sumo.trains) < 8 and rng.random() < 0.05:  # a train comes
            vid = f"t{next_id % 10}"  # ids come back: a new vehicle under an old id
            next_id += 1
            if vid not in sumo.trains:
                memory.forget(vid)
                sumo.trains[vid] = FakeTrain(rng.randrange(len(ROUTE) - 1), rng.uniform(0.0, 30.0))
        for vid, tr in list(sumo.trains.items()):
            r = rng.random()
            if r < 0.01:  # leaves
                memory.forget(vid)
                del sumo.trains[vid]
            elif r < 0.02 and tr.lane_id == "c_0":  # reverses at standstill onto the bidi partner
                tr.lane_id, tr.pos_m = "-c_0", 900.0 - tr.pos_m + 90.0
            elif r < 0.03:  # moveTo on its lane or onto the next one; SUMO shifts the odometer with it
                shift_m = rng.uniform(0.0, 60.0)
                sumo.advance(tr, shift_m)
            elif r < 0.25:
                pass  # standing
            else:
                sumo.advance(tr, rng.choice([0.05, 0.1, 0.3, 2.0, 7.5, 11.11]))
        ids = list(sumo.trains)
        if step % 7 == 0:
            rng.shuffle(ids)  # the order may change between steps
        odo = np.array([sumo.trains[v].odometer_m for v in ids])
        pos = np.array([sumo.trains[v].pos_m for v in ids])
        truth = [LANES[sumo.trains[v].lane_id][0] for v in ids]
        assert memory.edges_now(ids, odo, pos, sumo) == truth, step
        train_steps += len(ids)
    assert train_steps > 10_000
    assert sumo.asked < 0.5 * train_steps  # most steps vouch for most edges


def test_forget_makes_the_next_reading_ask() -> None:
    sumo = FakeSumo()
    sumo.trains["x"] = FakeTrain(0, 10.0)
    memory = EdgeMemory(_lane_length)
    for _ in range(3):
        sumo.advance(sumo.trains["x"], 1.0)
        memory.edges_now(["x"], np.array([sumo.trains["x"].odometer_m]), np.array([sumo.trains["x"].pos_m]), sumo)
    assert sumo.asked == 1  # the first reading only
    memory.forget("x")
    sumo.advance(sumo.trains["x"], 1.0)
    memory.edges_now(["x"], np.array([sumo.trains["x"].odometer_m]), np.array([sumo.trains["x"].pos_m]), sumo)
    assert sumo.asked == 2
