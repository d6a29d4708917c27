"""The slot store in whole runs: at every check the truth pass reads what the trains themselves hold.

railsim/engine/slots.py keeps the truth pass's inputs resident and writes them when they change, instead of gathering
them from the trains each step. Here the engine runs in SUMO with a probe on the truth pass: at every step, right
before the pass, each train's row (route, depart chainage, pointer, reversing, the speed handed to SUMO, length) must
equal the row read from the train (``SlotStore.gathered``, the former gather). Two runs: a unit shuttling on a
single-track line with rotations (it reverses on bidi platforms: views and depart chainages handed over to its next
trips, reversing set and cleared) and the mini line with a coupled pair (trains joining and leaving the step).
"""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from tests.helpers import DATA, run_python
from tests.sumo.test_external_net import _COMMON, _write
from tests.sumo.test_single_track import build_single_line
from tests.sumo.test_turnback import SHUTTLE

CHILD = r"""
import json, tempfile
from pathlib import Path
from railsim.engine import slots
from railsim.engine.loop import Simulation
from railsim.scenario.loading import load

with tempfile.TemporaryDirectory() as out:
    sim = Simulation(load(SCENARIO), Path(out), progress=False)
    store, read = sim.slots, sim.truth.read
    seen = {"checks": 0, "sent": 0, "reversing": 0, "mismatch": []}

    def probed(t, active, truth):
        store.index(active)
        got = store.table[store.slots, slots.ROUTE : slots.LENGTH_M + 1]
        want = store.gathered(active)
        if got.tobytes() != want.tobytes() and len(seen["mismatch"]) < 5:
            seen["mismatch"].append([t, got.tolist(), want.tolist()])
        seen["checks"] += len(active)
        seen["sent"] += int((got[:, slots.SENT_MPS] == got[:, slots.SENT_MPS]).sum())  # not NaN: a speed was sent
        seen["reversing"] += int(got[:, slots.REVERSING].sum())
        read(t, active, truth)

    sim.truth.read = probed
    summary = sim.run()
seen["reversed"] = len(list(sim.events.entries("reversed")))
seen["arrived"] = summary["n_arrived"]
print(json.dumps(seen))
"""


def _probe(scenario: Path) -> dict:
    res = run_python(CHILD.replace("SCENARIO", repr(str(scenario))), reference=True)
    assert res.returncode == 0, res.stderr[-3000:]
    return json.loads(res.stdout.strip().splitlines()[-1])


def test_a_shuttle_that_reverses_reads_what_its_trips_hold_at_every_step(tmp_path: Path) -> None:
    net, stops = build_single_line(tmp_path)
    raw = {
        "name": "shuttle",
        "world": {"net": str(net), "additional": [str(stops)]},
        **_COMMON,
        "services": SHUTTLE,
        "rotations": {"units": "auto", "turnback_min_s": 60},
    }
    raw["simulation"] = {**raw["simulation"], "duration_s": 2500}  # type: ignore[dict-item]
    seen = _probe(_write(tmp_path, "scenario.yaml", yaml.safe_dump(raw, sort_keys=False)))
    assert seen["mismatch"] == []
    assert seen["reversed"] == 3 and seen["arrived"] == 4  # three turnbacks, four trips of one unit
    assert seen["reversing"] > 0 and seen["sent"] > 0.9 * seen["checks"] > 1000


def test_the_mini_line_reads_what_its_trains_hold_at_every_step() -> None:
    seen = _probe(DATA / "scenarios" / "mini_line.yaml")
    assert seen["mismatch"] == []
    assert seen["arrived"] > 1 and seen["sent"] > 0.9 * seen["checks"] > 1000
