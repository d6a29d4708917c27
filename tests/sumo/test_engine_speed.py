"""The engine's speed shortcuts give the same bits as the long way.

Each shortcut on the hot path has a reference it must reproduce exactly: here the free-run planner's direct
call of the line ATO's law (no observation objects), against the same law reached through ``command(obs)``.
Other shortcuts have their own tests beside the code they shortcut (``test_occupancy``: the edge pointer and
restriction windows; ``test_controllers_line``: the ATO screens; ``test_events_comms``: deliveries).
"""

from __future__ import annotations

import json

import pytest

from tests.helpers import DATA, ROOT, run_python

CHILD = r"""
import json, sys, tempfile
from pathlib import Path
from controllers.ato import Ato
from railsim.engine import trips as trips_mod
from railsim.engine.fleet import ato_factory
from railsim.engine.loop import Simulation
from railsim.scenario.loading import load

class ObservedAto(Ato):
    '''The line ATO reached through command(observation): its type is not Ato, so the planner takes the long way.'''

def observed(factory):
    def make():
        ato = factory()
        twin = ObservedAto.__new__(ObservedAto)
        twin.__dict__.update(ato.__dict__)
        return twin
    return make

scn = load(sys.argv[1])
with tempfile.TemporaryDirectory() as out:
    sim = Simulation(scn, Path(out), progress=False)
seen, rows = set(), []
for tr in sim.trains.values():
    trip = tr.trip
    key = (trip.route.id, trip.stops, trip.start_offset_m, trip.start_speed_mps)
    if key in seen:
        continue
    seen.add(key)
    factory = ato_factory(sim.scenario, dict(trip.roles), trip.vehicle, sim.step_method)
    assert type(factory()) is Ato
    fast = trips_mod._free_run_cached(("fast",) + key, trip, factory, sim.dt, sim.step_method, 6 * 3600.0)
    slow = trips_mod._free_run_cached(("slow",) + key, trip, observed(factory), sim.dt, sim.step_method, 6 * 3600.0)
    rows.append([fast, slow])
print(json.dumps(rows))
"""


@pytest.mark.parametrize(
    "scenario", [DATA / "scenarios" / "mini_line.yaml", ROOT / "scenarios" / "chongqing_line3_peak.yaml"]
)
def test_free_run_plan_on_plain_values_is_the_observed_plan(scenario, tmp_path_factory) -> None:
    """Every distinct trip's planned arrivals and departures are the same floats both ways (JSON keeps all 17
    digits), and a plan reaches the trip's destination (so the comparison covers whole runs)."""
    res = run_python(CHILD.replace("sys.argv[1]", repr(str(scenario))), reference=True)
    assert res.returncode == 0, res.stderr[-3000:]
    rows = json.loads(res.stdout.strip().splitlines()[-1])
    assert rows
    for fast, slow in rows:
        assert fast == slow
        assert len(fast[0]) >= 2  # origin and at least one station reached


HEAP_CHILD = r"""
import gc, json, tempfile
from pathlib import Path
from railsim.engine.loop import Simulation
from railsim.scenario.loading import load

seen = []
class Probe(Simulation):
    def _step(self, t):
        seen.append(gc.get_freeze_count())
        super()._step(t)

with tempfile.TemporaryDirectory() as out:
    sim = Probe(load(SCENARIO), Path(out), progress=False)
    before = gc.get_freeze_count()
    sim.run()
print(json.dumps({"before": before, "during": min(seen), "after": gc.get_freeze_count(), "n_set_up": len(sim.trains)}))
"""


def test_the_set_up_is_frozen_for_the_run_and_released_after(tmp_path_factory) -> None:
    """railsim.engine.heap: while the loop runs, everything the set-up built sits in the collector's permanent
    generation (full collections do not walk it again), and the run gives it back when it ends."""
    code = HEAP_CHILD.replace("SCENARIO", repr(str(DATA / "scenarios" / "mini_line.yaml")))
    res = run_python(code, reference=True)
    assert res.returncode == 0, res.stderr[-3000:]
    got = json.loads(res.stdout.strip().splitlines()[-1])
    assert got["before"] == 0 and got["after"] == 0
    assert got["during"] > 10_000  # the set-up's objects (trips, views, controllers, the network), not a handful


