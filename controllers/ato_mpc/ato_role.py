"""Paper B's ATO laws in the engine's ``ato`` role: ``sempc``, ``mpc``, ``afsmc``, ``pid_ato``.

Every train has an ``ato`` controller (:mod:`controllers.base`); these factories make the laws of this package
usable there. Per step the adapter

1. builds the section's speed–distance profile from the observation, like :mod:`controllers.ato` reads it:
   the stop point is the next stop's mark (clamped ``stop_tolerance_m`` inside the platform window) or the end
   of movement authority minus ``authority_margin_m``, whichever comes first (the route end if neither);
   ``v_max(s) = min(obs.line_speed_mps, restrictions, vehicle.max_speed_mps)``, a restriction counting until
   the rear has cleared it (its end is extended by the train length);
2. forms the multi-point state: if the engine runs the multi-point plant it passes the relative-coordinate
   state in ``obs.extras["multipoint_rel_state"]`` (proposed interface); otherwise the single-mass
   observation is lifted to couplers at rest (``x_{i,i−1} = −l``, relative speeds 0) and the gradient under
   the front is used for all carriages;
3. holds (holding-brake force, reached at the force-rate limit) while dwelling or standing at the stop, and
   otherwise asks the law (:class:`controllers.ato_mpc.core.AtoDriver`);
4. returns ``Command.accel_mps2 = Σu_i / Σm_i`` — the model's applied specific force, what the single-mass
   plant integrates — and ``info["forces_n"]`` (per carriage, for the multi-point plant), ``fallback`` when the
   QP failed. Emergency braking if even service braking cannot stop before the end of authority.
5. keeps the section's *time-indexed* expected profile (Paper B's expected displacement/speed, built at the
   section's departure): the law tracks it with ``reference_mode: time`` (paper-literal), and every step reports
   it in ``info`` (``x_ref_m``, ``v_ref_mps``, with the stop point ``stop_m``) for the paper's E_d/E_v/E_p
   (:mod:`railsim.engine.extensions.paper001`), whatever the law tracks.

The controller model is derived from the train's :class:`~railsim.physics.vehicle.VehicleParams` by default (effective
mass split over ``n_cars``, Davis A/B/C per tonne of it, traction/brake/jerk limits split per carriage), so the
ATO runs on any line; ``paper_train: true`` uses Paper B's Table 1 instead. The control period is the engine's
step (``period_s: 0``) or a fixed value equal to it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from controllers.ato_mpc.afsmc import AfsmcLaw, AfsmcParams
from controllers.ato_mpc.core import REFERENCE_MODES, AtoDriver, CarriageLaw, Situation
from controllers.ato_mpc.mpc import mpc_settings
from controllers.ato_mpc.pid import PidLaw, PidParams
from controllers.ato_mpc.reference import Limit, SpeedDistanceProfile, TimeReference, time_profile
from controllers.ato_mpc.sempc import MpcLaw, sempc_settings
from controllers.base import Command, Observation, register
from controllers.braking import params_from_mapping, require
from railsim.physics.multipoint import MultipointParams
from railsim.physics.vehicle import VehicleParams


@dataclass(frozen=True)
class MpcAtoParams:
    """Scenario parameters of the ``sempc``/``mpc``/``afsmc``/``pid_ato`` controllers."""

    n_cars: float = 6
    paper_train: bool = False
    period_s: float = 0.0  # 0: the engine's step
    reference_mode: str = "distance"
    variant: str = "A"  # mpc only: A (no terminal cost) or B (u as decision, no rate limit)
    terminal: str = "dare"  # sempc only: dare | lyapunov
    discretisation: str = "zoh"
    q_x1: float = 0.5
    q_v1: float = 1e9
    q_rel_x: float = 1e12
    q_rel_v: float = 1e12
    r_du: float = 1e-5
    horizon: float = 3
    margin_mps: float = 1.0
    brake_mps2: float = 0.7
    accel_mps2: float = 0.9
    hold_decel_mps2: float = 0.3
    stop_tolerance_m: float = 0.3
    authority_margin_m: float = 5.0

    def __post_init__(self) -> None:
        require("n_cars", self.n_cars >= 1 and float(self.n_cars).is_integer(), "an integer >= 1", self.n_cars)
        require("horizon", self.horizon >= 1 and float(self.horizon).is_integer(), "an integer >= 1", self.horizon)
        require("period_s", self.period_s >= 0.0, "a number >= 0", self.period_s)
        require("reference_mode", self.reference_mode in REFERENCE_MODES, "one of distance, time", self.reference_mode)
        require("variant", self.variant in ("A", "B"), "A or B", self.variant)
        require("terminal", self.terminal in ("dare", "lyapunov"), "dare or lyapunov", self.terminal)
        require("discretisation", self.discretisation in ("euler", "zoh"), "euler or zoh", self.discretisation)
        for name in ("q_x1", "q_v1", "q_rel_x", "q_rel_v"):
            require(name, getattr(self, name) >= 0.0, "a number >= 0", getattr(self, name))
        for name in ("r_du", "brake_mps2", "accel_mps2", "hold_decel_mps2", "stop_tolerance_m"):
            require(name, getattr(self, name) > 0.0, "a number > 0", getattr(self, name))
        require("margin_mps", self.margin_mps >= 0.0, "a number >= 0", self.margin_mps)
        require("authority_margin_m", self.authority_margin_m >= 0.0, "a number >= 0", self.authority_margin_m)


def multipoint_from_vehicle(vehicle: VehicleParams, n_cars: int) -> MultipointParams:
    """The controller's n-carriage model of a single-mass train (see module docstring)."""
    m_eff = vehicle.effective_mass_kg
    tonnes = m_eff / 1000.0
    return MultipointParams(
        n_cars=n_cars,
        car_mass_kg=m_eff / n_cars,
        davis_c0_n_per_t=vehicle.davis_a_n / tonnes,
        davis_c1_ns_per_m_t=vehicle.davis_b_n_per_mps / tonnes,
        davis_c2_ns2_per_m2_t=vehicle.davis_c_n_per_mps2 / tonnes,
        force_max_n=vehicle.traction_max_force_n / n_cars,
        force_min_n=-vehicle.service_decel_mps2 * m_eff / n_cars,
        force_rate_max_n_per_s=vehicle.jerk_limit_mps3 * m_eff / n_cars,
        force_rate_min_n_per_s=-vehicle.jerk_limit_mps3 * m_eff / n_cars,
    )


