"""The compiled free run gives the same bits as its interpreted form (the loop is written once).

Here: the tests of it that run SUMO or a railsim child process; the others are in ``tests/unit/test_free_run_kernel.py``.
"""

from __future__ import annotations

import json

import pytest

from railsim.physics import dynamics
from tests.helpers import DATA, ROOT, run_python

CHILD = r"""
import dataclasses, json, sys, tempfile
from pathlib import Path
from controllers.ato import Ato
from railsim.engine import free_run_kernel, trips as T
from railsim.engine.fleet import ato_factory
from railsim.engine.loop import Simulation
from railsim.engine.primary_delays import scaled_vehicle
from railsim.scenario.loading import load
from tests.helpers import interpreted

reference = interpreted(free_run_kernel).free_run

scn = load(SCENARIO)
with tempfile.TemporaryDirectory() as out:
    sim = Simulation(scn, Path(out), progress=False)
seen, rows = set(), []
for tr in sim.trains.values():
    trip = tr.trip
    key = (trip.route.id, trip.stops, trip.start_offset_m, trip.start_speed_mps)
    if key in seen:
        continue
    seen.add(key)
    for factor in FACTORS:
        run = trip if factor == 1.0 else dataclasses.replace(trip, vehicle=scaled_vehicle(trip.vehicle, factor))
        for dt in STEPS:
            for method in METHODS:
                ato = ato_factory(sim.scenario, dict(trip.roles), trip.vehicle, method)()
                assert type(ato) is Ato
                fast = T.free_run(run, ato, dt, method, 6 * 3600.0)
                slow = T.free_run(run, ato, dt, method, 6 * 3600.0, loop=reference)
                rows.append([method, list(fast[0].items()), list(fast[1].items()), list(slow[0].items()), list(slow[1].items())])
print(json.dumps(rows))
"""


@pytest.mark.parametrize(
    ("scenario", "steps", "methods", "factors"),
    [
        (DATA / "scenarios" / "mini_line.yaml", (0.1, 0.5, 1.0), dynamics.STEP_METHODS, (1.0, 0.9, 0.95)),
        (ROOT / "scenarios" / "chongqing_line3_peak.yaml", (0.5,), ("euler",), (1.0, 0.97)),
    ],
)
def test_compiled_free_run_is_the_reference_bit_for_bit(scenario, steps, methods, factors, tmp_path_factory) -> None:
    code = CHILD.replace("SCENARIO", repr(str(scenario))).replace("FACTORS", repr(factors))
    code = code.replace("STEPS", repr(steps)).replace("METHODS", repr(tuple(methods)))
    res = run_python(code)
    assert res.returncode == 0, res.stderr[-3000:]
    rows = json.loads(res.stdout.strip().splitlines()[-1])
    assert len(rows) >= len(steps) * len(methods) * len(factors) * 2  # at least two distinct trips
    for method, fast_arr, fast_dep, slow_arr, slow_dep in rows:
        assert fast_arr == slow_arr and fast_dep == slow_dep  # same floats (JSON keeps 17 digits), same order
        if method == "euler":  # whole runs compared (the line ATO's stop predictor is Euler's: with the other
            assert len(slow_arr) >= 3  # methods at 0.5-1 s it may never halt in a window, 6 h both ways)
