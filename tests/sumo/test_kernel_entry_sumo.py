"""The engine's compiled step through its entry point gives the run the dispatcher gives (railsim/engine/kernel_entry.py).

``ControlStage`` calls the line step (:func:`railsim.engine.line_step_kernel.step`) through numba's dispatcher once,
then through the entry point :func:`kernel_entry.direct` finds for the types it passes. A run on SUMO must take
that path (the entry point is what it ends with) and give byte for byte the trips, stops and events of the same run
with the dispatcher on every call — on the mini line and on Line 3's peak, both with line trains and CACC followers.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests.helpers import DATA, ROOT, run_python

CHILD = r"""
import json, sys, tempfile
from pathlib import Path
from railsim.engine import kernel_entry, line_step_kernel
from railsim.engine.control import ControlStage

coupled_steps = [0]
coupled_step = ControlStage._coupled_step
def counted(self, *args):
    coupled_steps[0] += 1
    return coupled_step(self, *args)
ControlStage._coupled_step = counted
from railsim.engine.loop import Simulation
from railsim.scenario.loading import load

def run(long_way):
    direct = kernel_entry.direct
    if long_way:
        kernel_entry.direct = lambda kernel, args, signature: kernel
    try:
        with tempfile.TemporaryDirectory() as out:
            sim = Simulation(load(sys.argv[1], {"simulation.duration_s": float(sys.argv[2])}), Path(out), progress=False)
            sim.run()
            sim.write(Path(out))
            step = sim.control._step
            files = {f: (Path(out) / f).read_text(encoding="utf-8") for f in ("trips.csv", "stops.csv", "events.csv")}
    finally:
        kernel_entry.direct = direct
    followers, coupled_steps[0] = coupled_steps[0], 0
    kind = "dispatcher" if step is line_step_kernel.step else "first" if getattr(step, "__name__", "") == "_first_step" else "entry"
    return {"files": files, "step": kind, "coupled_steps": followers}

print(json.dumps([run(False), run(True)]))
"""


@pytest.mark.parametrize(
    ("scenario", "duration_s"),
    [(DATA / "scenarios" / "mini_line.yaml", 1500.0), (ROOT / "scenarios" / "chongqing_line3_peak_vc.yaml", 3600.0)],
)
def test_run_through_the_entry_point_is_the_run_through_the_dispatcher(scenario: Path, duration_s: float) -> None:
    res = run_python(
        CHILD.replace("sys.argv[1]", repr(str(scenario))).replace("sys.argv[2]", repr(duration_s)), reference=True
    )
    assert res.returncode == 0, res.stderr[-3000:]
    fast, slow = json.loads(res.stdout.strip().splitlines()[-1])
    assert fast["step"] == "entry" and slow["step"] == "dispatcher"
    for name, text in fast["files"].items():
        assert text == slow["files"][name], name
    assert fast["files"]["trips.csv"].count("\n") > 3
    assert fast["coupled_steps"] > 100  # CACC followers stepped through the compiled step too
