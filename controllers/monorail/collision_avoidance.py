"""Active collision avoidance (Paper D §3.2 / §3.8): sensor-triggered emergency MPC, registered as ``monorail_ca``.

The paper's CA "does not rely on V2V or vehicle-to-ground communication, and is solely triggered by the safety
distance while evaluating only the vehicle's own operating state". So this controller reads only the vehicle's
own odometry and its own ranging sensor, never ``obs.predecessor``:

``obs.extras["sensor"]`` — a mapping with
    ``distance_m``        net gap from this vehicle's front to the rear of the nearest object ahead, now [m]
                          (``inf`` or missing key: nothing in range);
    ``closing_speed_mps`` own speed minus the object's speed [m/s], > 0 when the gap shrinks;
    ``object``            ``"vehicle"`` or ``"obstacle"`` (optional, default ``"vehicle"``); an obstacle
                          latches the emergency brake until standstill (paper §3.3.3);
    ``service_accel_mps2`` optional: the service command another role is applying, for additive braking (A27).

Trigger and release (A10): on at ``gap ≤ S_trig`` (fixed 28 m, or the ADBM/RDBM distance of
:mod:`.braking_modes`) — debounced (:func:`.states.ca_should_fire`): a shallow intrusion
(``gap > S_trig − trigger_band_m``) is ignored while the own present braking already ends the closing above
``s_min_m`` (:func:`.states.braking_suffices`), otherwise it must last ``trigger_dwell_s`` and may not re-fire
within ``rearm_s`` of a release; a deep one or an obstacle fires at once; set the three to 0 for the paper's bare trigger —
off at ``gap > S_trig + release_margin_m`` after ``min_on_s`` (:func:`.states.ca_hysteresis`);
``latch = "obstacle"`` (default) holds the brake to standstill for obstacles, ``"always"``/``"never"`` force it.

While active the command is the first move of the QP of :mod:`.mpc` (Eqs 17–22): track ``d_ref`` = release
threshold + ``ref_offset_m`` and the object's speed, ``u ∈ [−a_eb,max(m), a_t,max(m)]``, gap ≥ ``s_min_m``
(soft) — or ``law = "bang_bang"`` (``u = −a_eb,max``). A latched (obstacle) brake uses ``latched_law``
(default bang-bang: the paper's obstacle runs look like full braking, A9).

**Additive braking** (``additive = true``, the arrival case, A27: "emergency braking on the basis of normal
deceleration braking"): with a ``service_accel_mps2`` in the sensor reading (the engine puts the other roles'
minimum there) the CA decides a braking *increment* ``Δ ∈ [−a_eb,max − u_service, 0]``: the QP predicts the
vehicle under ``u_service + Δ`` (held over the horizon) and prices ``Δ`` itself (``r_u``, ``r_du``), so a large
``r_u`` gives the gentle, long CA braking the paper reports. The command is marked ``additive`` and the
engine's arbitration (:func:`controllers.base.arbitrate`) adds it to the others' minimum, bounded by the brake
envelope; an idle additive CA returns an increment of 0 (adds nothing). ``Command.emergency`` is True while the
brake is latched or the (total) command is below the service braking.

Inactive, a non-additive CA commands the traction limit (no restriction under the engine's min()); with
``post_release = "hold_speed"`` a released vehicle is capped at cruise (net 0), with ``"previous_command"`` at the
service command it had when the CA fired ("continues to move under its previous deceleration state and proceeds
to stop", arrival case) — either until the formation state becomes ``coupling`` again or
``extras["ca_hold_clear"]`` is set (A11).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from controllers.base import Command, Observation, register
from controllers.braking import params_from_mapping, require
from controllers.monorail.braking_modes import BrakingPolicy, required_gap_m
from controllers.monorail.mpc import GapTrackingQp, QpWeights, predict_ahead
from controllers.monorail.states import braking_suffices, ca_hysteresis, ca_should_fire
from railsim.physics.vehicle import VehicleParams

POST_RELEASE = ("none", "hold_speed", "previous_command")


@dataclass(frozen=True)
class CaParams:
    threshold_mode: str = "fixed"  # fixed | adbm | rdbm
    fixed_threshold_m: float = 28.0
    t_eq_s: float = 1.0
    margin_m: float = 5.0
    assumed_own_decel_mps2: float = 0.0  # 0: use the vehicle's own (load-aware) emergency deceleration
    assumed_object_decel_mps2: float = 0.0  # 0: same as the own value (RDBM credit for the object ahead)
    release_margin_m: float = 0.0  # h of A10 (0 = paper reproduction, 0.5 robust)
    min_on_s: float = 0.1
    # Trigger debounce (:func:`.states.ca_should_fire`): all 0 (the default) = the paper's bare trigger.
    # Opt-in (e.g. dwell 0.3 s, band 2.5 m, re-arm 1 s, release margin 0.5 m) until "unguarded" time is defined
    # against the debounced band: with it the gap may sit up to ``trigger_band_m`` below the bare trigger unbraked.
    trigger_dwell_s: float = 0.0  # a shallow intrusion must persist this long
    trigger_band_m: float = 0.0  # deeper than this below the trigger fires at once (whatever the own braking)
    rearm_s: float = 0.0  # after a release, shallow intrusions do not re-fire for this long
    latch: str = "obstacle"  # obstacle | always | never
    law: str = "mpc"  # mpc | bang_bang
    latched_law: str = "bang_bang"
    additive: bool = False
    post_release: str = "none"  # none | hold_speed | previous_command
    horizon_steps: int = 20
    control_horizon_steps: int = 10
    dt_s: float = 0.1
    response_s: float = 0.3
    efficiency: float = 1.0
    q_gap: float = 1.0
    q_speed: float = 1.0
    r_u: float = 0.5
    r_du: float = 1.0
    ref_offset_m: float = 2.0
    s_min_m: float = 5.0
    standstill_mps: float = 0.01

    def __post_init__(self) -> None:
        require("latch", self.latch in ("obstacle", "always", "never"), "'obstacle', 'always' or 'never'", self.latch)
        for name in ("law", "latched_law"):
            require(name, getattr(self, name) in ("mpc", "bang_bang"), "'mpc' or 'bang_bang'", getattr(self, name))
        require(
            "post_release",
            self.post_release in POST_RELEASE,
            "'none', 'hold_speed' or 'previous_command'",
            self.post_release,
        )
        for name in (
            "release_margin_m",
            "min_on_s",
            "trigger_dwell_s",
            "trigger_band_m",
            "rearm_s",
            "assumed_own_decel_mps2",
            "assumed_object_decel_mps2",
            "ref_offset_m",
            "s_min_m",
            "standstill_mps",
        ):
            require(name, getattr(self, name) >= 0.0, "a number >= 0", getattr(self, name))
        require(
            "horizon_steps",
            self.horizon_steps >= self.control_horizon_steps >= 1,
            "horizon_steps >= control_horizon_steps >= 1",
            (self.horizon_steps, self.control_horizon_steps),
        )
        self.policy()

    def policy(self) -> BrakingPolicy:
        return BrakingPolicy(
            mode=self.threshold_mode,
            fixed_threshold_m=self.fixed_threshold_m,
            t_eq_s=self.t_eq_s,
            margin_m=self.margin_m,
            follower_decel_mps2=self.assumed_own_decel_mps2 or None,
            leader_decel_mps2=self.assumed_object_decel_mps2 or None,
        )


@dataclass(frozen=True)
class SensorReading:
    distance_m: float
    closing_speed_mps: float
    object: str = "vehicle"
    service_accel_mps2: float | None = None


def read_sensor(obs: Observation) -> SensorReading | None:
    """The ``obs.extras["sensor"]`` reading (see module docstring), or None when nothing is in range."""
    raw = obs.extras.get("sensor")
    if not raw:
        return None
    dist = float(raw.get("distance_m", math.inf))
    if not math.isfinite(dist):
        return None
    service = raw.get("service_accel_mps2")
    return SensorReading(
        dist,
        float(raw.get("closing_speed_mps", 0.0)),
        str(raw.get("object", "vehicle")),
        None if service is None else float(service),
    )


class CollisionAvoidance:
    """CA for one vehicle; keeps the trigger state (hysteresis, latch), the post-release hold and the QP."""

    def __init__(self, params: CaParams) -> None:
        p = self.params = params
        self.qp = GapTrackingQp(
            p.dt_s,
            p.response_s,
            p.efficiency,
            int(p.horizon_steps),
            int(p.control_horizon_steps),
            QpWeights(p.q_gap, p.q_speed, p.r_u, p.r_du),
        )
        self.reset()

    def reset(self) -> None:
        self.active = False
        self.latched = False
        self.on_since_s = -math.inf
        self.off_since_s = -math.inf
        self.below_since_s: float | None = None
        self.hold = False
        self.hold_cap_mps2 = 0.0  # the post-release cap (0: cruise; previous_command: the service command at ca_on)
        self.service_at_on_mps2: float | None = None
        self._u_prev = 0.0

    def thresholds_m(self, obs: Observation, reading: SensorReading) -> tuple[float, float]:
        """(trigger, release) gaps [m] for the present speeds."""
        v = max(obs.own.speed_mps, 0.0)
        trig = required_gap_m(
            self.params.policy(), v, max(v - reading.closing_speed_mps, 0.0), obs.vehicle.emergency_decel_mps2
        )
        return trig, trig + self.params.release_margin_m

    def command(self, obs: Observation) -> Command:
        p, veh = self.params, obs.vehicle
        a_t = veh.traction_max_force_n / veh.effective_mass_kg
        b_e, b_s = veh.emergency_decel_mps2, veh.service_decel_mps2
        v = max(obs.own.speed_mps, 0.0)
        reading = read_sensor(obs)
        if self.hold and (obs.formation_state == "coupling" or obs.extras.get("ca_hold_clear")):
            self.hold = False
        if reading is None and not self.active:
            return self._idle(a_t, {"ca": "idle", "sensor": "none"})
        gap = reading.distance_m if reading is not None else math.inf
        trig, release = self.thresholds_m(obs, reading) if reading is not None else (0.0, 0.0)
        was = self.active
        self.below_since_s = (
            (self.below_since_s if self.below_since_s is not None else obs.t_s) if gap <= trig else None
        )
        if was:
            self.active = ca_hysteresis(
                True, self.on_since_s, obs.t_s, gap, trig, release, p.min_on_s, self.latched, v, p.standstill_mps
            )
        else:
            urgent = reading is not None and reading.object == "obstacle"
            enough = reading is not None and braking_suffices(
                gap, reading.closing_speed_mps, obs.own.accel_mps2, p.s_min_m
            )
            self.active = ca_should_fire(
                gap,
                trig,
                obs.t_s,
                self.below_since_s,
                self.off_since_s,
                p.trigger_dwell_s,
                p.trigger_band_m,
                p.rearm_s,
                urgent,
                enough,
            )
        info: dict[str, Any] = {"ca": "active" if self.active else "idle", "gap_m": gap, "trigger_m": trig}
        if self.active and not was:
            self.on_since_s = obs.t_s
            obstacle = reading is not None and reading.object == "obstacle"
            self.latched = p.latch == "always" or (p.latch == "obstacle" and obstacle)
            info["event"] = "ca_on"
            self.service_at_on_mps2 = None if reading is None else reading.service_accel_mps2
        if not self.active:
            if was:
                info["event"] = "ca_off"
                self.off_since_s = obs.t_s
                self.hold = p.post_release != "none" and not self.latched
                prev = self.service_at_on_mps2
                self.hold_cap_mps2 = (
                    min(prev, 0.0) if p.post_release == "previous_command" and prev is not None else 0.0
                )
                self.latched = False
            return self._idle(a_t, info)
        info["latched"] = self.latched
        law = p.latched_law if self.latched else p.law
        # A27: an additive CA decides a braking increment on top of the others' command (``service``), within
        # [−a_eb − service, 0]; otherwise an absolute command in [−a_eb, a_t] that joins the minimum.
        service = self._additive_base(reading)
        base = 0.0 if service is None else service
        u_lo, u_hi = (-b_e, a_t) if service is None else (min(-b_e - service, 0.0), 0.0)
        if law == "bang_bang" or reading is None:
            u = u_lo
        else:
            n = int(p.horizon_steps)
            v_obj = max(v - reading.closing_speed_mps, 0.0)
            dx, v_ahead = predict_ahead(v_obj, 0.0, p.dt_s, n)
            sol = self.qp.solve(
                gap,
                v,
                obs.own.accel_mps2,
                dx,
                v_ahead,
                release + p.ref_offset_m,
                p.s_min_m,
                self._u_prev,
                u_lo,
                u_hi,
                base,
            )
            if sol is None:
                u, info["fallback"] = u_lo, True
                info["fallback_reason"] = "collision-avoidance QP infeasible; emergency brake"
            else:
                u = float(sol[0])
        self._u_prev = u
        emergency = self.latched or base + u < -b_s + 1e-9
        additive = service is not None
        return Command(u, emergency=emergency, fallback=bool(info.get("fallback")), info=info, additive=additive)

    def _additive_base(self, reading: SensorReading | None) -> float | None:
        """The service command the CA adds to (``additive`` and a reading that carries it), else None."""
        if not self.params.additive or reading is None or reading.service_accel_mps2 is None:
            return None
        return reading.service_accel_mps2

    def _idle(self, a_t: float, info: dict[str, Any]) -> Command:
        self._u_prev = 0.0
        if self.hold:
            info["ca"] = "hold_speed" if self.params.post_release == "hold_speed" else "previous_command"
            return Command(self.hold_cap_mps2, info=info)
        if self.params.additive:
            return Command(0.0, info=info, additive=True)  # adds nothing
        return Command(a_t, info=info)


@register("monorail_ca")
def make_ca(params: Mapping[str, Any], vehicle: VehicleParams) -> CollisionAvoidance:
    """``controllers: {ca: {type: monorail_ca, threshold_mode: fixed, fixed_threshold_m: 28}}`` (extra role)."""
    return CollisionAvoidance(params_from_mapping(CaParams, params))


def sensor_extras(
    distance_m: float, closing_speed_mps: float, obj: str = "vehicle", service_accel_mps2: float | None = None
) -> dict[str, Any]:
    """Build the ``obs.extras`` entry this controller reads (for the engine and the scenario runner)."""
    reading: dict[str, Any] = {
        "distance_m": float(distance_m),
        "closing_speed_mps": float(closing_speed_mps),
        "object": obj,
    }
    if service_accel_mps2 is not None:
        reading["service_accel_mps2"] = float(service_accel_mps2)
    return {"sensor": reading}


__all__ = ["CaParams", "CollisionAvoidance", "SensorReading", "make_ca", "read_sensor", "sensor_extras"]
