"""Can the Line 3 Bijin down pair couple on the run, before its leader stands at Bijin? Closed form and planner.

The down Airport unit (leader, normal leg) and the Jurenba unit (follower, diverging leg) meet at ``bijin_down``;
the leader must stop at Bijin. The geometry is read from the world (``chongqing_line3``: the pair of
``scenarios/chongqing_line3_peak_merge.yaml``): the switch point, the 50 m / 30 km/h turnout zone on the branch leg,
the platform window and the leader's halt position, the units (89.4 m, service braking 1.11 m/s²), the engine's
interlocking (clearance 10 m, protection 20 m, the ATO's 5 m authority margin and 0.8 planning share of service
braking) and the 15 s throw. Distances ``x`` below are the leader's front past the switch point.

Closed form
    * *Leader on its ATO profile* (no planner): it passes the point at the line speed less the ATO margin, brakes
      at its planning rate for its halt, and stands ``t_halt`` after passing the point; the follower may pass the
      point only after the release (rear ``clearance`` past the point) and one throw: ``t_release + throw``. If
      that exceeds ``t_halt`` the leader stands before the follower is even on the trunk.
    * *Leader slowing early* (any plan): hold the leader at ``u`` from its release on. When the follower's lock is
      granted (one throw after the release) the leader's front is at ``L + clearance + throw·u`` and the follower's
      front at least ``protection + authority margin + v_max·dt + v₀²/(2 b_plan)`` before the point (it must hold
      the lock before braking for the end of its authority). It closes to ``target gap`` behind the leader at the
      turnout limit at most (ATO margin off), accelerating at ``a_max`` and braking at ``b_plan``, then both run
      5 s at ``u`` (the coupled state) and the leader brakes for its halt. :func:`slowest_catch_up` gives the
      least leader travel for each ``u``; the largest ``u`` whose travel fits before the halt (and before the
      platform start) is reported.

Planner
    ``qp_order`` (:mod:`controllers.junction.qp`) with the engine's model, as the online coordinator builds it
    (:mod:`railsim.engine.extensions.junction_coordinator.readings`: the exact interlocking rule, the RBD guard of
    the coupled controller, the turnout zone over the unit's length, the ATO's envelope), the passing order fixed
    leader first (the formation's), the planner's switch at the turnout start, its coupling point F at ``x_F``.
    Behind F the plan holds the coupled speed ``v_c``; the engine's coupled state needs 5 s of it and the leader
    must then still stop at its halt: a feasible plan counts only if ``x_F + 5 v_c + v_c²/(2 b_plan) ≤ x_halt``
    ("before the halt"), or ``x_F + 5 v_c ≤ x_platform`` ("before the platform"). Initial states: the leader 800 m
    before the point at 16 m/s, the follower 0-40 s of its free run behind it. Every first plan's CPU time
    (``time.process_time``) is recorded; median/p95/max over all of them, over the feasible ones and over those
    that couple before the halt are reported (an infeasible plan spends the whole QP budget, 30 QPs). Then the thresholds: the least
    merge-to-platform distance, and the largest throw time, at which the pair couples before the platform.

Prints one JSON object:

    .venv/bin/python benchmarks/bijin_merge_feasibility.py
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from controllers.junction.model import JunctionParams  # noqa: E402
from controllers.junction.planner import (  # noqa: E402
    TrainState,
    YJunctionLayout,
    build_problem,
    decode,
    solve,
)
from controllers.junction.qp import InterlockingModel, QpOrderParams  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "chongqing_line3_peak_merge.yaml"
HOLD_S = 5.0  # the formation state machine's coupled state: gap and speeds within tolerance this long
F_GRID_M = tuple(range(100, 272, 10))
FOLLOWER_BEHIND_S = (0.0, 10.0, 20.0, 30.0, 40.0)


@dataclass(frozen=True)
class Geometry:
    """The Bijin down merge as the engine sees it (distances past the switch point, leader's front)."""

    length_m: float
    turnout_m: float
    turnout_speed_mps: float
    line_speed_mps: float
    platform_start_m: float
    halt_m: float
    throw_s: float
    clearance_m: float
    protection_m: float
    authority_margin_m: float
    speed_margin_mps: float
    b_plan_mps2: float
    a_max_mps2: float
    v_max_mps: float
    dt_s: float
    emergency_decel_mps2: float
    target_gap_m: float


def read_geometry() -> Geometry:
    """The pair of the peak-merge scenario, built by the engine (no SUMO started)."""
    from railsim.engine.loop import Simulation
    from railsim.scenario.loading import loads

    data = yaml.safe_load(SCENARIO.read_text())
    services = {s["id"]: s for s in data["services"]}
    lead, follow = services["airport_down_vc"], services["jurenba_down"]
    lead.update(to="huixing", departures={"times": [900]})
    follow.update(to="huixing")
    data["services"] = [lead, follow]
    merge = next(f for f in data["formations"] if f["id"] == "merge")
    data["formations"] = [merge]
    sim = Simulation(loads(yaml.safe_dump(data), str(SCENARIO), SCENARIO.parent), None)
    leader, follower = sim.trains["airport_down_vc.000"], sim.trains["jurenba_down.000"]
    sw = merge["couple"]["after_switch"]
    point_l = next(rs.point_m for rs in leader.trip.route.switches if rs.switch_id == sw)
    point_f = next(rs.point_m for rs in follower.trip.route.switches if rs.switch_id == sw)
    bijin = next(s for s in leader.trip.stops if s.station_id == "bijin")
    zone = next((a, v) for a, b, v in follower.trip.route.speed_limits if a < point_f <= b + 0.5)
    veh = leader.trip.vehicle
    ato = leader.controllers["ato"].params
    traction = veh.traction_max_force_n - veh.davis_a_n
    return Geometry(
        length_m=veh.length_m,
        turnout_m=point_f - zone[0],
        turnout_speed_mps=zone[1],
        line_speed_mps=leader.view.line_speed_mps,
        platform_start_m=bijin.window_start_m - point_l,
        halt_m=bijin.mark_m - point_l,
        throw_s=float(sim.bundle.switches[sw].throw_time_s),
        clearance_m=sim.settings.clearance_m,
        protection_m=sim.settings.protection_margin_m,
        authority_margin_m=ato.authority_margin_m,
        speed_margin_mps=ato.speed_margin_mps,
        b_plan_mps2=ato.planning_decel_fraction * veh.service_decel_mps2,
        a_max_mps2=round(traction / (veh.mass_kg * veh.rotating_mass_factor), 2),
        v_max_mps=veh.max_speed_mps,
        dt_s=sim.dt,
        emergency_decel_mps2=veh.emergency_decel_mps2,
        target_gap_m=float(merge["target_gap_m"]),
    )


# ---------------------------------------------------------------------------------------------- closed form
def ato_approach(g: Geometry) -> dict[str, float]:
    """The leader on its ATO profile: from the point to standing, and the follower's earliest passage."""
    v = g.line_speed_mps - g.speed_margin_mps
    brake_m = v * v / (2.0 * g.b_plan_mps2)
    cruise_m = max(g.halt_m - brake_m, 0.0)
    if cruise_m > 0.0:
        t_halt = cruise_m / v + v / g.b_plan_mps2
    else:  # already braking at the point
        v = math.sqrt(2.0 * g.b_plan_mps2 * g.halt_m)
        t_halt = v / g.b_plan_mps2
    release_m = g.length_m + g.clearance_m
    # time to run release_m from the point on the same profile
    if release_m <= cruise_m:
        t_release = release_m / v
    else:
        left = g.halt_m - release_m  # distance still to run when released, braking: v_r² = 2 b left
        t_release = t_halt - math.sqrt(2.0 * left / g.b_plan_mps2)
    return {
        "leader_speed_at_point_mps": round(v, 2),
        "leader_point_to_standing_s": round(t_halt, 1),
        "release_after_point_s": round(t_release, 1),
        "follower_earliest_passage_s": round(t_release + g.throw_s, 1),
    }


def slowest_catch_up(g: Geometry, u: float) -> tuple[float, float]:
    """Least leader travel from its release (front at ``L + clearance``) to the end of the 5 s coupled state when
    it runs at ``u`` from the release on, over the follower's speed ``v₀`` at the grant; and that ``v₀``."""
    v_lim = g.turnout_speed_mps - g.speed_margin_mps
    a, b = g.a_max_mps2, g.b_plan_mps2
    best = (math.inf, math.nan)
    for v0 in np.linspace(0.5, v_lim, 60):
        x_f0 = -(g.protection_m + g.authority_margin_m + g.v_max_mps * g.dt_s + v0 * v0 / (2.0 * b))
        x_l0 = g.length_m + g.clearance_m + g.throw_s * u
        close_m = x_l0 - (g.length_m + g.target_gap_m) - x_f0  # the follower's front must gain this on the leader
        if close_m <= 0.0:
            continue
        # fastest catch-up: accelerate from v0 to vp (≤ v_lim), brake to u; relative distance gained vs time
        t_best = math.inf
        for vp in np.linspace(max(v0, u), v_lim, 40):
            d_acc = (vp * vp - v0 * v0) / (2.0 * a)
            d_dec = (vp * vp - u * u) / (2.0 * b)
            t_acc, t_dec = (vp - v0) / a, (vp - u) / b
            gained = d_acc + d_dec - u * (t_acc + t_dec)
            if gained > close_m + 1e-9:
                continue  # too fast a peak: shorten it (a lower vp is tried too)
            cruise_gain = vp - u
            if cruise_gain <= 1e-9:
                continue
            t = t_acc + t_dec + (close_m - gained) / cruise_gain
            t_best = min(t_best, t)
        if not math.isfinite(t_best):
            continue
        travel = g.throw_s * u + u * (t_best + HOLD_S)
        if travel < best[0]:
            best = (travel, float(v0))
    return best


def closed_form(g: Geometry) -> dict[str, Any]:
    """Largest leader speed from its release on at which the pair can couple before the halt / the platform."""
    release_m = g.length_m + g.clearance_m
    rows, u_halt, u_platform = [], 0.0, 0.0
    for u in np.arange(0.5, g.turnout_speed_mps, 0.25):
        travel, v0 = slowest_catch_up(g, float(u))
        end_m = release_m + travel  # leader's front when the 5 s coupled state is complete
        fits_halt = end_m + u * u / (2.0 * g.b_plan_mps2) <= g.halt_m
        fits_platform = end_m <= g.platform_start_m
        if fits_halt:
            u_halt = float(u)
        if fits_platform:
            u_platform = float(u)
        rows.append({"u_mps": float(u), "coupled_at_m": round(end_m, 1), "follower_speed_at_grant_mps": round(v0, 2)})
    return {
        "ato_approach": ato_approach(g),
        "largest_leader_speed_coupling_before_halt_mps": u_halt,
        "largest_leader_speed_coupling_before_platform_mps": u_platform,
        "by_leader_speed": rows[::4],
    }


# ---------------------------------------------------------------------------------------------- planner
def planner_model(g: Geometry, throw_s: float) -> tuple[JunctionParams, QpOrderParams]:
    """``qp_order``'s model of the merge with the engine's numbers (as the online coordinator derives them)."""
    il = InterlockingModel(
        release_after_m=g.turnout_m + g.length_m + g.clearance_m,
        throw_s=throw_s,
        grant_before_m=max(g.protection_m + g.authority_margin_m - g.turnout_m, 0.0) + g.v_max_mps * g.dt_s,
        brake_decel_mps2=g.b_plan_mps2,
    )
    qp = QpOrderParams(
        zone_m=g.turnout_m + g.length_m,
        approach_decel_mps2=0.5 * g.b_plan_mps2,
        approach_hold_m=20.0,
        line_speed_margin_mps=3.0,
        interlocking=il,
    )
    v_lsn, v_lsr = g.line_speed_mps, g.turnout_speed_mps
    # the coordinator's t_ls (readings.switch_interval_s) with these speeds and the ATO's planning braking
    t_ls = (
        (g.turnout_m + g.length_m + g.clearance_m) / v_lsr
        + throw_s
        + (v_lsn**2 / (2 * g.b_plan_mps2) + g.protection_m) / v_lsn
    )
    p = JunctionParams(
        accel_min_mps2=-g.b_plan_mps2,
        accel_max_mps2=g.a_max_mps2,
        normal_speed_mps=v_lsn,
        reverse_speed_mps=v_lsr,
        line_speed_mps=v_lsn,
        throw_time_s=t_ls,
        pred_length_m=g.length_m,
        standstill_gap_m=g.target_gap_m,
        gap_tolerance_m=2.0,  # the state machine's coupled state
        speed_tolerance_mps=0.3,
        switch_speed_margin_mps=g.speed_margin_mps,
        comm_delay_s=0.2,
        processing_delay_s=0.0,
        rbd_reaction_s=g.dt_s + 0.2,
        rbd_decel_mps2=g.emergency_decel_mps2,
        rbd_margin_m=10.0,
    )
    return p, qp


def plan_once(g: Geometry, x_F: float, behind_s: float, throw_s: float) -> dict[str, Any]:
    """One first plan, leader first, F at ``x_F`` past the point; the follower ``behind_s`` of free run behind."""
    p, qp = planner_model(g, throw_s)
    layout = YJunctionLayout(S4_m=200.0, S5_m=x_F + g.turnout_m, sw2_branch_leg="reverse")
    d0, v0 = 800.0, 16.0
    trains = [TrainState("leader", "trunk", d0, v0), TrainState("follower", "entry1", d0 + behind_s * v0, v0)]
    t0 = time.process_time()
    problem = build_problem(trains, (), layout, p, frozen_order=("leader", "follower"))
    res = solve(problem, "qp_order", qp=qp)
    pl = decode(problem, res.x, "qp_order", res.iterations, res.wall_time_s, converged=res.converged)
    cpu_s = time.process_time() - t0
    v_c = pl.coupled_speed_mps
    held_end_m = x_F + HOLD_S * v_c
    return {
        "x_F_m": x_F,
        "behind_s": behind_s,
        "feasible": bool(pl.feasible),
        "v_c_mps": round(v_c, 2),
        "before_halt": bool(pl.feasible and held_end_m + v_c * v_c / (2 * g.b_plan_mps2) <= g.halt_m),
        "before_platform": bool(pl.feasible and held_end_m <= g.platform_start_m),
        "coupled_by_m": round(held_end_m, 1),
        "cpu_s": cpu_s,
        "violations": {k: round(v, 2) for k, v in pl.violations.items() if v > 1e-3},
    }


def _stats(cpu: np.ndarray) -> dict[str, float]:
    if cpu.size == 0:
        return {}
    return {
        "n": int(cpu.size),
        "median": round(float(np.median(cpu)), 4),
        "p95": round(float(np.percentile(cpu, 95)), 4),
        "max": round(float(cpu.max()), 4),
    }


def planner_study(g: Geometry) -> dict[str, Any]:
    rows = [plan_once(g, float(x), b, g.throw_s) for x in F_GRID_M for b in FOLLOWER_BEHIND_S]
    ok_halt = [r for r in rows if r["before_halt"]]
    ok_plat = [r for r in rows if r["before_platform"]]
    cpu = np.array([r["cpu_s"] for r in rows])
    # thresholds: the least merge-to-platform distance (the earliest coupled state over all feasible plans) and
    # the largest throw time at which some plan couples before the real platform start
    least_platform_m = min((r["coupled_by_m"] for r in rows if r["feasible"] and r["before_halt"]), default=math.nan)
    throws = []
    for throw in np.arange(g.throw_s, -0.01, -1.0):
        hit = [
            r
            for x in range(60, int(g.platform_start_m) + 1, 10)
            for r in [plan_once(g, float(x), 20.0, float(throw))]
            if r["before_platform"]
        ]
        throws.append({"throw_s": float(throw), "couples_before_platform": bool(hit)})
        if hit:
            break
    return {
        "plans": len(rows),
        "feasible": sum(r["feasible"] for r in rows),
        "before_halt": len(ok_halt),
        "before_platform": len(ok_plat),
        "least_x_F_before_halt_m": min((r["x_F_m"] for r in ok_halt), default=None),
        "least_merge_to_platform_m_for_coupling_before_it": least_platform_m,
        "throw_sweep_F_before_platform_follower_20s": throws,
        "first_plan_cpu_s": _stats(cpu),
        "first_plan_cpu_s_feasible_plans": _stats(np.array([r["cpu_s"] for r in rows if r["feasible"]])),
        "first_plan_cpu_s_before_halt_plans": _stats(np.array([r["cpu_s"] for r in ok_halt])),
        "rows_before_halt": [{k: r[k] for k in ("x_F_m", "behind_s", "v_c_mps", "coupled_by_m")} for r in ok_halt],
        "rows_infeasible_sample": [
            {k: r[k] for k in ("x_F_m", "behind_s", "violations")} for r in rows if not r["feasible"]
        ][:10],
    }


def main() -> None:
    g = read_geometry()
    out = {
        "geometry": g.__dict__,
        "closed_form": closed_form(g),
        "planner": planner_study(g),
        "load_average": list(__import__("os").getloadavg()),
    }
    print(json.dumps(out, indent=1, default=float))


if __name__ == "__main__":
    main()
