"""The analytic headway floor (:mod:`railsim.studies.floor`) against closed forms and the brick-wall rule itself.

Here: the tests of it that run SUMO or a railsim child process; the others are in ``tests/unit/test_floor.py``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from railsim import scenario
from railsim.studies.floor import regime_floor

ROOT = Path(__file__).resolve().parents[2]


def test_line3_pattern_floors_follow_from_the_unit_floor() -> None:
    mb = scenario.load(ROOT / "scenarios" / "chongqing_line3_peak_mb.yaml")
    vc = scenario.load(ROOT / "scenarios" / "chongqing_line3_peak_vc.yaml")
    fmb = regime_floor(mb, ("airport_up", "airport_down"))
    fvc = regime_floor(vc, ("airport_up", "airport_down"))
    up_mb, up_vc = fmb.patterns[0], fvc.patterns[0]
    for st_mb, st_vc in zip(up_mb.stations, up_vc.stations):
        assert st_mb.station == st_vc.station and st_mb.path_s == pytest.approx(st_vc.path_s)
        if st_mb.dependent == "jurenba_up":  # one Jurenba unit per 4 Airport units, on its own path in (a)
            assert st_mb.strict_s == pytest.approx(2 * st_mb.path_s)
            assert st_mb.cycle_s == pytest.approx(5 * st_mb.path_s / 4)
            # (b): coupled Liugongli -> Bijin: one longer path instead of two
            assert st_vc.formation_s is not None and st_vc.formation_s > st_vc.path_s
            assert st_vc.cycle_s == pytest.approx((3 * st_vc.path_s + st_vc.formation_s) / 4)
            assert st_vc.cycle_s < st_mb.cycle_s and st_vc.strict_s < st_mb.strict_s
        else:
            assert st_mb.cycle_s == pytest.approx(st_mb.path_s) and st_vc.formation_s is None
    # a 45 s dwell station is critical, and the down pattern (independent Jurenba units in both) is the same
    assert up_mb.critical.dwell_s == 45.0
    assert fmb.patterns[1].critical.cycle_s == pytest.approx(fvc.patterns[1].critical.cycle_s)
