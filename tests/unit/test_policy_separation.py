"""ADBM vs RDBM as the line's separation policy (Paper D §3.9), closed forms and a SUMO run on Line 3.

ADBM caps the follower at the speed that stops it before the leader's rear (``v·t + v²/(2b) = gap − margin``);
RDBM also credits the leader's own braking distance (``+ v_l²/(2 b_l)``), so at the same gap and a moving leader it
allows more speed. In SUMO (Jiugongli → Bagongli, the follower released 20 s behind) the follower is held back less
(shorter mean running time) under RDBM, and neither collides: the leader brakes as assumed.
"""

from __future__ import annotations

import math

import pytest

from controllers.base import Observation, OwnState, PredecessorState
from controllers.monorail.policy_separation import make_policy_separation
from railsim.physics.vehicle import preset

VEH = preset("cq3_6car")


def _cap(mode: str, gap: float, v_lead: float) -> float:
    ctl = make_policy_separation({"mode": mode, "t_eq_s": 1.0, "margin_m": 5.0}, VEH)
    own = OwnState("f", 0.0, 10.0, 0.0, VEH.length_m)
    pred = PredecessorState("l", gap + VEH.length_m, v_lead, 0.0, VEH.length_m, stamp_s=0.0, age_s=0.0)
    cmd = ctl.command(Observation(t_s=0.0, dt_s=0.5, own=own, vehicle=VEH, route_length_m=1e4, predecessor=pred))
    return cmd.info["v_cap_mps"]


def test_caps_follow_the_closed_forms() -> None:
    b, t, margin, gap = VEH.emergency_decel_mps2, 1.0, 5.0, 120.0
    v_adbm = -b * t + math.sqrt((b * t) ** 2 + 2 * b * (gap - margin))
    assert _cap("adbm", gap, 15.0) == pytest.approx(v_adbm, rel=1e-9)
    room = gap - margin + 15.0**2 / (2 * b)
    assert _cap("rdbm", gap, 15.0) == pytest.approx(-b * t + math.sqrt((b * t) ** 2 + 2 * b * room), rel=1e-9)
    assert _cap("rdbm", gap, 15.0) > _cap("adbm", gap, 15.0)
    assert _cap("rdbm", gap, 0.0) == pytest.approx(_cap("adbm", gap, 0.0))  # a standing leader: the same
