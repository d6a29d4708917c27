"""Readings of the junction planner online (:mod:`.paper004`) that fix its parameters from the engine's rules.

Where the paper's model (mass points, a 10 s switch interval, ``S_0`` = 10 m) and the engine (trains of real
length, an interlocking that frees a switch only behind the rear, a relative-braking-distance guard) differ, the
planner is given the engine's numbers, so that its plans are ones the engine lets trains fly.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from controllers.base import Observation, OwnState, PredecessorState
from controllers.junction.model import JunctionParams
from railsim.engine.extensions.paper004_tracking import PlannedTrain


def switch_interval_s(
    settings: Any, members: Iterable[PlannedTrain], p: JunctionParams, throw_s: float, length_m: float
) -> float:
    """The planner's ``t_ls``: the least time between two passages on different legs that the interlocking
    can serve without stopping the second train (unless ``junction.params.throw_time_s`` is given).

    *Reading (departure from the paper's 10 s, which treats trains as points passing instantly):* after the
    first train passes the turnout entry, its body must clear the switch point by the clearance distance
    before the lock is released (``release``), then the switch throws (``throw_s``), and the lock must be
    granted before the second train reaches its braking point for the protection point in front of the
    switch (``sighting``), or its ATO brakes for the end of its movement authority::

        t_ls = (turnout + L + clearance) / v_lsr  +  throw_s  +  (v_lsn² / (2 |a_min|) + protection) / v_lsn
    """
    st = settings
    turnout = max((m.point_m[sid] - m.switch_m[sid] for m in members for sid in m.legs), default=0.0)
    release = (turnout + length_m + st.clearance_m) / p.reverse_speed_mps
    v = p.normal_speed_mps
    sighting = (v * v / (2.0 * abs(p.accel_min_mps2)) + st.protection_margin_m) / v
    return float(release + throw_s + sighting)


def safe_gap_m(ports: Any, train_ids: list[str], speed_mps: float) -> float:
    """The gap the followers' own coupled controller holds at ``speed_mps`` behind an equally fast leader.

    *Reading:* the planner's ``S_0`` (standstill part of ``S_m``, spec §6 #5) is raised to this gap, so that the
    planned slots at F are ones the engine's relative-braking-distance safety cap lets the trains take; with
    the spec's ``S_0`` = 10 m the guard holds followers ~8 m further back than planned (measured in SUMO) and
    no platoon meets Eq. 2 (``|D − S_m| ≤ 5 m``). The controller is asked, not re-derived: one ``command`` on a
    synthetic observation (leader at equal speed, message age = the t2t delay's mean) returns its target.
    """
    gaps = [0.0]
    ch = ports.channels.get("t2t")
    age = float(ch.delay.mean_delay_s) if ch is not None else 0.1
    for tid in train_ids:
        tr = ports.trains[tid]
        ctl = tr.controllers.get("coupled")
        if ctl is None:
            continue
        veh = tr.trip.vehicle
        own = OwnState(tid, 1000.0, speed_mps, 0.0, veh.length_m)
        pred = PredecessorState(
            "leader",
            2000.0,
            speed_mps,
            0.0,
            veh.length_m,
            0.0,
            age,
            veh.service_decel_mps2,
            veh.emergency_decel_mps2,
        )
        obs = Observation(
            t_s=age,
            dt_s=ports.dt_s,
            own=own,
            vehicle=veh,
            route_length_m=1e6,
            predecessor=pred,
            formation_state="coupled",
            target_gap_m=1.0,
        )
        info = ctl.command(obs).info or {}
        gaps.append(float(info.get("target_gap_m", 0.0)))
    return max(gaps)


def turnout_start(tr: Any, point_m: float) -> float:
    """Route chainage where the leg speed restriction in front of a switch point begins (the point if none)."""
    line = tr.view.line_speed_mps
    for a, b, v in tr.trip.route.speed_limits:
        if a < point_m <= b + 0.5 and v < line - 1e-6:
            return a
    return point_m
