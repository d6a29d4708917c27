"""Analytic headway floors: the minimum headway a separation rule allows, from closed forms, beside a simulation.

A rail planner checks a simulated minimum headway against the **blocking-time / braking-distance floor**: the
time one path occupies the critical station. This module computes that floor for the two separation rules of
``railsim study vc-vs-mb`` and for the service patterns the study runs.

**Station headway of one path (moving block, "brick wall").** A leader of length ``L`` departs a platform from
rest; the follower approaches at line speed ``v`` and brakes at the service deceleration ``b`` to the same
stopping mark. Moving block lets the follower's front be at most its braking distance
``S(v) = v·T + v²/(2b)`` plus the margin behind the leader's rear (``T`` = the separation controller's dead time:
reaction + message age + control step + actuator lag + half the jerk ramp, :mod:`controllers.separation`). The
follower is on its braking curve to the mark, so the leader's rear must have cleared the mark by
``L + margin + v·T`` when the follower starts braking, and the constraint binds exactly then (before, the leader
gains distance on a cruising follower only once it is faster than ``v``; after, the follower's own dead-time term
shrinks). With ``t_clear(d)`` the time the leader needs from rest to cover ``d``::

    H(L) = dwell + t_clear(L + margin + v·T) + v/b

For a constant acceleration ``a`` reached before ``v`` this is the closed form
``H = dwell + √(2·(L + margin + v·T)/a) + v/b`` (and ``(L + margin + v·T)/v + v/(2a) + v/b`` when the leader reaches
``v`` first). :func:`station_headway_s` integrates ``t_clear`` from the vehicle's traction curve (tractive effort
``F0`` up to the power limit ``P/v``, Davis resistance, rotating mass) in steps of ``dt_s``; with a constant
force and no resistance it reproduces the closed form within one step (a test checks).

**A virtually coupled formation** stands at the platform as one path of length ``L₁ + g + L₂`` (``g`` the target
gap at standstill) and departs together (relative braking keeps the follower ``g`` behind at the start; its lag
behind the leader, the t2t message age plus one step, is added). Inside the formation relative braking replaces
the absolute braking distance; behind the formation the next train keeps absolute braking distance, so the
formation's floor is ``H(L₁ + g + L₂) + lag``.

**A service pattern.** The study searches the headway ``h`` of a reference service R (the Airport units) while a
dependent service D departs relative to it (one D unit per ``N`` R units, ``departures: {after: ...}``). At a
station both serve, one cycle of ``N·h`` carries ``N`` R paths and, unless the D unit runs coupled there, one D path:

* **strict floor** (no train is ever held): every gap holds one path, the D unit sits in one R gap —
  ``h ≥ 2·H(L)`` (independent D unit) or ``h ≥ H(formation)`` (coupled);
* **cycle floor** (delays absorbed within the cycle, the sustained capacity): ``N·h ≥ Σ paths`` —
  ``h ≥ (N + 1)·H(L)/N`` independent, ``h ≥ ((N − 1)·H(L) + H(formation))/N`` coupled.

The simulated minimum lies above the cycle floor; between the two floors a feasible headway holds trains back
(bounded by the delay threshold); the study prints both, the critical station and the simulated/floor ratio.
What the floors leave out (so the simulation is above them): the ATO's comfort braking and speed margins, the
separation controller's barrier (``v/γ`` of extra distance), dwell extensions, switch throw and lock times.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

_CLEAR_DT_S = 0.05  # integration step of the leader's departure [s]


@dataclass(frozen=True)
class Traction:
    """What the floor needs of a vehicle: the departure curve and the service braking."""

    mass_kg: float  # effective (rotating) mass
    force_n: float  # tractive effort at low speed F0
    power_w: float  # power limit P (math.inf: none)
    davis_n: tuple[float, float, float]  # A [N], B [N/(m/s)], C [N/(m/s)²]
    decel_mps2: float  # service braking b (positive)
    length_m: float

    @classmethod
    def of(cls, vehicle: Any) -> Traction:
        """From :class:`railsim.physics.vehicle.VehicleParams`."""
        return cls(
            mass_kg=float(vehicle.mass_kg) * float(vehicle.rotating_mass_factor),
            force_n=float(vehicle.traction_max_force_n),
            power_w=float(vehicle.traction_max_power_w),
            davis_n=(float(vehicle.davis_a_n), float(vehicle.davis_b_n_per_mps), float(vehicle.davis_c_n_per_mps2)),
            decel_mps2=float(vehicle.service_decel_mps2),
            length_m=float(vehicle.length_m),
        )

    def accel_mps2(self, v_mps: float) -> float:
        """Net acceleration from rest at full traction [m/s²] at speed ``v_mps``."""
        force = self.force_n if v_mps <= 0 else min(self.force_n, self.power_w / v_mps)
        a, b, c = self.davis_n
        return (force - (a + b * v_mps + c * v_mps * v_mps)) / self.mass_kg


def clear_time_s(tr: Traction, line_mps: float, distance_m: float, dt_s: float = _CLEAR_DT_S) -> float:
    """Time a train starting from rest at full traction (capped at ``line_mps``) needs to cover ``distance_m``.

    Explicit integration in steps of ``dt_s`` (speed updated first, the step's distance at the new speed), the
    crossing step interpolated linearly. ValueError if the train cannot reach the distance (traction below
    resistance)."""
    if distance_m <= 0.0:
        return 0.0
    t = x = v = 0.0
    while True:
        a = tr.accel_mps2(v)
        if v < line_mps and a <= 0.0:
            raise ValueError(f"the train cannot accelerate at {v:.1f} m/s (traction below resistance)")
        v_new = min(line_mps, v + max(a, 0.0) * dt_s)
        step = v_new * dt_s
        if x + step >= distance_m:
            return t + dt_s * (distance_m - x) / step
        t, x, v = t + dt_s, x + step, v_new
        if t > 1e5:
            raise ValueError("the train does not reach the distance in 1e5 s")


def station_headway_s(
    tr: Traction,
    *,
    line_mps: float,
    dwell_s: float,
    margin_m: float,
    dead_time_s: float,
    length_m: float | None = None,
    dt_s: float = _CLEAR_DT_S,
) -> float:
    """``H(L) = dwell + t_clear(L + margin + v·T) + v/b`` (module docstring); ``length_m`` defaults to the
    vehicle's (a formation passes its whole length)."""
    length = tr.length_m if length_m is None else length_m
    return (
        dwell_s
        + clear_time_s(tr, line_mps, length + margin_m + line_mps * dead_time_s, dt_s)
        + line_mps / (tr.decel_mps2)
    )


def closed_form_headway_s(
    *,
    length_m: float,
    margin_m: float,
    line_mps: float,
    dead_time_s: float,
    accel_mps2: float,
    decel_mps2: float,
    dwell_s: float,
) -> float:
    """The closed form of :func:`station_headway_s` for a constant acceleration ``accel_mps2`` (module docstring)."""
    d = length_m + margin_m + line_mps * dead_time_s
    t_reach = line_mps / accel_mps2
    t_clear = math.sqrt(2.0 * d / accel_mps2)
    if t_clear > t_reach:  # line speed reached first: cruise the rest
        t_clear = (d - 0.5 * accel_mps2 * t_reach**2) / line_mps + t_reach
    return dwell_s + t_clear + line_mps / decel_mps2


# --------------------------------------------------------------------------------------------------------------
# Floors of a scenario's pattern
# --------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class StationFloor:
    """The floor at one station of the reference service's route."""

    station: str
    line_kmh: float
    dwell_s: float
    path_s: float  # H(L): one independent unit
    formation_s: float | None  # H(formation) + lag where the dependent unit runs coupled, else None
    dependent: str | None  # the dependent service stopping here, if any
    strict_s: float
    cycle_s: float


@dataclass(frozen=True)
class PatternFloor:
    """The floor of one reference service with its dependents: the critical station and both floors."""

    reference: str
    every: int
    stations: tuple[StationFloor, ...]
    dead_time_s: float
    margin_m: float
    notes: tuple[str, ...] = ()

    @property
    def critical(self) -> StationFloor:
        return max(self.stations, key=lambda s: (s.cycle_s, s.strict_s))

    @property
    def critical_strict(self) -> StationFloor:
        return max(self.stations, key=lambda s: (s.strict_s, s.cycle_s))


@dataclass(frozen=True)
class RegimeFloor:
    """Floors of every searched reference service of one scenario; the regime's floor is the largest."""

    patterns: tuple[PatternFloor, ...]
    assumptions: dict[str, Any] = field(default_factory=dict)

    @property
    def cycle_s(self) -> float:
        return max(p.critical.cycle_s for p in self.patterns)

    @property
    def strict_s(self) -> float:
        return max(p.critical_strict.strict_s for p in self.patterns)

    def binding(self, which: str = "cycle") -> tuple[PatternFloor, StationFloor]:
        """The pattern and station that set the regime's floor."""
        if which == "cycle":
            p = max(self.patterns, key=lambda p: p.critical.cycle_s)
            return p, p.critical
        p = max(self.patterns, key=lambda p: p.critical_strict.strict_s)
        return p, p.critical_strict


def _dead_time_s(scn: Any, vehicle: Any) -> tuple[float, float]:
    """(T, margin) of the scenario's separation controller: reaction + t2g message age + step + lag + ½ ramp."""
    from controllers.braking import params_from_mapping
    from controllers.separation import SeparationParams

    spec = scn.controllers[scn.roles["separation"]]
    p = params_from_mapping(SeparationParams, spec.params)
    delay = scn.faults.comm["t2g"].delay
    age = _mean_delay_s(delay)
    ramp = 0.5 * float(vehicle.service_decel_mps2) / float(vehicle.jerk_limit_mps3)
    t = p.reaction_time_s + age + scn.simulation.step_s + float(vehicle.actuator_time_constant_s) + ramp
    return t, float(p.margin_m)


def _mean_delay_s(delay: Any) -> float:
    """Mean of a :class:`railsim.scenario.model.DelaySpec` [s]."""
    p = delay.params
    if delay.dist == "constant":
        return float(p["value"])
    if delay.dist == "uniform":
        return 0.5 * (float(p["low"]) + float(p["high"]))
    return float(p["mean"])


def regime_floor(scn: Any, reference_services: tuple[str, ...] | list[str]) -> RegimeFloor:
    """The floors of ``scn`` (a :class:`railsim.scenario.Scenario`) for each searched reference service.

    For every station of the reference service's route: the line speed there (the route's speed limit at the
    stopping mark, capped by the vehicle), its dwell, ``H(L)``, and — where a service departing relative to the
    reference also stops — the strict and cycle floors of the pattern (module docstring). The dependent unit runs
    coupled where a ``pairs`` formation (an ``on_departure`` coupling) holds it: from its origin to the last stop
    before its ``before_switch`` decoupling point."""
    from network.world import load_world
    from railsim.scenario import with_station_ids

    world = load_world(scn.world, scn.source)  # built, or read from a net as it is
    scn = with_station_ids(scn, world)  # an imported net's stations may go by their names
    patterns = []
    notes_all: dict[str, Any] = {}
    for ref_id in reference_services:
        ref = scn.service(ref_id)
        veh = scn.vehicle_of(ref_id)
        tr = Traction.of(veh)
        dead_t, margin = _dead_time_s(scn, veh)
        route = world.route_between(ref.from_station, ref.to_station, ref.via)
        dependents = [
            s for s in scn.services if s.departures_after is not None and s.departures_after.service == ref_id
        ]
        coupled_at: dict[str, set[str]] = {}
        lag_s = _mean_delay_s(scn.faults.comm["t2t"].delay) + scn.simulation.step_s
        gaps: dict[str, float] = {}
        for dep in dependents:
            stations = _coupled_stations(scn, world, ref_id, dep)
            if stations:
                coupled_at[dep.id] = stations
                gaps[dep.id] = next(
                    f.target_gap_m
                    for f in scn.formations
                    if f.leader.service == ref_id and f.follower.service == dep.id
                )
        dep_routes = {
            d.id: {s.station_id for s in world.route_between(d.from_station, d.to_station, d.via).stops}
            for d in dependents
        }
        every = min((d.departures_after.every for d in dependents), default=1)
        rows = []
        for stop in route.stops[:-1]:  # the terminus is left by turning back, not by the next path through it
            st = stop.station_id
            line_mps = min(float(veh.max_speed_mps), route.speed_at(max(stop.end_m - 1.0, 0.0)))
            dwell = ref.dwell_s(st)
            h_path = station_headway_s(tr, line_mps=line_mps, dwell_s=dwell, margin_m=margin, dead_time_s=dead_t)
            dep_here = next((d for d in dependents if st in dep_routes[d.id] and st not in d.skip), None)
            h_form = None
            if dep_here is None:
                strict = cycle = h_path
            else:
                n = dep_here.departures_after.every
                if st in coupled_at.get(dep_here.id, set()):
                    dep_len = float(scn.vehicle_of(dep_here.id).length_m)
                    h_form = lag_s + station_headway_s(
                        tr,
                        line_mps=line_mps,
                        dwell_s=dwell,
                        margin_m=margin,
                        dead_time_s=dead_t,
                        length_m=tr.length_m + gaps[dep_here.id] + dep_len,
                    )
                    strict = max(h_path, h_form)
                    cycle = ((n - 1) * h_path + h_form) / n
                else:
                    strict = 2.0 * h_path
                    cycle = (n + 1) * h_path / n
            rows.append(
                StationFloor(
                    st, line_mps * 3.6, dwell, h_path, h_form, dep_here.id if dep_here else None, strict, cycle
                )
            )
        patterns.append(PatternFloor(ref_id, every, tuple(rows), dead_t, margin))
        notes_all[ref_id] = {"dead_time_s": dead_t, "margin_m": margin, "formation_lag_s": lag_s}
    return RegimeFloor(tuple(patterns), notes_all)


def _coupled_stations(scn: Any, world: Any, ref_id: str, dep: Any) -> set[str]:
    """Stations where ``dep``'s units run coupled behind ``ref_id``'s: from the follower's origin (coupling on
    departure) to the last stop before its decoupling switch (or to its destination)."""
    forms = [
        f
        for f in scn.formations
        if f.leader.service == ref_id
        and f.follower.service == dep.id
        and f.couple is not None
        and f.couple.kind == "on_departure"
    ]
    if not forms:
        return set()
    route = world.route_between(dep.from_station, dep.to_station, dep.via)
    end_m = math.inf
    dec = forms[0].decouple
    if dec is not None and dec.kind == "before_switch":
        end_m = next((s.point_m for s in route.switches if s.switch_id == dec.switch), math.inf)
    return {s.station_id for s in route.stops if s.end_m < end_m and s.station_id != dep.to_station}
