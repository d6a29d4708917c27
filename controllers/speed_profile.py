"""A leader that follows a prescribed speed-versus-time profile (the papers' "leader keeps 220 km/h" runs).

Paper A's experiments move the platoon leader by a schedule, not by a timetable: constant 220 km/h (S-A…S-D),
or 220 → 180 km/h at 0.2 m/s², hold 100 s, back to 220 km/h at 0.2 m/s² (S-E). This controller produces that
reference and tracks it::

    v_ref(t)  piecewise: hold, then ramps at |accel_mps2| towards each segment's target from its start time
    a_net     = a_ref(t) + k_speed·(v_ref(t) − v)                      (feed-forward + proportional)
    u         = vehicle.net_to_applied(a_net, v, gradient)               (resistance feed-forward, same physics)

The initial reference speed is ``initial_kmh`` or, if absent, the train's speed at its first control step. It is
meant for open-track experiments: it ignores stations (give such services no intermediate stops); the engine's
min() with the other roles still applies separation and authority limits.

Broadcast plan (Paper A §2.5/A17: the follower's DMPC reads its predecessor's predicted states, and
S-E's "leader future known"): with ``plan_horizon_s > 0`` every command carries ``info["plan"]``, this law's own
closed-loop prediction over the horizon — the same law applied to the predicted state, sampled every
``plan_dt_s`` (default: the control step), integrated as the plant does for a constant command over a step
(``x += v·dt + a·dt²/2``, ``v += a·dt``: exact under the ballistic update), with the traction/brake envelope
and the gradient under the front now. Without noise the prediction is the leader's future exactly (ballistic);
the engine sends it on t2t with the next position report (:mod:`railsim.engine.knowledge`), and a follower that
gets no fresh plan extrapolates.

Parameters (``params``): ``initial_kmh`` (optional), ``segments``: list of ``{at_s, to_kmh, accel_mps2}`` (start
time of the ramp in simulation seconds, target speed, ramp rate > 0), ``k_speed_per_s`` (default 1.0),
``plan_horizon_s`` (default 0: no plan), ``plan_dt_s`` (default: the observation's step).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from controllers.base import Command, Observation, register
from controllers.braking import require, traction_limit_mps2
from railsim.physics.vehicle import VehicleParams


@dataclass(frozen=True)
class Segment:
    """From ``at_s`` on, ramp at ``accel_mps2`` (magnitude) towards ``to_mps``, then hold."""

    at_s: float
    to_mps: float
    accel_mps2: float


@dataclass(frozen=True)
class SpeedProfileParams:
    initial_mps: float | None = None
    segments: tuple[Segment, ...] = ()
    k_speed_per_s: float = 1.0
    plan_horizon_s: float = 0.0  # 0: no broadcast plan
    plan_dt_s: float | None = None  # None: the control step


def reference(profile: SpeedProfileParams, v0_mps: float, t_s: float) -> tuple[float, float]:
    """``(v_ref, a_ref)`` at ``t_s`` for a profile starting at ``v0_mps`` (pure, closed form)."""
    v = v0_mps
    for k, seg in enumerate(profile.segments):
        if t_s < seg.at_s:
            break
        end = profile.segments[k + 1].at_s if k + 1 < len(profile.segments) else math.inf
        ramp_s = abs(seg.to_mps - v) / seg.accel_mps2
        t_in = min(t_s, end) - seg.at_s
        sign = 1.0 if seg.to_mps >= v else -1.0
        if t_in < ramp_s:
            v_now = v + sign * seg.accel_mps2 * t_in
            if t_s < end:
                return v_now, sign * seg.accel_mps2
            v = v_now
        else:
            v = seg.to_mps
    return v, 0.0


class SpeedProfile:
    """Tracks :func:`reference`; remembers the first speed it saw when no ``initial_kmh`` is given."""

    def __init__(self, params: SpeedProfileParams, vehicle: VehicleParams) -> None:
        self.params = params
        self.vehicle = vehicle
        self._v0: float | None = params.initial_mps

    def reset(self) -> None:
        self._v0 = self.params.initial_mps

    def command(self, obs: Observation) -> Command:
        v = max(obs.own.speed_mps, 0.0)
        if self._v0 is None:
            self._v0 = v
        grad = obs.own.gradient_permille
        u, v_ref = self._law(obs.vehicle, obs.t_s, v, grad)
        info: dict[str, Any] = {"v_ref_mps": v_ref}
        if self.params.plan_horizon_s > 0.0:
            info["plan"] = self._plan(obs, v, u, grad)
        return Command(u, info=info)

    def _law(self, veh: VehicleParams, t_s: float, v: float, grad: float) -> tuple[float, float]:
        """The applied command at ``(t_s, v)`` and the reference speed (feed-forward + P, envelope-clipped)."""
        assert self._v0 is not None
        v_ref, a_ref = reference(self.params, self._v0, t_s)
        a_net = a_ref + self.params.k_speed_per_s * (v_ref - v)
        u = veh.net_to_applied(a_net, v, grad)
        return min(max(u, -veh.service_decel_mps2), traction_limit_mps2(veh, v)), v_ref

    def _plan(self, obs: Observation, v0: float, u0: float, grad: float) -> dict[str, Any]:
        """This law's closed-loop prediction from the observed state (the plan format of ``Command.info``)."""
        veh = obs.vehicle
        dt = self.params.plan_dt_s or obs.dt_s
        steps = max(1, int(math.ceil(self.params.plan_horizon_s / dt - 1e-9)))
        xs, vs, us = [float(obs.own.position_m)], [v0], []
        u = u0
        for j in range(steps):
            if j > 0:
                u = self._law(veh, obs.t_s + j * dt, vs[-1], grad)[0]
            a = u - veh.resistance_n(vs[-1], grad) / veh.effective_mass_kg
            a = max(a, -vs[-1] / dt)  # the plant does not reverse: a stop within the step ends the plan there
            xs.append(xs[-1] + vs[-1] * dt + 0.5 * a * dt * dt)
            vs.append(vs[-1] + a * dt)
            us.append(u)
        us.append(us[-1])
        return {"dt_s": dt, "position_m": tuple(xs), "speed_mps": tuple(vs), "accel_mps2": tuple(us)}


