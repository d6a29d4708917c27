"""Every scenario shipped in ``scenarios/`` validates against the schema and its world (``railsim validate``).

Here: the tests of it that run SUMO or a railsim child process; the others are in ``tests/unit/test_shipped_scenarios.py``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.helpers import run_railsim
from tests.unit.test_shipped_scenarios import SCENARIOS


@pytest.mark.parametrize("path", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_shipped_scenario_validates(path: Path) -> None:
    res = run_railsim(["validate", str(path)])
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith("ok:"), res.stdout
