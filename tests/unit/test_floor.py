"""The analytic headway floor (:mod:`railsim.studies.floor`) against closed forms and the brick-wall rule itself.

What is pinned: with a constant tractive force and no resistance the integrated floor equals the closed form within
one integration step (both when the leader is still accelerating and when it reaches line speed first); the closed
form is the *binding* headway — a follower arriving on its braking curve exactly then never violates the moving-block
rule, and one arriving half a second earlier does; and on Line 3 the pattern floors follow from the unit floor
(independent branch unit: strict 2·H, cycle (N+1)·H/N; a coupled formation: a longer path, a lower floor).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from railsim.studies.floor import Traction, closed_form_headway_s, station_headway_s


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