DECISION_CHILD = r"""
import json
from pathlib import Path
from railsim.engine.control import ControlStage
from railsim.engine.loop import run
from railsim.scenario.loading import load
from tests.golden import hash_outputs

scenario, workdir, mode = Path(SCENARIO), Path(WORKDIR), MODE
compiled = [0]
line_step = ControlStage._line_step

def counted(self, *args):
    compiled[0] += 1
    return line_step(self, *args)

ControlStage._line_step = counted
if mode == "roles":  # no train is a line train: every decision goes through the roles one by one
    ControlStage._is_line_train = lambda self, tr, a, ato: False
run(load(scenario), workdir / "out", progress=False)
print(json.dumps({"compiled": compiled[0], "hashes": hash_outputs(mode, workdir, 0)}))
"""


@pytest.mark.parametrize("sensor_noise", [False, True])
def test_compiled_line_step_decides_what_the_roles_one_by_one_decide(sensor_noise: bool, tmp_path) -> None:
    """``ControlStage.control`` decides in one place and hands a line train to the compiled line step. The mini
    line (line trains, a coupled pair, a merge), once as it runs and once with every train sent through its roles
    one by one (``_role_commands``, ``arbitrate``, the plant), gives the same outputs byte for byte; with sensor
    noise too (drawn before the decision, so both runs draw the same numbers)."""
    import yaml

    from tests.helpers import mini_line

    data = mini_line()
    if sensor_noise:
        data["faults"]["sensor_noise"] = {"position_sd_m": 0.5, "speed_sd_mps": 0.05}
    scenario = tmp_path / "mini.yaml"
    scenario.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    runs = {}
    for mode in ("as_run", "roles"):
        code = (
            DECISION_CHILD.replace("SCENARIO", repr(str(scenario)))
            .replace("WORKDIR", repr(str(tmp_path / mode)))
            .replace("MODE", repr(mode))
        )
        res = run_python(code, cache_dir=tmp_path / "cache", reference=True)
        assert res.returncode == 0, res.stderr[-3000:]
        runs[mode] = json.loads(res.stdout.strip().splitlines()[-1])
    assert runs["as_run"]["compiled"] > 1000 and runs["roles"]["compiled"] == 0
    assert {"trips.csv", "trace.csv", "events.csv"} <= set(runs["as_run"]["hashes"])
    assert runs["as_run"]["hashes"] == runs["roles"]["hashes"]


AT_T_CHILD = r"""
import json
from pathlib import Path
from railsim.engine.control import ControlStage
from railsim.engine.loop import run
from railsim.scenario.loading import load

calls = []  # (t, "situation" | "stepped", train)
situation, commit = ControlStage._situation, ControlStage._commit

def read(self, t, tr, a, rear):
    calls.append((t, "situation", tr.train_id))
    return situation(self, t, tr, a, rear)

def stepped(self, tr, *args):
    calls.append((self.knowledge.layer.now_s, "stepped", tr.train_id))
    return commit(self, tr, *args)

ControlStage._situation, ControlStage._commit = read, stepped
run(load(Path(SCENARIO)), Path(WORKDIR), progress=False)
print(json.dumps(calls))
"""


def test_every_situation_is_read_at_t_before_any_train_is_stepped(tmp_path) -> None:
    """``ControlStage.control_all`` reads every train's situation (its stop, limits, authority and the berth rule on
    the train ahead) before it steps any train, so what a train sees of the train ahead is that train's state at
    ``t`` whatever their order in the step. On the mini line (several trains at once, a platform shared in turn)
    no situation of a step is read after a train of that step was stepped, and every stepped train had its
    situation read in the same step."""
    import yaml

    from tests.helpers import mini_line

    scenario = tmp_path / "mini.yaml"
    scenario.write_text(yaml.safe_dump(mini_line(), sort_keys=False), encoding="utf-8")
    code = AT_T_CHILD.replace("SCENARIO", repr(str(scenario))).replace("WORKDIR", repr(str(tmp_path / "out")))
    res = run_python(code, cache_dir=tmp_path / "cache", reference=True)
    assert res.returncode == 0, res.stderr[-3000:]
    calls = json.loads(res.stdout.strip().splitlines()[-1])
    by_step: dict[float, list[tuple[str, str]]] = {}
    for t, what, train in calls:
        by_step.setdefault(t, []).append((what, train))
    crowded = 0
    for t, seq in by_step.items():
        read = [train for what, train in seq if what == "situation"]
        first_step = next((i for i, (what, _) in enumerate(seq) if what == "stepped"), len(seq))
        assert all(what == "stepped" for what, _ in seq[first_step:]), f"a situation read after a step at t={t}"
        assert {train for what, train in seq if what == "stepped"} <= set(read)
        crowded += len(read) > 1
    assert crowded > 100  # steps with several trains on the line: the order could matter there
