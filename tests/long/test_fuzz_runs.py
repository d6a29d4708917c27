"""The operating fuzz (:mod:`tests.fuzz_runs`): a fixed sample of unusual-but-valid mini-line variants run in real SUMO
keep the safety contract — an exit code of the contract, no traceback, a summary without NaN that never counts fewer
collisions than SUMO saw, and no collision at all.

The sample is variants 0–11 (deterministic); ``python -m tests.fuzz_runs --n 300`` is the campaign. The test that
the sample reaches the unusual corners it is meant to is in ``tests/unit/test_fuzz_runs_unit.py``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests import fuzz_runs
from tests.unit.test_fuzz_runs_unit import SAMPLE


@pytest.mark.parametrize("k", SAMPLE)
def test_variant_keeps_the_contract(k: int, tmp_path: Path) -> None:
    res = fuzz_runs.run_variant(k, tmp_path)
    assert res.problems == [], f"variant {k} (exit {res.rc}): {res.problems}"
    assert res.rc in (0, 2, 3)  # 1 (a collision) is already a problem above
    if res.rc != 2:
        assert res.summary is not None and res.summary["n_trains"] >= 4
