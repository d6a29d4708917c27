"""The SUMO bridge asks for a train's edge only where its odometer and lane position cannot vouch for the last one
(:class:`railsim.engine.sumo.EdgeMemory`); here against SUMO itself.

Each run below reads, besides the bridge, every train's edge from SUMO at every step and fails on the first
difference: the mini line (a Y line with a junction, station stops, coupling and decoupling, trains coming and
going) and a unit that SUMO reverses on a bidi turnback track beyond the platform and that runs its next trip
(the flip onto the partner edge happens at standstill). The bridge uses the memory here for any number of trains
(by default only from ``EDGE_MEMORY_MIN_TRAINS``) and must have asked for far fewer edges than there were
train-steps. The outputs themselves are pinned by the golden test.
"""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from tests.helpers import DATA, run_python
from tests.sumo.test_turnback import _COMMON, _service, build_tail_track

CHILD = r"""
import json, sys, tempfile
from pathlib import Path
from railsim.engine import sumo
from railsim.engine.loop import Simulation
from railsim.scenario.loading import load

counts = {"train_steps": 0, "asked": 0, "mismatches": []}
edges_now = sumo.EdgeMemory.edges_now


class Counting:
    def __init__(self, calls):
        self.calls = calls

    def __getattr__(self, name):
        return getattr(self.calls, name)

    def getRoadID(self, vid):
        counts["asked"] += 1
        return self.calls.getRoadID(vid)


def counted(self, ids, odometer_m, lane_pos_m, calls):
    return edges_now(self, ids, odometer_m, lane_pos_m, Counting(calls))


read = sumo.SumoBridge.read


def checked(self, ids=None):
    truth = read(self, ids)
    sumo_edges = [sumo._vehicle_calls().getRoadID(vid) for vid in truth.ids]
    if sumo_edges != truth.edge_ids:
        counts["mismatches"].append([truth.t_s, sumo_edges, truth.edge_ids])
    counts["train_steps"] += len(truth.ids)
    return truth


sumo.EdgeMemory.edges_now = counted
sumo.SumoBridge.edge_memory_min_trains = 0  # the memory for any number of trains (the bridge's default: 100)
sumo.SumoBridge.read = checked
with tempfile.TemporaryDirectory() as out:
    sim = Simulation(load(sys.argv[1]), Path(out), progress=False)
    sim.run()
    counts["reversed"] = len(sim.events.rows("reversed"))
    counts["failure"] = sim.failure()
print(json.dumps(counts))
"""


def _checked_run(scenario: Path) -> dict:
    res = run_python(CHILD.replace("sys.argv[1]", repr(str(scenario))), reference=True)
    assert res.returncode == 0, res.stderr + res.stdout
    return json.loads(res.stdout.strip().splitlines()[-1])


def test_mini_line_edges_are_sumos_at_every_step() -> None:
    counts = _checked_run(DATA / "scenarios" / "mini_line.yaml")
    assert counts["failure"] is None and counts["mismatches"] == []
    assert counts["train_steps"] > 5000 and counts["asked"] < 0.3 * counts["train_steps"]


def test_a_reversing_unit_has_sumos_edge_at_every_step(tmp_path: Path) -> None:
    net, stops = build_tail_track(tmp_path)
    raw = {
        "name": "tail",
        "world": {"net": str(net), "additional": [str(stops)]},
        **_COMMON,
        "services": [_service("out", "Aston", "Bury", [0]), _service("back", "Bury", "Aston", [600])],
        "rotations": {"units": "auto", "turnback_min_s": 120},
    }
    raw["simulation"] = {**raw["simulation"], "duration_s": 1200}  # type: ignore[dict-item]
    scenario = tmp_path / "tail.yaml"
    scenario.write_text(yaml.safe_dump(raw, sort_keys=False))
    counts = _checked_run(scenario)
    assert counts["reversed"] == 1 and counts["failure"] is None
    assert counts["mismatches"] == [] and counts["asked"] < counts["train_steps"]