class MpcAto:
    """One train's ATO around a law of this package (lazy set-up at the first observation's ``dt``)."""

    def __init__(self, kind: str, params: MpcAtoParams, vehicle: VehicleParams) -> None:
        self.kind = kind
        self.params = params
        self.vehicle = vehicle
        n = int(params.n_cars)
        self.model = MultipointParams(n_cars=n) if params.paper_train else multipoint_from_vehicle(vehicle, n)
        self.driver: AtoDriver | None = None
        self.period_s = params.period_s
        self._section: tuple[str | None, TimeReference, float] | None = None  # (stop station, reference, t_dep)

    def _law(self, period_s: float) -> CarriageLaw:
        pr = self.params
        n_h = int(pr.horizon)
        common = dict(
            period_s=period_s,
            q_x1=pr.q_x1,
            q_v1=pr.q_v1,
            q_rel_x=pr.q_rel_x,
            q_rel_v=pr.q_rel_v,
            r_du=pr.r_du,
            horizon_p=n_h,
            horizon_c=n_h,
            discretisation=pr.discretisation,
        )
        if self.kind == "sempc":
            return MpcLaw(self.model, sempc_settings(terminal=pr.terminal, **common), pr.reference_mode)
        if self.kind == "mpc":
            extra = {"r_u": pr.r_du} if pr.variant == "B" else {}
            return MpcLaw(self.model, mpc_settings(pr.variant, **common, **extra), pr.reference_mode)
        if self.kind == "afsmc":
            return AfsmcLaw(self.model, AfsmcParams(period_s=period_s), pr.reference_mode)
        return PidLaw(self.model, PidParams(period_s=period_s), pr.reference_mode)

    def reset(self) -> None:
        if self.driver is not None:
            self.driver.reset()
        self._section = None

    def _section_reference(
        self, obs: Observation, profile: SpeedDistanceProfile, dwelling: bool
    ) -> tuple[TimeReference | None, float]:
        """The section's time-indexed expected profile (Paper B §2.9, :func:`~.reference.time_profile`) and its
        departure time: built at the first running step towards a new stop (keyed by the stop's station, so a
        moving end of authority does not restart it), from the position there; None until the train first runs."""
        key = obs.next_stop.station_id if obs.next_stop is not None else None
        if not dwelling and (self._section is None or self._section[0] != key):
            tref = time_profile(profile, obs.own.position_m, self.period_s)
            self._section = (key, tref, obs.t_s)
        if self._section is None:
            return None, obs.t_s
        return self._section[1], self._section[2]

    def _profile(self, obs: Observation) -> tuple[SpeedDistanceProfile, bool]:
        pr = self.params
        own = obs.own
        points = [obs.route_length_m]
        stop = obs.next_stop
        if stop is not None:
            lo = stop.window_start_m + pr.stop_tolerance_m
            hi = stop.window_end_m - pr.stop_tolerance_m
            points.append(
                min(max(stop.mark_m, lo), hi) if lo <= hi else 0.5 * (stop.window_start_m + stop.window_end_m)
            )
        if obs.authority_end_m is not None:
            points.append(obs.authority_end_m - pr.authority_margin_m)
        limits = tuple(Limit(lim.start_m, lim.end_m + own.length_m, lim.speed_mps) for lim in obs.speed_limits)
        profile = SpeedDistanceProfile(
            stop_m=min(points),
            line_speed_mps=max(obs.line_speed_mps, 1e-3),
            design_speed_mps=self.vehicle.max_speed_mps,
            limits=limits,
            margin_mps=pr.margin_mps,
            brake_mps2=pr.brake_mps2,
            accel_mps2=pr.accel_mps2,
        )
        in_window = (
            stop is not None
            and stop.window_start_m <= own.position_m <= stop.window_end_m + pr.stop_tolerance_m  # SUMO's window
        )
        return profile, in_window

    def command(self, obs: Observation) -> Command:
        if self.driver is None:
            period = self.period_s if self.period_s > 0.0 else obs.dt_s
            self.period_s = period
            pr = self.params
            self.driver = AtoDriver(self._law(period), self.model, period, pr.hold_decel_mps2, pr.stop_tolerance_m)
        p = self.model
        n = p.n_cars
        own = obs.own
        v = max(own.speed_mps, 0.0)
        rel = obs.extras.get("multipoint_rel_state") if obs.extras else None
        if rel is None:
            rel = np.concatenate(([own.position_m], np.full(n - 1, -p.coupler_length_m), [v], np.zeros(n - 1)))
        rel = np.asarray(rel, dtype=float)
        grad = np.full(n, own.gradient_permille)
        profile, in_window = self._profile(obs)
        standing = v <= p.standstill_mps
        dwelling = obs.next_stop is not None and (obs.next_stop.dwelling or (standing and in_window))
        tref, t_dep = self._section_reference(obs, profile, dwelling)
        sit = Situation(obs.t_s, rel, grad, profile, tref, obs.t_s - t_dep)
        u, info = self.driver.step(sit, dwelling)
        accel = float(np.sum(u) / p.total_mass_kg)
        if not math.isfinite(accel):  # never hand a NaN to the plant (nor to the carriage plant's forces)
            accel = -self.vehicle.service_decel_mps2
            u = np.full(n, accel * p.car_mass_kg)
            info = {**info, "fallback": True, "fallback_reason": "non-finite traction forces; service brake"}
        out_info: dict[str, Any] = {"phase": info.get("phase", "run"), "forces_n": tuple(float(f) for f in u)}
        if tref is not None:  # the paper's expected displacement/speed now, and the stop point (Paper B metrics)
            x_ref, v_ref = tref.at(tref.index(obs.t_s - t_dep))
            out_info.update(x_ref_m=float(x_ref), v_ref_mps=float(v_ref), stop_m=float(profile.stop_m))
        for key in ("status", "solve_time_s", "iterations", "fallback_reason"):
            if key in info:
                out_info[key] = info[key]
        if obs.authority_end_m is not None and v > 0.0:
            room = obs.authority_end_m - own.position_m
            if v * v / (2.0 * self.vehicle.service_decel_mps2) > max(room, 0.0):
                return Command(
                    -self.vehicle.emergency_decel_mps2, emergency=True, info={**out_info, "phase": "emergency"}
                )
        return Command(accel, fallback=bool(info.get("fallback", False)), info=out_info)


def _factory(kind: str):
    def make(params: Mapping[str, Any], vehicle: VehicleParams) -> MpcAto:
        pr = params_from_mapping(MpcAtoParams, params)
        ato = MpcAto(kind, pr, vehicle)
        if kind in ("sempc", "mpc"):
            # Build once with a nominal period so that bad weights fail at load time, not mid-run.
            ato._law(pr.period_s if pr.period_s > 0.0 else 0.1)
        return ato

    return make


register("sempc")(_factory("sempc"))
register("mpc")(_factory("mpc"))
register("afsmc")(_factory("afsmc"))
register("pid_ato")(_factory("pid_ato"))
