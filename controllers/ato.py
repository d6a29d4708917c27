"""ATO: automatic train operation — run to the line speed, obey restrictions, stop on the mark, hold, creep.

Every train has this role (see :mod:`controllers.base`); the engine takes the minimum of its command and the
``follow`` role's. The law is a minimum over a few simple sub-laws, each returning a **net** acceleration that
is turned into the applied command with :meth:`VehicleParams.net_to_applied` (resistance and gradient
feed-forward, the same physics as the plant):

Cruise (speed tracking)
    ``a = k_v·(v_target − v)`` clipped to ``[−b_plan, traction − resistance]``, with
    ``v_target = min(line speed, v_max, restrictions under the train) − speed_margin``. With the plant's
    first-order lag τ the loop ``τ·s² + s + k_v`` is over-damped for ``k_v < 1/(4τ)`` (default 0.4 /s for
    τ = 0.5 s), so the speed approaches the target without overshoot; the margin absorbs the rest.

Speed restrictions (continuous braking curve, :mod:`controllers.braking`)
    A restriction ``[start, end)`` must be respected from the moment the **front** reaches ``start`` until
    the **rear** has cleared ``end`` (front ≥ ``end + own length``). For restrictions ahead, the constant
    deceleration needed to be at ``limit − margin`` at ``start`` is computed with the dead-time model (lag,
    jerk ramp); braking starts when that reaches the planning deceleration ``b_plan`` and follows the
    required deceleration from then on. The cruise target is also capped by the planning braking curve so the
    train settles at the restriction speed instead of re-accelerating before it.

Stopping on the mark (exact discrete predictor)
    The stop points are the station's stopping mark (clamped so that the aim is at least ``stop_tolerance``
    inside the platform window) and the end of movement authority minus ``authority_margin``. For each, the
    controller predicts with the plant's *exact* discrete recursion (lag, Euler position update, speed clamp)
    how far the train runs if it held a constant net deceleration from now on
    (:func:`controllers.braking.discrete_stop_distance_m`), and

    * starts braking when, one step from now plus the jerk ramp, braking at ``b_plan`` would no longer stop
      before the point — and, while cruise speeds the train up, when one more step of it would leave even service
      braking short;
    * from then on solves, every step, for the constant deceleration that stops the front **exactly** on the
      point (:func:`controllers.braking.discrete_required_decel_mps2`) and commands it.

    The jerk-limited ramp of the command from the present net acceleration ``a0`` down to ``−b`` lasts
    ``(a0 + b)/J``; it counts as the dead-time model's half-ramp dead time (:mod:`controllers.braking`): ``a0``
    held for ``(a0 + b)/(2J)``, the exact sum from the speed reached then, both for the onset and for the
    deceleration solved. From full traction that ramp runs about as far as the braking after it (``v·(a0 + b)²
    /(2·b·J)``, ``(a0 + b)/b`` times the ramp's run at the present speed, which is all a train cruising at zero net
    acceleration needs), and more on a downhill grade, where ``b`` is smaller.

    Because the prediction is the plant's own difference equation at the observation's ``dt``, the stop is
    exact up to the resistance change during braking and the jerk ramp at the onset, and both are corrected by
    re-solving every step (receding horizon) — this is what keeps the stopping error well inside ±0.5 m at
    dt = 0.1, 0.5 and 1.0 s with a 0.5 s actuator lag. ``b_plan`` (default 0.8 × service braking, reduced on
    downhill gradients) leaves headroom for those corrections. Braking stays engaged while the train is
    already braking and the required deceleration is at least ``release_fraction × b_plan``; this hysteresis
    keeps cruise and stop laws from alternating when the onset overshoots the plan slightly.

Holding and creeping
    The train holds (a brake command of ``hold_decel``) while ``next_stop.dwelling`` is true, while it stands
    in the platform window (never short of it: SUMO registers no stop there; arrival is registered by SUMO about a second after the halt; the engine advances
    ``next_stop`` when the dwell is over and the departure time ``departure_not_before_s`` has passed), and
    while it stands on a stop point. A train standing short of a stop point (e.g. held by the train ahead) with
    less than ``creep_zone_m`` to go moves up at ``creep_speed`` and stops precisely as above.

If even service braking cannot stop the train before the authority end itself, the command is emergency
braking (``emergency=True``).

Other position updates
    The predictor's sum is SUMO's default Euler update (``x += dt·v_new``). A plant that moves by
    ``dt·(v + v_new)/2`` (ballistic) or ``dt·v`` (the papers' explicit Euler, "forward") runs farther while
    braking to a stop by exactly ``lead·dt·v`` (``lead`` = 1/2 or 1; ``v`` the speed now): the sums differ by
    their first term only, since the last speed is 0. The engine tells the law which update SUMO and the plant
    use (:meth:`Ato.use_position_update`), and every distance to a stop point (and to the end of authority for
    the emergency check) is shortened by that lead. Without it a forward-Euler train at dt = 1 s overran its
    stopping window and the end of its authority by up to one step's run.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from controllers import line_kernels
from controllers.base import Command, Observation, SpeedLimit, register
from controllers.braking import params_from_mapping, require
from railsim.physics.vehicle import VehicleParams

NO_STOP = (0.0, 0.0, 0.0, False)  # the kernel's stop arguments when there is no next stop (it does not read them)
# How far a step's position update runs ahead of Euler's ``dt·v_new``, in steps of the speed now (docstring)
POSITION_LEAD = {"euler": 0.0, "ballistic": 0.5, "forward": 1.0}
# Restriction tuples as kernel arrays, by identity (the route views hand out the same window tuples step after step;
# the tuple is kept in the entry so its id cannot be reused while cached).
_LIMIT_ARRAYS: dict[int, tuple[tuple[SpeedLimit, ...], np.ndarray]] = {}


def limits_array_cached(limits: tuple[SpeedLimit, ...]) -> np.ndarray:
    """``limits`` as the kernels' ``(n, 3)`` array, remembered by the tuple's identity (see above)."""
    entry = _LIMIT_ARRAYS.get(id(limits))
    if entry is not None and entry[0] is limits:
        return entry[1]
    if len(_LIMIT_ARRAYS) > 4096:  # formations' extended restrictions are new tuples every step
        _LIMIT_ARRAYS.clear()
    arr = line_kernels.limits_array(limits)
    _LIMIT_ARRAYS[id(limits)] = (limits, arr)
    return arr


@dataclass(frozen=True)
class AtoParams:
    """ATO tuning; defaults suit a metro (cq3_6car)."""

    speed_margin_mps: float = 0.3  # run this far below a line speed or restriction [m/s]
    speed_gain_per_s: float = 0.4  # k_v of the speed tracking law [1/s]
    planning_decel_fraction: float = 0.8  # b_plan as a fraction of service braking [-]
    release_fraction: float = 0.5  # keep braking while required ≥ this × b_plan [-]
    max_accel_mps2: float = math.inf  # comfort cap on the applied traction [m/s²] (inf: traction envelope)
    authority_margin_m: float = 5.0  # stop this far before the end of movement authority [m]
    stop_tolerance_m: float = 0.5  # "on the mark" and minimum aim inside the platform window [m]
    creep_speed_mps: float = 1.0  # speed to move up when standing short of a stop point [m/s]
    creep_zone_m: float = 30.0  # creeping applies when the stop point is closer than this [m]
    hold_decel_mps2: float = 0.5  # brake command while holding at a standstill [m/s²]

    def __post_init__(self) -> None:
        require("speed_margin_mps", self.speed_margin_mps >= 0.0, "a number >= 0", self.speed_margin_mps)
        require("speed_gain_per_s", self.speed_gain_per_s > 0.0, "a number > 0", self.speed_gain_per_s)
        require(
            "planning_decel_fraction",
            0.0 < self.planning_decel_fraction <= 1.0,
            "a number in (0, 1]",
            self.planning_decel_fraction,
        )
        require("release_fraction", 0.0 < self.release_fraction < 1.0, "a number in (0, 1)", self.release_fraction)
        require("max_accel_mps2", self.max_accel_mps2 > 0.0, "a number > 0", self.max_accel_mps2)
        require("authority_margin_m", self.authority_margin_m >= 0.0, "a number >= 0", self.authority_margin_m)
        require("stop_tolerance_m", self.stop_tolerance_m > 0.0, "a number > 0", self.stop_tolerance_m)
        require("creep_speed_mps", self.creep_speed_mps > 0.0, "a number > 0", self.creep_speed_mps)
        require("creep_zone_m", self.creep_zone_m >= 0.0, "a number >= 0", self.creep_zone_m)
        require("hold_decel_mps2", self.hold_decel_mps2 > 0.0, "a number > 0", self.hold_decel_mps2)


class Ato:
    """The ATO law for one train (stateless between calls: the same observation gives the same command)."""

    def __init__(self, params: AtoParams, vehicle: VehicleParams) -> None:
        require(
            "hold_decel_mps2",
            params.hold_decel_mps2 <= vehicle.service_decel_mps2,
            f"a number <= the service deceleration {vehicle.service_decel_mps2}",
            params.hold_decel_mps2,
        )
        self.params = params
        self.vehicle = vehicle
        self._packed = np.zeros(0)  # the kernel's packed inputs for the vehicle and dt last seen
        self._packed_vehicle: VehicleParams | None = None
        self._packed_dt = math.nan
        self.position_lead = 0.0  # lead of the plant's position update over Euler (module docstring)

    def use_position_update(self, step_method: str) -> None:
        """How the plant (and SUMO) move a train's position in a step: ``euler`` (``x += dt·v_new``, what the
        stop predictor sums), ``ballistic`` or ``forward`` (module docstring, "Other position updates")."""
        lead = POSITION_LEAD.get(step_method)
        if lead is None:
            raise ValueError(f"unknown step method {step_method!r} (one of {', '.join(POSITION_LEAD)})")
        if lead != self.position_lead:
            self.position_lead = lead
            self._packed_vehicle = None  # pack again with the new lead

    def reset(self) -> None:
        """Nothing to forget: the law keeps no state."""

    def command(self, obs: Observation) -> Command:
        own = obs.own
        stop = obs.next_stop
        accel, emergency, phase = self.decide(
            obs.vehicle,
            obs.dt_s,
            own.position_m,
            own.speed_mps,
            own.accel_mps2,
            own.length_m,
            own.gradient_permille,
            obs.line_speed_mps,
            obs.speed_limits,
            None if stop is None else (stop.mark_m, stop.window_start_m, stop.window_end_m, stop.dwelling),
            obs.authority_end_m,
        )
        return Command(accel, emergency=emergency, info={"phase": phase})

    def decide(
        self,
        veh: VehicleParams,
        dt: float,
        x: float,
        speed_mps: float,
        applied_now: float,
        length_m: float,
        grade: float,
        line_speed_mps: float,
        speed_limits: tuple[SpeedLimit, ...],
        stop: tuple[float, float, float, bool] | None,
        authority_end_m: float | None,
        tail_m: float = 0.0,
    ) -> tuple[float, bool, str]:
        """The law on plain values: ``(applied acceleration, emergency, phase)``; :meth:`command` is this on an
        observation. The engine calls it directly for a train whose ATO is this class (no observation built).
        ``stop`` is the next stop as ``(mark_m, window_start_m, window_end_m, dwelling)``, or None. ``tail_m`` > 0:
        the train leads a formation that long behind it, and every restriction's end moves on by it (it holds
        until the formation's rear clears).

        The law itself is :func:`controllers.line_kernels.ato`, written once and compiled; this packs its inputs."""
        packed = self._packed
        if veh is not self._packed_vehicle or dt != self._packed_dt:
            packed = self._pack(veh, dt)
        accel, emergency, phase = line_kernels.ato(
            packed,
            x,
            speed_mps,
            applied_now,
            length_m,
            grade,
            line_speed_mps,
            limits_array_cached(speed_limits),
            stop is not None,
            *(stop if stop is not None else NO_STOP),
            authority_end_m is not None,
            authority_end_m if authority_end_m is not None else 0.0,
            tail_m,
        )
        return accel, emergency, line_kernels.ATO_PHASES[phase]

    def packed(self, veh: VehicleParams, dt: float) -> np.ndarray:
        """The law's inputs for ``veh`` and step ``dt`` as :func:`controllers.line_kernels.ato` reads them (for a
        caller that runs the kernel inside its own compiled loop: ``railsim.engine.free_run_kernel``)."""
        if veh is not self._packed_vehicle or dt != self._packed_dt:
            return self._pack(veh, dt)
        return self._packed

    def _pack(self, veh: VehicleParams, dt: float) -> np.ndarray:
        self._packed = line_kernels.pack(line_kernels.ATO_FIELDS, veh, self.params, dt, (self.position_lead * dt,))
        self._packed_vehicle, self._packed_dt = veh, dt
        return self._packed


@register("ato")
def make_ato(params: Mapping[str, Any], vehicle: VehicleParams) -> Ato:
    """Factory for scenarios: ``controllers: {ato: {type: ato, speed_margin_mps: 0.5}}``."""
    return Ato(params_from_mapping(AtoParams, params), vehicle)