@register("speed_profile")
def make_speed_profile(params: Mapping[str, Any], vehicle: VehicleParams) -> SpeedProfile:
    """Factory: ``{type: speed_profile, params: {initial_kmh: 220, segments: [{at_s: 50, to_kmh: 180, accel_mps2: 0.2}]}}``."""
    params = dict(params or {})
    known = ("initial_kmh", "segments", "k_speed_per_s", "plan_horizon_s", "plan_dt_s")
    unknown = set(params) - set(known)
    if unknown:
        raise ValueError(f"{sorted(unknown)[0]}: unknown parameter; expected {', '.join(known)}")
    initial = params.get("initial_kmh")
    if initial is not None:
        require(
            "initial_kmh",
            isinstance(initial, (int, float)) and not isinstance(initial, bool) and initial >= 0,
            "a number >= 0",
            initial,
        )
    k = params.get("k_speed_per_s", 1.0)
    require("k_speed_per_s", _finite(k) and k > 0, "a number > 0", k)
    horizon = params.get("plan_horizon_s", 0.0)
    require("plan_horizon_s", _finite(horizon) and 0 <= horizon <= 3600, "a number in [0, 3600]", horizon)
    plan_dt = params.get("plan_dt_s")
    require("plan_dt_s", plan_dt is None or (_finite(plan_dt) and plan_dt >= 0.01), "a number >= 0.01", plan_dt)
    segments = params.get("segments") or []
    require("segments", isinstance(segments, (list, tuple)), "a list of {at_s, to_kmh, accel_mps2}", segments)
    segs = []
    last_t = -math.inf
    for i, raw in enumerate(segments):
        if not isinstance(raw, Mapping) or set(raw) != {"at_s", "to_kmh", "accel_mps2"}:
            raise ValueError(f"segments[{i}]: expected a mapping with at_s, to_kmh, accel_mps2, got {raw!r}")
        at, to, acc = raw["at_s"], raw["to_kmh"], raw["accel_mps2"]
        for name, val, _ok in (("at_s", at, True), ("to_kmh", to, True), ("accel_mps2", acc, True)):
            if isinstance(val, bool) or not isinstance(val, (int, float)) or not math.isfinite(val):
                raise ValueError(f"segments[{i}].{name}: expected a number, got {val!r}")
        require(f"segments[{i}].at_s", at > last_t, "strictly increasing start times", at)
        require(f"segments[{i}].to_kmh", to >= 0, "a number >= 0", to)
        require(f"segments[{i}].accel_mps2", acc > 0, "a number > 0", acc)
        segs.append(Segment(float(at), float(to) / 3.6, float(acc)))
        last_t = at
    initial_mps = None if initial is None else float(initial) / 3.6
    plan_dt_s = None if plan_dt is None else float(plan_dt)
    return SpeedProfile(SpeedProfileParams(initial_mps, tuple(segs), float(k), float(horizon), plan_dt_s), vehicle)


def _finite(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
