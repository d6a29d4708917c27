"""The on-the-run verdict after a merge (:mod:`railsim.engine.merge_reach`) with the Line 3 Bijin down numbers.

The numbers are the engine's for ``bijin_down`` (``benchmarks/bijin_merge_feasibility.py`` reads them from the
world): leader's halt 271 m past the switch point, 70 km/h line, ATO margin 0.3 m/s and planning braking
0.8 × 1.11 m/s², 89.4 m units, clearance 10 m, 15 s throw, 30 km/h turnout, 30 m target gap, 5 s hold.
"""

from __future__ import annotations

import pytest

from railsim.engine.merge_reach import on_run_reach

BIJIN = dict(
    leader_limit_mps=19.444,
    speed_margin_mps=0.3,
    brake_mps2=0.888,
    halt_m=271.0,
    leader_length_m=89.4,
    clearance_m=10.0,
    throw_s=15.0,
    follower_turnout_mps=8.333,
    follower_line_mps=19.444,
    follower_length_m=89.4,
    target_gap_m=30.0,
    hold_s=5.0,
)


def test_bijin_down_cannot_couple_on_the_run_with_its_leader_on_its_own_profile() -> None:
    r = on_run_reach(**BIJIN)
    assert not r.feasible
    assert r.leader_to_halt_s == pytest.approx(24.9, abs=0.1)  # 65 m at 19.1 m/s, then 21.6 s of braking
    assert r.release_s == pytest.approx(5.3, abs=0.1)  # its rear 10 m past the point
    assert r.switch_interval_s == pytest.approx(20.3, abs=0.1)
    # 5 s before the leader stands (19.9 s) the follower may not even pass the point (20.3 s)
    assert r.least_gap_m == float("inf")
    d = r.detail()
    assert d["least_gap_m"] is None and d["leader_to_halt_s"] - d["hold_s"] < d["switch_interval_s"]


def test_a_faster_point_machine_makes_it_feasible_and_a_farther_platform_does_not() -> None:
    quick = on_run_reach(**{**BIJIN, "throw_s": 0.0})
    assert quick.feasible and quick.least_gap_m == pytest.approx(10.0, abs=0.5)
    slow = on_run_reach(**{**BIJIN, "throw_s": 5.0})
    assert not slow.feasible and slow.least_gap_m == pytest.approx(86.2, abs=0.5)
    # farther platforms: the leader runs on at line speed, the follower 20 s behind it never closes up
    for halt_m in (400.0, 800.0, 2000.0):
        far = on_run_reach(**{**BIJIN, "halt_m": halt_m})
        assert not far.feasible and far.least_gap_m > 200.0
