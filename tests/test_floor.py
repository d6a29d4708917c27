"""The analytic headway floor (:mod:`railsim.studies.floor`) against closed forms and the brick-wall rule itself.

What is pinned: with a constant tractive force and no resistance the integrated floor equals the closed form within
one integration step (both when the leader is still accelerating and when it reaches line speed first); the closed
form is the *binding* headway — a follower arriving on its braking curve exactly then never violates the moving-block
rule, and one arriving half a second earlier does; and on Line 3 the pattern floors follow from the unit floor
(independent branch unit: strict 2·H, cycle (N+1)·H/N; a coupled formation: a longer path, a lower floor).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from railsim import scenario
from railsim.studies.floor import Traction, closed_form_headway_s, regime_floor, station_headway_s

ROOT = Path(__file__).resolve().parents[1]


def _constant(accel_mps2: float, decel_mps2: float, length_m: float) -> Traction:
    mass = 1.0e5
    return Traction(mass, accel_mps2 * mass, math.inf, (0.0, 0.0, 0.0), decel_mps2, length_m)


CASES = [
    # (a, b, L, margin, v, T, dwell): leader still accelerating when the follower brakes / at line speed first
    (1.0, 1.1, 90.0, 50.0, 19.4, 3.0, 30.0),
    (0.6, 1.0, 210.0, 50.0, 12.0, 2.0, 45.0),
    (0.3, 0.8, 120.0, 20.0, 22.0, 1.0, 0.0),
]


@pytest.mark.parametrize("a, b, length, margin, v, dead, dwell", CASES)
def test_integrated_floor_matches_the_closed_form_within_a_step(
    a: float, b: float, length: float, margin: float, v: float, dead: float, dwell: float
) -> None:
    dt = 0.05
    closed = closed_form_headway_s(
        length_m=length, margin_m=margin, line_mps=v, dead_time_s=dead, accel_mps2=a, decel_mps2=b, dwell_s=dwell
    )
    got = station_headway_s(
        _constant(a, b, length), line_mps=v, dwell_s=dwell, margin_m=margin, dead_time_s=dead, dt_s=dt
    )
    assert abs(got - closed) <= dt, (got, closed)


def _worst_clearance_m(
    h_run_s: float, a: float, b: float, length: float, margin: float, v: float, dead: float
) -> float:
    """Smallest ``leader rear − margin − (follower front + S(v_f))`` over time when the leader leaves the mark at
    t = 0 from rest and the follower, cruising at ``v``, stops at the mark at ``h_run_s`` on its braking curve."""
    t = np.arange(-60.0, h_run_s + 1e-9, 0.001)
    leader = np.where(t < 0, 0.0, np.where(t < v / a, 0.5 * a * t**2, v * t - v * v / (2 * a)))
    t_brake = h_run_s - v / b
    v_f = np.where(t < t_brake, v, b * (h_run_s - t))
    front = np.where(t < t_brake, -v * v / (2 * b) - v * (t_brake - t), -(v_f**2) / (2 * b))
    braking = v_f * dead + v_f**2 / (2 * b)
    return float(np.min(leader - length - margin - (front + braking)))


@pytest.mark.parametrize("a, b, length, margin, v, dead, dwell", CASES)
def test_closed_form_is_the_binding_headway_of_the_brick_wall_rule(
    a: float, b: float, length: float, margin: float, v: float, dead: float, dwell: float
) -> None:
    h = closed_form_headway_s(
        length_m=length, margin_m=margin, line_mps=v, dead_time_s=dead, accel_mps2=a, decel_mps2=b, dwell_s=0.0
    )
    assert _worst_clearance_m(h, a, b, length, margin, v, dead) >= -0.05  # feasible exactly at the floor
    assert _worst_clearance_m(h - 0.5, a, b, length, margin, v, dead) < -1.0  # half a second earlier: violated


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
