"""Readings of the junction planner online (:mod:`.coordinator`) that fix its parameters from the engine's rules.

Where the paper's model (mass points, a 10 s switch interval, ``S_0`` = 10 m) and the engine (trains of real
length, an interlocking that frees a switch only behind the rear, a relative-braking-distance guard) differ, the
planner is given the engine's numbers, so that its plans are ones the engine lets trains fly.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

from controllers.base import Observation, OwnState, PredecessorState
from controllers.junction.model import JunctionParams
from controllers.junction.qp import InterlockingModel
from railsim.engine.extensions.junction_coordinator.tracking import PlannedTrain

if TYPE_CHECKING:  # pragma: no cover
    from railsim.engine.extensions.context import ExtensionContext
    from railsim.engine.settings import EngineSettings


def switch_interval_s(
    settings: EngineSettings, members: Iterable[PlannedTrain], p: JunctionParams, throw_s: float, length_m: float
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


def safe_gap_m(ctx: ExtensionContext, train_ids: list[str], speed_mps: float) -> float:
    """The gap the followers' own coupled controller holds at ``speed_mps`` behind an equally fast leader.

    *Reading:* the planner's ``S_0`` (standstill part of ``S_m``, spec §6 #5) is raised to this gap, so that the
    planned slots at F are ones the engine's relative-braking-distance safety cap lets the trains take; with
    the spec's ``S_0`` = 10 m the guard holds followers ~8 m further back than planned (measured in SUMO) and
    no platoon meets Eq. 2 (``|D − S_m| ≤ 5 m``). The controller is asked, not re-derived: one ``command`` on a
    synthetic observation (leader at equal speed, message age = the t2t delay's mean) returns its target.
    """
    gaps = [0.0]
    ch = ctx.channels.get("t2t")
    age = float(ch.delay.mean_delay_s) if ch is not None else 0.1
    for tid in train_ids:
        tr = ctx.trains[tid]
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
            dt_s=ctx.dt_s,
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


def engine_corrected_params(
    ctx: ExtensionContext, train_ids: list[str], p: JunctionParams, given: dict[str, Any]
) -> JunctionParams:
    """The planner model with the followers' relative-braking-distance guard switched on (``qp_order``).

    *Reading:* the guard's numbers are the coupled controller's own — its safety margin, the leader's and the
    follower's emergency braking (the smaller of the planned trains'), and a dead time of the control step plus
    the t2t message age (the guard extrapolates the leader over the age). Fields the scenario gives win.
    """
    margins, decels = [], []
    for tid in train_ids:
        tr = ctx.trains[tid]
        decels.append(tr.trip.vehicle.emergency_decel_mps2)
        ctl = tr.controllers.get("coupled")
        margin = getattr(getattr(ctl, "params", None), "safety_margin_m", None)
        if margin is not None:
            margins.append(float(margin))
    ch = ctx.channels.get("t2t")
    age = float(ch.delay.mean_delay_s) if ch is not None else 0.1
    values = {
        "rbd_reaction_s": ctx.dt_s + age,
        "rbd_decel_mps2": min(decels),
        "rbd_margin_m": max(margins, default=10.0),
    }
    values = {k: v for k, v in values.items() if k not in given}
    return dataclasses.replace(p, **values)


def interlocking_model(
    ctx: ExtensionContext, train_ids: list[str], turnout_m: float, length_m: float, throw_s: float
) -> InterlockingModel:
    """The engine's switch rule in the planner's distances (``qp_order``; see :class:`InterlockingModel`).

    The lock is released when the leader's rear is ``clearance_m`` past the switch point: its front has then run
    ``turnout + L + clearance`` past the planner's switch point (the turnout start). A train without the lock
    has its authority end ``protection_margin_m`` before the switch point and its ATO aims ``authority_margin_m``
    short of that, braking at ``b_plan`` (the ATO's planning deceleration); it must hold its lock before that
    braking point, one control step of reaction included.
    """
    st = ctx.settings
    ato_margins, b_plan = [5.0], []
    for tid in train_ids:
        tr = ctx.trains[tid]
        ap = getattr(tr.controllers.get("ato"), "params", None)
        if ap is not None:
            ato_margins.append(float(ap.authority_margin_m))
            b_plan.append(float(ap.planning_decel_fraction) * tr.trip.vehicle.service_decel_mps2)
        else:
            b_plan.append(tr.trip.vehicle.service_decel_mps2)
    v_max = max(ctx.trains[t].trip.vehicle.max_speed_mps for t in train_ids)
    return InterlockingModel(
        release_after_m=turnout_m + length_m + st.clearance_m,
        throw_s=throw_s,
        grant_before_m=max(st.protection_margin_m + max(ato_margins) - turnout_m, 0.0) + v_max * ctx.dt_s,
        brake_decel_mps2=min(b_plan),
    )
