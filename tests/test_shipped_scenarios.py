"""Every scenario shipped in ``scenarios/`` validates against the schema and its world (``railsim validate``).

A user's first contact with railsim is running one of these files; a stale field or a renamed station must fail
here, not in front of them. (The SUMO runs of the important ones are in their own tests.)
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.helpers import ROOT, run_railsim

SCENARIOS = sorted((ROOT / "scenarios").glob("*.yaml"))


def test_there_are_shipped_scenarios() -> None:
    assert len(SCENARIOS) >= 10


@pytest.mark.parametrize("path", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_shipped_scenario_validates(path: Path, tmp_path: Path) -> None:
    res = run_railsim(["validate", str(path)], cache_dir=tmp_path)
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith("ok:"), res.stdout


SWEEPS = sorted(p for p in (ROOT / "scenarios" / "sweeps").glob("*.yaml") if "\nbase:" in "\n" + p.read_text())


@pytest.mark.parametrize("path", SWEEPS, ids=[p.stem for p in SWEEPS])
def test_shipped_sweep_validates(path: Path) -> None:
    """Every case of every shipped sweep file loads and passes the scenario schema (world ids: the scenarios above)."""
    from railsim.studies import sweep

    spec = sweep.load_sweep(path)
    assert spec.cases
    sweep.validate_cases(spec, world_check=False)
