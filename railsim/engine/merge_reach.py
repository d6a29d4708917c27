"""Can a formation that couples after a merge do so on the run, before its leader stands at its next stop?

A follower coming to merge ``X`` on the other leg may pass ``X`` only after the interlocking has released the
switch behind its leader (the leader's rear ``clearance`` past the switch point) and thrown it (``throw``). If the
leader then stops at a platform just past ``X``, it may be standing before the follower can be anywhere near it:
the pair couples standing at the platform, not on the run. This module answers the question with the engine's own
numbers for a leader on its own profile (the engine does not slow a leader down for its follower), before the run:

* **the leader** passes the switch point at its speed limit there less its ATO's margin and brakes at the ATO's
  planning rate ``b`` for its halt ``x_halt`` past the point: it stands ``t_halt`` after passing the point, and its
  rear clears the point by ``clearance`` at ``t_release``;
* **the follower** can pass the point ``t_pass = t_release + throw`` after the leader at the earliest (the
  interlocking's switch interval on the leader's profile) and then runs at most at its turnout limit until its
  rear has cleared the point, at the line limit beyond (no acceleration counted: an upper bound on how far it
  can be);
* the formation state machine counts a pair coupled after ``hold`` seconds in band, so the follower must be
  ``target gap`` behind the leader's rear at some instant ``t ≤ t_halt − hold``. ``least_gap_m`` is the closest
  it can come over those instants; above the target gap the verdict is ``infeasible`` with those numbers, and the
  pair couples standing at the platform (as a join).

This is a necessary condition for the leader's own profile, not a plan; whether a leader slowed down on purpose
could couple on the run is the junction planner's question (``benchmarks/bijin_merge_feasibility.py`` for the
Line 3 Bijin merge: ``docs/model.md``, "Coupling after a merge").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

STEP_S = 0.1  # time grid of the search for the closest approach


@dataclass(frozen=True)
class OnRunReach:
    """The numbers of the verdict (seconds from the leader's front passing the switch point, metres past it)."""

    leader_speed_at_point_mps: float
    leader_to_halt_s: float  # t_halt
    release_s: float  # t_release
    throw_s: float
    switch_interval_s: float  # t_pass = t_release + throw
    hold_s: float
    halt_m: float  # the leader's halt past the switch point
    least_gap_m: float  # closest the follower's front can be to the leader's rear by t_halt − hold (inf: never past)
    target_gap_m: float

    @property
    def feasible(self) -> bool:
        return self.least_gap_m <= self.target_gap_m

    def detail(self) -> dict[str, float | None]:
        """The event's and the summary's fields (rounded to 0.1)."""
        return {
            "switch_interval_s": round(self.switch_interval_s, 1),
            "release_s": round(self.release_s, 1),
            "throw_s": round(self.throw_s, 1),
            "leader_to_halt_s": round(self.leader_to_halt_s, 1),
            "hold_s": round(self.hold_s, 1),
            "least_gap_m": round(self.least_gap_m, 1) if math.isfinite(self.least_gap_m) else None,  # None: not past
            "target_gap_m": round(self.target_gap_m, 1),
            "leader_speed_at_point_mps": round(self.leader_speed_at_point_mps, 2),
            "halt_m": round(self.halt_m, 1),
        }


def _time_to_run_m(distance_m: float, cruise_m: float, v_mps: float, b_mps2: float) -> float:
    """Time a train at ``v_mps`` that cruises ``cruise_m`` then brakes at ``b_mps2`` to a halt takes to run
    ``distance_m`` (≤ the whole way)."""
    if distance_m <= cruise_m:
        return distance_m / v_mps
    left_m = max(cruise_m + v_mps * v_mps / (2.0 * b_mps2) - distance_m, 0.0)  # still to run when there
    return cruise_m / v_mps + (v_mps - math.sqrt(2.0 * b_mps2 * left_m)) / b_mps2


def _run_m(t_s: float, cruise_m: float, v_mps: float, b_mps2: float) -> float:
    """Distance that train has run ``t_s`` after the point (the inverse of :func:`_time_to_run_m`)."""
    t_cruise = cruise_m / v_mps
    if t_s <= t_cruise:
        return v_mps * t_s
    tb = min(t_s - t_cruise, v_mps / b_mps2)
    return cruise_m + v_mps * tb - 0.5 * b_mps2 * tb * tb


def on_run_reach(
    *,
    leader_limit_mps: float,
    speed_margin_mps: float,
    brake_mps2: float,
    halt_m: float,
    leader_length_m: float,
    clearance_m: float,
    throw_s: float,
    follower_turnout_mps: float,
    follower_line_mps: float,
    follower_length_m: float,
    target_gap_m: float,
    hold_s: float,
) -> OnRunReach:
    """The verdict for one formation at one merge (module docstring); every speed is a limit, before margins."""
    v = max(leader_limit_mps - speed_margin_mps, 0.1)
    if v * v / (2.0 * brake_mps2) > halt_m:  # too close to cruise: braking already at the point
        v = math.sqrt(2.0 * brake_mps2 * halt_m)
    cruise_m = halt_m - v * v / (2.0 * brake_mps2)
    t_halt = _time_to_run_m(halt_m, cruise_m, v, brake_mps2)
    t_release = _time_to_run_m(min(leader_length_m + clearance_m, halt_m), cruise_m, v, brake_mps2)
    t_pass = t_release + throw_s
    v_turn = max(follower_turnout_mps - speed_margin_mps, 0.1)
    v_line = max(follower_line_mps - speed_margin_mps, v_turn)
    t_zone = follower_length_m / v_turn  # until its rear has cleared the point
    least = math.inf
    n = int(math.floor((t_halt - hold_s - t_pass) / STEP_S))
    for k in range(n + 1):
        t = t_pass + k * STEP_S
        run = t - t_pass
        front_m = v_turn * run if run <= t_zone else follower_length_m + v_line * (run - t_zone)
        least = min(least, _run_m(t, cruise_m, v, brake_mps2) - leader_length_m - front_m)
    return OnRunReach(v, t_halt, t_release, throw_s, t_pass, hold_s, halt_m, least, target_gap_m)
