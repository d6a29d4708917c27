"""The golden outputs with the SUMO bridge's edge memory on for any number of trains.

The bridge reads a train's edge only where its odometer and lane position cannot vouch for the last one
(:class:`railsim.engine.sumo.EdgeMemory`), but only from ``EDGE_MEMORY_MIN_TRAINS`` trains present: the golden
runs have fewer, so they read every edge. Here the demo (edge changes, junctions, stops, turnbacks of a whole line)
and the external passing loop run with the memory forced on and must give the golden bytes all the same.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.golden import CASES, hash_outputs, load_golden
from tests.helpers import ROOT, run_python

CHILD = r"""
import sys
from railsim.engine import sumo
from railsim.cli.main import main

sumo.SumoBridge.edge_memory_min_trains = 0
sys.exit(main(ARGS))
"""


@pytest.mark.parametrize("name", ["demo_line3_peak", "external_passing_loop"])
def test_outputs_with_the_edge_memory_forced_on_are_golden(name: str, tmp_path: Path) -> None:
    case = next(c for c in CASES if c.name == name)
    scenario = case.scenario(tmp_path) if callable(case.scenario) else ROOT / case.scenario
    out = tmp_path / "out"
    args = ["run", str(scenario), "--out", str(out), "--seed", str(case.seed), "--no-progress"]
    res = run_python(CHILD.replace("ARGS", repr(args)), cache_dir=tmp_path / "cache", timeout=900, reference=True)
    assert res.returncode in (0, 1) and "Traceback" not in res.stderr, res.stderr[-3000:]
    got = hash_outputs(name, tmp_path, res.returncode)
    expected = load_golden()[name]
    assert got == expected, sorted(k for k in set(got) | set(expected) if got.get(k) != expected.get(k))
