"""CACC: cooperative adaptive cruise control for a virtually coupled follower (constant gap + safety check).

Used in the ``follow`` role while a formation is ``coupling`` or ``coupled`` (see :mod:`controllers.base`).

Tracking law (net accelerations; the applied command adds resistance and gradient feed-forward)::

    gap  = (rear_p + v_p·age) − x            front-to-rear, predecessor extrapolated by the message age
    e    = gap − gap*                          gap* = obs.target_gap_m
    a    = k_gap·e + k_speed·(v_p − v) + k_ff·â_p

written in cascade form ``a = k_speed·(v_p + v_close − v) + k_ff·â_p`` with the closing-speed reference
``v_close = (k_gap/k_speed)·e``, limited while the gap is much larger than its target to
``min(approach_speed, √(2·approach_decel·e))`` — in the linear region this *is* the law above; far out it closes
at a bounded relative speed and sheds it at a comfortable relative deceleration, so coupling converges from
hundreds of metres without overshoot.

Feed-forward and string stability. ``â_p`` should be the acceleration the predecessor is *commanding now*:
its command passes through the same lag τ as ours, so the follower replicates it in step and the string is
neutral — the gap-error transfer from one train to the next is Γ ≡ 1 for any gains (with ``P`` the plant
from command to position and ``C`` the feedback, ``X = P·(C·(X_p − X) + U_p)`` and ``X_p = P·U_p`` give
``X = X_p``). Where it comes from, in order of preference:

1. the predecessor's broadcast plan (``planned_accel_mps2``, DMPC-style), entry ``⌊age/plan_dt⌋`` — exact
   when the engine publishes a train's command before its follower decides;
2. ``ff_lag_compensation`` (default): the command reconstructed from two consecutive messages by inverting
   the lag, ``û = a_prev + (a_new − a_prev)/(1 − e^{−Δt/τ})`` (Δt between the time stamps, τ of this train's
   vehicle as a proxy) — this is the predecessor's command of the *previous* step;
3. otherwise the reported applied acceleration.

With (2) or (3) the feed-forward is at least one step old, and with constant spacing and predecessor-only
information that makes some amplification unavoidable (Seiler, Pant & Hedrick 2004): for the default gains
max |Γ| ≈ 1.1 at dt = 0.1 s, ≈ 1.6 at dt = 0.5 s, ≈ 2.5 at dt = 1.0 s (around 1.5–2 rad/s). Lower gains
reduce it (k_gap = 0.02, k_speed = 0.5: 1.26 at dt = 0.5 s) at the cost of a slow gap loop. The defaults
``k_gap = 0.1 /s²``, ``k_speed = 1.0 /s`` give ζ ≈ 0.68 with the cq3_6car plant (τ = 0.5 s) at dt = 0.5 s
and a slowest time constant of ≈ 9 s. The controller keeps one piece of state: the last message of the
current predecessor (for the reconstruction).

Safety check (relative braking distance, Hou et al. RDBM reading). With the predecessor extrapolated by its
message age under worst-case emergency braking (``v_pw``, ``rear_w``)::

    RBD = S_f(v) − v_pw²/(2·b_p) + margin,     S_f(v) = v·T + a0·T²/2 + (v + a0·T)²/(2·b_f)
    h   = (rear_w − x) − RBD ≥ 0

(:func:`controllers.braking.relative_braking_distance_m` is this ``RBD``, the one definition shared with the
junction planner, which keeps its plans outside the guard's cap.)

``b_f`` is this train's emergency deceleration (net: gradient and the constant Davis term, i.e. the resistance at
a crawl, the least it gets during a stop), ``b_p`` the predecessor's emergency deceleration plus its running
resistance at its present speed (estimated with this train's Davis coefficients; a predecessor that stops sooner
is the worse case), ``T`` = actuator lag + reaction time + one control step (the command is held for a step
before the next decision; emergency braking bypasses the jerk limit). The message age enters through the
worst-case extrapolation, i.e. like extra reaction time. So the target gap is only kept where it is safe: with
the defaults (margin 10 m, τ = 0.5 s) at dt = 0.5 s and 0.5 s old messages a 30 m gap is consistent up to about
11 m/s; above that the safety cap holds the follower further back (≈ 38 m at 15 m/s) — scenarios should set
``target_gap_m`` ≳ v·(τ + dt + age) + margin + (braking-rate asymmetry) for their speed. As in
:mod:`controllers.separation` the acceleration is capped so that ``h`` decays no faster than ``−γ·h``
(γ ≤ 0.5/dt)::

    a ≤ [(v_p − v) + (v_pw/b_p)·a_p + γ·h] / (T + (v + a0·T)/b_f)

(the rate uses the reported speed: the worst-case extrapolation sets the level of ``h`` and is refreshed by
every message; it is not a trend).

and ``emergency=True`` (emergency braking) when that cap asks for more than service braking can give.

Gap policy (``gap_policy``). ``constant`` tracks ``obs.target_gap_m`` as given. ``safe`` (default) tracks
``max(obs.target_gap_m, G(v) + gap_buffer_m)`` where ``G`` is the steady-state gap that keeps the safety
barrier above zero at equal speeds with the current message age::

    G(v) = S_f(v, a0 = R(v)/m_eff) − v²/(2·b_p) + margin + v·age

so at standstill a formation keeps its configured (platform-sized) gap and at speed the relative braking
distance the safety check demands — the controller never fights its own safety cap. The effective target is
reported in ``Command.info["target_gap_m"]``; the engine measures gap errors against it.

Stopping behind a standing leader (``obs.extras["vc_tracking"] is False``). When the predecessor already
stands at the station this train is stopping at, the stop is a point-stopping problem (the ATO stops the
front exactly ``target gap`` behind the leader's rear); the CACC then applies only its safety cap, so its slow
final gap loop does not freeze the train a metre short.

Without a predecessor or without a target gap there is nothing to track: the command is the traction limit,
so the engine's ``min()`` leaves ATO in charge.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from controllers import cacc_kernel
from controllers.base import Command, Observation, PredecessorState, register
from controllers.braking import params_from_mapping, require, traction_limit_mps2
from railsim.physics.vehicle import VehicleParams


@dataclass(frozen=True)
class CaccParams:
    """CACC gains and safety parameters; defaults tuned for cq3_6car at dt = 0.5 s (τ = 0.5 s)."""

    k_gap_per_s2: float = 0.1  # gap-error gain [1/s²]
    k_speed_per_s: float = 1.0  # relative-speed gain [1/s]
    k_ff: float = 1.0  # predecessor acceleration feed-forward gain [-]
    ff_lag_compensation: bool = True  # reconstruct the predecessor's command by inverting the lag
    approach_speed_mps: float = 3.0  # largest closing speed while the gap is much larger than target [m/s]
    approach_decel_mps2: float = 0.3  # relative deceleration to shed the closing speed [m/s²]
    safety_margin_m: float = 10.0  # relative-braking-distance margin [m]
    reaction_time_s: float = 0.0  # reaction allowance on top of actuator lag and one control step [s]
    barrier_rate_per_s: float = 1.0  # γ of the safety cap [1/s] (capped at 0.5/dt)
    gap_policy: str = "safe"  # "safe": max(target, steady-state safe gap + buffer); "constant": target as given
    gap_buffer_m: float = 2.0  # added to the steady-state safe gap under the "safe" policy [m]

    def __post_init__(self) -> None:
        require("k_gap_per_s2", self.k_gap_per_s2 > 0.0, "a number > 0", self.k_gap_per_s2)
        require("k_speed_per_s", self.k_speed_per_s > 0.0, "a number > 0", self.k_speed_per_s)
        require("k_ff", 0.0 <= self.k_ff <= 2.0, "a number in [0, 2]", self.k_ff)
        require("approach_speed_mps", self.approach_speed_mps > 0.0, "a number > 0", self.approach_speed_mps)
        require("approach_decel_mps2", self.approach_decel_mps2 > 0.0, "a number > 0", self.approach_decel_mps2)
        require("safety_margin_m", self.safety_margin_m >= 0.0, "a number >= 0", self.safety_margin_m)
        require("reaction_time_s", self.reaction_time_s >= 0.0, "a number >= 0", self.reaction_time_s)
        require("barrier_rate_per_s", self.barrier_rate_per_s > 0.0, "a number > 0", self.barrier_rate_per_s)
        require("gap_policy", self.gap_policy in ("safe", "constant"), "'safe' or 'constant'", self.gap_policy)
        require("gap_buffer_m", self.gap_buffer_m >= 0.0, "a number >= 0", self.gap_buffer_m)


class Cacc:
    """CACC for one follower. Keeps the last message of its predecessor (for the lag compensation)."""

    def __init__(self, params: CaccParams, vehicle: VehicleParams) -> None:
        self.params = params
        self.vehicle = vehicle
        self._last: tuple[str, float, float] | None = None  # (train_id, stamp_s, accel_mps2) of the last message
        self._command_estimate_mps2 = 0.0
        self._packed: tuple[VehicleParams, float, np.ndarray] | None = None  # the law's inputs (cacc_kernel.pack)

    def reset(self) -> None:
        """Forget the predecessor's message history."""
        self._last = None
        self._command_estimate_mps2 = 0.0

    def _predecessor_command(self, pred: PredecessorState, lag_s: float) -> float:
        """The predecessor's commanded acceleration, reconstructed from consecutive messages (applied if unknown)."""
        last = self._last
        if last is None or last[0] != pred.train_id or pred.stamp_s < last[1]:
            self._last = (pred.train_id, pred.stamp_s, pred.accel_mps2)
            self._command_estimate_mps2 = pred.accel_mps2
        elif pred.stamp_s > last[1]:
            interval_s = pred.stamp_s - last[1]
            alpha = 1.0 - math.exp(-interval_s / lag_s) if lag_s > 0.0 else 1.0
            estimate = last[2] + (pred.accel_mps2 - last[2]) / alpha
            # Bound by what any train can do; a lost message in between makes the inversion approximate.
            self._command_estimate_mps2 = min(max(estimate, -pred.emergency_decel_mps2), 2.0)
            self._last = (pred.train_id, pred.stamp_s, pred.accel_mps2)
        return self._command_estimate_mps2

    def command(self, obs: Observation) -> Command:
        own = obs.own
        return self.decide(
            obs.vehicle,
            obs.dt_s,
            own.position_m,
            own.speed_mps,
            own.accel_mps2,
            own.gradient_permille,
            obs.predecessor,
            obs.target_gap_m,
            obs.extras.get("vc_tracking") is not False,
        )

    def decide(
        self,
        veh: VehicleParams,
        dt_s: float,
        position_m: float,
        speed_mps: float,
        accel_mps2: float,
        gradient_permille: float,
        pred: PredecessorState | None,
        target_gap_m: float | None,
        tracking: bool = True,
    ) -> Command:
        """:meth:`command` on plain values (what the engine hands a coupled follower's CACC without building an
        :class:`Observation`): the feed-forward chosen here (plan entry, reconstructed command or the reported
        acceleration), the law itself in one compiled call (:func:`controllers.cacc_kernel.cacc`)."""
        if pred is None or target_gap_m is None:
            return Command(traction_limit_mps2(veh, max(speed_mps, 0.0)), info={"phase": "free"})
        a_p_applied = self.feed_forward_mps2(pred, veh)
        accel, emergency, phase, gap_m, error_m, h, target_m = cacc_kernel.cacc(
            self.packed(veh, dt_s),
            position_m,
            speed_mps,
            accel_mps2,
            gradient_permille,
            pred.rear_position_m,
            pred.speed_mps,
            pred.accel_mps2,
            pred.emergency_decel_mps2,
            pred.age_s,
            a_p_applied,
            float(target_gap_m),
            tracking,
        )
        info: dict[str, Any] = {
            "phase": cacc_kernel.PHASES[phase],
            "gap_m": gap_m,
            "gap_error_m": error_m,
            "rbd_margin_m": h,
            "target_gap_m": target_m,
        }
        return Command(accel, emergency=emergency, info=info)

    def feed_forward_mps2(self, pred: PredecessorState, veh: VehicleParams) -> float:
        """The predecessor's acceleration the law feeds forward (module docstring): the entry for "now" of its
        broadcast plan, else its command reconstructed from consecutive messages (this updates the controller's
        memory of them: call it once per decision), else the acceleration it reported."""
        if pred.planned_accel_mps2 and pred.plan_dt_s > 0.0:
            # The predecessor broadcast its plan: the entry for "now" is the command it is applying.
            index = min(int(max(pred.age_s, 0.0) / pred.plan_dt_s + 1e-9), len(pred.planned_accel_mps2) - 1)
            return pred.planned_accel_mps2[index]
        if self.params.ff_lag_compensation:
            return self._predecessor_command(pred, veh.actuator_time_constant_s)
        return pred.accel_mps2

    def packed(self, veh: VehicleParams, dt_s: float) -> np.ndarray:
        """The law's inputs for ``veh`` and step ``dt_s`` (:func:`controllers.cacc_kernel.pack`, once per vehicle
        and step length; also for the engine's compiled coupled step)."""
        packed = self._packed
        if packed is None or packed[0] is not veh or packed[1] != dt_s:
            packed = self._packed = (veh, dt_s, cacc_kernel.pack(veh, self.params, dt_s))
        return packed[2]


@register("cacc")
def make_cacc(params: Mapping[str, Any], vehicle: VehicleParams) -> Cacc:
    """Factory for scenarios: ``controllers: {follow: {type: cacc, k_gap_per_s2: 0.1}}``."""
    return Cacc(params_from_mapping(CaccParams, params), vehicle)
