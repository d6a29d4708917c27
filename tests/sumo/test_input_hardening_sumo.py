"""Reproducers, one regression test each: inputs that once crashed, hung, leaked or passed validation.

Here: the tests of it that run SUMO or a railsim child process; the others are in ``tests/unit/test_input_hardening.py``.
"""

from __future__ import annotations

from pathlib import Path

from tests import fuzz
from tests.helpers import ROOT
from tests.unit.test_input_hardening import CORRIDOR, _rejected


def test_sweep_validate_checks_every_case_with_run_checks(tmp_path: Path) -> None:
    ok = fuzz.validate_in_process(ROOT / "scenarios" / "sweeps" / "corridor_headway.yaml", world_check=True)
    assert ok.problem is None and ok.rc == 0, ok.stderr
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(f"base: {CORRIDOR}\ngrid:\n  services[0].from: [s1, s9]\n", encoding="utf-8")
    line = _rejected(sweep, world_check=True)  # only the world knows s9 is no station
    assert "sweep.yaml: case 1 (services[0].from=s9, seed 3): " in line and "services[0].from" in line, line
    sweep.write_text(f"base: {CORRIDOR}\ncases:\n  - {{simulation.step_s: 1e-300}}\n", encoding="utf-8")
    assert "case 0 (simulation.step_s=1e-300, seed 3): " in _rejected(sweep)
