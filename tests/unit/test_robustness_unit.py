"""``railsim robustness``: Monte-Carlo runs on the sweep machinery, KPIs with 95 % intervals, resumable.

Here: the tests of it that start no process; the others are in ``tests/sumo/test_robustness.py``.
"""

from __future__ import annotations

import math

from railsim.studies.robustness import ci95, verdict


def test_confidence_interval_is_the_student_t_half_width() -> None:
    s = ci95([1.0, 2.0, 3.0, None])
    # sd = 1, t(0.975, 2) = 4.302653, half-width = t·sd/√3
    assert s["n"] == 3 and s["mean"] == 2.0 and s["sd"] == 1.0
    assert math.isclose(s["ci95"], 4.302652729911275 / math.sqrt(3.0), rel_tol=1e-9)
    assert verdict({"mean": 0.5, "ci95": 0.4}) is True
    assert verdict({"mean": 1.5, "ci95": 0.4}) is False
    assert verdict({"mean": 0.9, "ci95": 0.4}) is None


def test_paired_differences_use_only_common_seeds() -> None:
    from railsim.studies.vc_robustness import paired_differences

    def regime(values: dict[str, float]) -> dict:
        per_seed = {s: {"knock_on_min": v} for s, v in values.items()}
        return {"groups": [{"headway_s": 110.0, "intensity": 1.0, "per_seed": per_seed}]}

    rows = paired_differences(regime({"1": 1.0, "2": 2.0, "3": 3.0, "9": 50.0}), regime({"1": 2.0, "2": 4.0, "3": 3.0}))
    assert len(rows) == 1 and rows[0]["n_pairs"] == 3  # seed 9 ran under moving block only: not a pair
    k = rows[0]["knock_on_min"]
    assert k["n"] == 3 and k["mean"] == 1.0 and k["vc_higher"] == 2  # differences 1, 2, 0
