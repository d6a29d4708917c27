"""The operating fuzz (:mod:`tests.fuzz_runs`): a fixed sample of unusual-but-valid mini-line variants run in real SUMO
keep the safety contract — an exit code of the contract, no traceback, a summary without NaN that never counts fewer
collisions than SUMO saw, and no collision at all.

Here: the tests of it that start no process; the others are in ``tests/long/test_fuzz_runs.py``.
"""

from __future__ import annotations

from tests import fuzz_runs

SAMPLE = range(12)


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
