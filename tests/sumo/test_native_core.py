"""The compiled core (railsim/native.py): the suite's children load it, and it is what they run.

``make test`` builds it first (``make native``). The suite's own process runs the interpreted modules
(``tests/conftest.py``); every child — each SUMO run, the golden tier's — loads the compiled modules, so the golden
bytes hold for the compiled core (and ``tests/golden/test_golden.py`` holds the interpreted demo to the same bytes).
"""

from __future__ import annotations

import os

import pytest

from tests.helpers import run_python

STATUS = "import railsim.native as n, railsim.engine.loop as loop; print(n.STATUS); print(loop.__file__)"


@pytest.mark.skipif(os.environ.get("RAILSIM_NATIVE") == "0", reason="RAILSIM_NATIVE=0 asks for the interpreted modules")
def test_the_suites_children_load_the_compiled_core() -> None:
    res = run_python(STATUS)
    assert res.returncode == 0, res.stderr
    status, loop_file = res.stdout.splitlines()[:2]
    assert status.startswith("compiled"), f"{status} (make native builds it; its log: build/native.log)"
    assert loop_file.endswith(".so") and "build/native" in loop_file, loop_file
    assert res.stderr == ""


def test_asked_for_the_interpreted_modules_a_child_loads_the_sources() -> None:
    res = run_python(STATUS, reference=True)
    assert res.returncode == 0, res.stderr
    status, loop_file = res.stdout.splitlines()[:2]
    assert status == "interpreted (RAILSIM_NATIVE=0)" and loop_file.endswith("railsim/engine/loop.py"), res.stdout


VALUES = """
import copy, pickle, sys
from dataclasses import replace
import railsim.native as n
from railsim.engine.settings import EngineSettings
from railsim.physics.vehicle import preset
from railsim.scenario import VEHICLE_FIELDS
v, s = preset("cq3_6car"), EngineSettings(lookahead_m=123.0)
print(n.STATUS.split()[0], sys.modules[type(v).__module__].__file__.endswith(".so"))
print(pickle.loads(pickle.dumps(v)) == v, copy.deepcopy(s) == s, replace(s, clearance_m=5.0).lookahead_m)
print(VEHICLE_FIELDS["capacity_pax"], VEHICLE_FIELDS["length_m"])
"""


@pytest.mark.skipif(os.environ.get("RAILSIM_NATIVE") == "0", reason="RAILSIM_NATIVE=0 asks for the interpreted modules")
def test_the_compiled_vehicle_and_settings_are_still_values() -> None:
    """Compiled, the frozen dataclasses VehicleParams and EngineSettings pickle, copy and compare as before (a
    compiled frozen class cannot set its fields one by one: they pickle as a constructor call), and the scenario
    checks still read their fields' types (compiled, a field's type is the class, not its name)."""
    res = run_python(VALUES)
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == ["compiled", "True", "True", "True", "123.0", "int", "float"], res.stdout
