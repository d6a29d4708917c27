"""The operating fuzz (:mod:`tests.fuzz_runs`): a fixed sample of unusual-but-valid mini-line variants run in real SUMO
keep the safety contract — an exit code of the contract, no traceback, a summary without NaN that never counts fewer
collisions than SUMO saw, and no collision at all.

The sample is variants 0–11 (deterministic); ``python -m tests.fuzz_runs --n 300`` is the campaign. A test of the
generator itself checks that the sample reaches the unusual corners it is meant to (it would otherwise test little).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests import fuzz_runs

SAMPLE = range(12)


@pytest.mark.parametrize("k", SAMPLE)
def test_variant_keeps_the_contract(k: int, tmp_path: Path) -> None:
    res = fuzz_runs.run_variant(k, tmp_path)
    assert res.problems == [], f"variant {k} (exit {res.rc}): {res.problems}"
    assert res.rc in (0, 2, 3)  # 1 (a collision) is already a problem above
    if res.rc != 2:
        assert res.summary is not None and res.summary["n_trains"] >= 4


def test_sample_reaches_the_unusual_corners() -> None:
    variants = [fuzz_runs.variant(k) for k in SAMPLE]
    methods = {v["simulation"]["step_method"] for v in variants}
    steps = {v["simulation"]["step_s"] for v in variants}
    assert methods == {"euler", "ballistic", "forward"}
    assert min(steps) <= 0.1 and max(steps) >= 1.0
    assert any("formations" in v for v in variants) and any("formations" not in v for v in variants)
    assert any(v["faults"]["comm"]["t2g"].get("loss_prob", 0) >= 0.5 for v in variants)
    assert any(any("start" in s for s in v["services"]) for v in variants)
    # deterministic: variant k is the same mapping every time
    assert fuzz_runs.variant(5) == fuzz_runs.variant(5)
