"""The control phase: what each train observes, which roles command it, arbitration and the plant step.

Per train and step (docs/architecture.md, "The step loop"):

1. **Observation** — own odometry (with sensor noise if configured), the speed limits ahead (a coupled
   formation runs as one long train: a restriction holds until its tail clears), the next stop's mark (behind
   the leader's for a coupled follower), the movement authority from the route locks.
2. **Roles** — ``ato`` always (the closing ATO without cruise margin for a coupled follower); ``coupled`` on
   t2t data while the formation couples/is coupled and the leader's data is fresh (else it degrades to
   ``separation`` on ground data, logged ``vc_degraded``/``vc_restored`` with one step of hysteresis);
   ``separation`` against any other train ahead; ``ca`` on the train's own sensor. An extension that
   ``drives`` a train (the junction planner) takes over its roles while it flies a plan (its ``commands``).
3. **Arbitration** — the most restrictive command wins (:func:`controllers.base.arbitrate`; a role whose command
   is ``additive`` — Paper D's arrival-case CA — adds its braking to the others' instead, bounded by the vehicle's
   emergency deceleration; the CA's sensor reading carries the others' minimum as ``service_accel_mps2``);
   emergency braking intervals and non-finite commands are events, and so is every role's fallback
   (``controller_fallback`` with the reason, plus a rate-limited WARNING: :mod:`railsim.engine.fallbacks`).
4. **Plant** — :func:`railsim.physics.dynamics.step` (envelopes, jerk, lag, resistance, gradient) with
   actuator noise and injected biases, or an exact plant extension (carriages, monorail drive) whose step's
   mean speed SUMO is handed. The return value is the speed SUMO applies during the coming step.

One decision, one compiled step for the common case
    :meth:`ControlStage.control_all` is the one place where trains' commands are decided: it reads every train's
    situation (the state at the step's time ``t``, for every train before any is stepped), then, train by train,
    works out which roles command it now (:meth:`~ControlStage._decide`, the only place that chooses) and hands
    steps 2–4 to one of two paths. Most trains on a line, most of the time, are *line trains*: the line ATO
    (:class:`controllers.ato.Ato`) and, with a train ahead, the line moving-block separation
    (:class:`controllers.separation.Separation`) are their only roles, their plant is the standard one and no
    actuator fault acts on them; a coupled follower that is otherwise a line train and whose coupled role is the
    CACC (:class:`controllers.cacc.Cacc`) adds that one role. Both go through one compiled call,
    :func:`railsim.engine.line_step_kernel.step` (:meth:`ControlStage._line_step`, :meth:`ControlStage._coupled_step`):
    the ATO, the CACC (followers only), the separation, the minimum, the plant — the same law functions
    (:mod:`controllers.line_kernels`, :mod:`controllers.cacc_kernel`) and plant (:mod:`railsim.physics.plant_kernel`)
    on the same values, so it gives the bits the general path would. Every other train goes through
    :meth:`ControlStage._role_commands` (each role's :class:`~controllers.base.Command`; the line laws and the CACC
    are asked on plain values, any other controller gets its :class:`~controllers.base.Observation`) and
    :meth:`ControlStage._finish` (arbitration, fallbacks, noise, the plant).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from controllers.ato import NO_STOP, Ato, limits_array_cached
from controllers.base import (
    Command,
    Observation,
    OwnState,
    PredecessorState,
    SpeedLimit,
    StopTarget,
    arbitrate,
    fallback_reason,
)
from controllers.cacc import Cacc
from controllers.separation import Separation
from railsim.engine import kernel_entry, line_step_kernel
from railsim.engine.coupling import COUPLED_STATES, FormationBook
from railsim.engine.disturbances import Disturbances
from railsim.engine.events.log import EventLog
from railsim.engine.extensions.base import ExtensionSet
from railsim.engine.fallbacks import FallbackReporter
from railsim.engine.knowledge import ASK, Knowledge
from railsim.engine.locking import RouteLocks
from railsim.engine.occupancy import Ahead
from railsim.engine.platforms import Berths
from railsim.engine.safety import SafetyMonitor
from railsim.engine.settings import INF, EngineSettings
from railsim.engine.situation import RouteSpans, Situation
from railsim.engine.stops import StopBook
from railsim.engine.train import TrainRuntime
from railsim.physics import dynamics, plant_kernel

log = logging.getLogger(__name__)
_NO_PACK = np.zeros(0)  # no separation law this step (the fused line step does not read it)
PLAN_EVENTS = ("leader_plan_lost", "leader_plan_restored")  # a coupled controller's use of its leader's plan


class ControlStage:
    """Observations → role commands → arbitration → plant step, for one train at a time."""

    def __init__(
        self,
        trains: dict[str, TrainRuntime],
        formations: FormationBook,
        knowledge: Knowledge,
        safety: SafetyMonitor,
        locks: RouteLocks,
        stops: StopBook,
        events: EventLog,
        settings: EngineSettings,
        dt_s: float,
        step_method: str,
        disturbances: Disturbances,
        extensions: ExtensionSet,
    ) -> None:
        self.trains = trains
        self.formations = formations
        self.knowledge = knowledge
        self.safety = safety
        self.locks = locks
        self.stops = stops
        self.events = events
        self.settings = settings
        self.dt = dt_s
        self.step_method = step_method
        self.dist = disturbances
        self.fallbacks = FallbackReporter(events)
        self.extensions = extensions  # extra ATO observation fields; an extension that drives some trains itself
        self.berths = Berths(trains, events, settings, self._coupled_behind, dt_s)  # railsim.engine.platforms
        self._plant_p: dict[int, tuple[Any, np.ndarray]] = {}  # plant kernel inputs per vehicle (_plant_packed)
        self._method_i = plant_kernel.method_index(step_method)
        self._forward = step_method == "forward"
        self._line_in: dict[str, tuple[Any, Any, Any, tuple[np.ndarray, np.ndarray, np.ndarray]]] = {}
        self._coupled_in: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # per follower: (CACC packed, its array)
        self._step: Any = self._first_step  # the compiled step, then its entry point (railsim.engine.kernel_entry)
        self._route_memo: dict[str, RouteSpans] = {}  # per train: its gradient and restriction window, kept

    # ------------------------------------------------------------------ observation
    def _situation(self, t: float, tr: TrainRuntime, a: Ahead | None, rear: tuple[float, float]) -> Situation:
        """What the train knows of itself now (noise drawn here, position then speed), see :class:`Situation`."""
        veh = tr.trip.vehicle
        stop, offset = self.stops.current(tr)
        own_pos = tr.front_m
        own_v = tr.plant.speed_mps
        if self.dist.position_sd_m > 0:
            own_pos += float(self.dist.noise_rng.normal(0.0, self.dist.position_sd_m))
        if self.dist.speed_sd_mps > 0:
            own_v = max(0.0, own_v + float(self.dist.noise_rng.normal(0.0, self.dist.speed_sd_mps)))
        view = tr.view
        front_m = tr.front_m
        tail_m = self.formations.tail_m(tr) if tr.train_id in self.formations.of_leader else 0.0  # a leader's only
        # a coupled formation runs like one long train: a restriction holds until its last unit's rear clears (the
        # ends move on by tail_m: the line ATO does it in its kernel, _base for the observation others get)
        from_m, to_m = front_m - veh.length_m - tail_m, front_m + self.settings.lookahead_m
        # the gradient and the restriction window, kept while the train stays where they hold (RouteView's spans)
        kept = self._route_memo.get(tr.train_id)
        if kept is None or kept.view is not view:
            kept = self._route_memo[tr.train_id] = RouteSpans(view)
        if not kept.grad_lo_m <= front_m < kept.grad_hi_m:
            kept.grad, kept.grad_lo_m, kept.grad_hi_m = view.gradient_span(front_m)
        grad = kept.grad
        if not (kept.from_lo_m <= from_m < kept.from_hi_m and kept.to_lo_m <= to_m < kept.to_hi_m):
            kept.limits, kept.from_lo_m, kept.from_hi_m, kept.to_lo_m, kept.to_hi_m = view.limits_window(from_m, to_m)
            kept.limits_arr = kernel_entry.checked_array(limits_array_cached(kept.limits), 2)
        limits = kept.limits
        # halted inside the window: hold until SUMO registers the stop (~1 s) and through the dwell
        target = None
        if stop is not None:
            target = (
                stop.mark_m - offset,
                stop.window_start_m,
                stop.window_end_m,
                tr.sumo_stopped or tr.halted_s is not None,
            )
        authority = self.locks.authority_end_m(tr)
        authority = self.berths.authority_end_m(t, tr, stop, a, authority)
        return Situation(own_pos, own_v, grad, limits, stop, target, authority, tail_m, kept.limits_arr, rear)

    def _coupled_behind(self, train_id: str, ahead_id: str) -> bool:
        """Is ``train_id`` coupling or coupled behind ``ahead_id`` (a formation partner in a coupled state), or on
        its way to couple behind it on departure (``FormationBook.joins``)?"""
        f = self.formations.of_follower.get(train_id)
        if f is None or not self.formations.partners(train_id, ahead_id):
            return False
        return self.formations.manager.state(f.id) in COUPLED_STATES or self.formations.joins(train_id, ahead_id)

    def _base(self, t: float, tr: TrainRuntime, sit: Situation) -> dict[str, Any]:
        """The fields every observation of this train shares this step."""
        own_pos, own_v, grad, limits, stop, target, authority, tail_m = (
            sit.own_pos_m, sit.own_v_mps, sit.grad, sit.limits, sit.stop, sit.target, sit.authority_m, sit.tail_m
        )  # fmt: skip
        veh = tr.trip.vehicle
        if tail_m > 0.0:  # every end moved on by the formation's length behind the front unit
            limits = tuple(SpeedLimit(lim.start_m, lim.end_m + tail_m, lim.speed_mps) for lim in limits)
        return dict(
            t_s=t,
            dt_s=self.dt,
            own=OwnState(tr.train_id, own_pos, own_v, tr.plant.applied_accel_mps2, veh.length_m, grad),
            vehicle=veh,
            route_length_m=tr.view.length_m,
            speed_limits=limits,
            line_speed_mps=tr.view.line_speed_mps,
            next_stop=None if stop is None or target is None else StopTarget(stop.station_id, *target),
            authority_end_m=authority,
        )

    # ------------------------------------------------------------------ the decision
    def control_all(
        self,
        t: float,
        active: list[TrainRuntime],
        ahead: Mapping[str, Ahead | None],
        rears: Sequence[tuple[float, float]] | None = None,
    ) -> list[float]:
        """Decide every active train's command and step its plant; return the speeds handed to SUMO for the coming
        step, in the order of ``active``.

        The one place where trains' commands are decided (module docstring, "One decision, one compiled step for
        the common case"): first every train's situation at ``t`` — what it knows of itself (sensor noise drawn
        train by train) and of the line ahead, the berth rule reading the trains ahead as they are at ``t``, so no
        train's situation depends on whether the train ahead was stepped before it — then, train by train in
        order, the roles that command it now and the compiled line step for a line train or the roles one by one
        for any other, each ending in arbitration and the plant step. ``rears``: what the ground reports of the
        train ahead of each (:meth:`Knowledge.ground_rears`, in the order of ``active``); None: asked train by
        train."""
        rears = rears if rears is not None else [ASK] * len(active)
        sits = [self._situation(t, tr, ahead[tr.train_id], rear) for tr, rear in zip(active, rears)]
        drivers = bool(self.extensions.overriding("drives"))  # (asked once a step, not train by train)
        return [self._decide(t, tr, ahead[tr.train_id], sit, drivers) for tr, sit in zip(active, sits)]

    def _decide(self, t: float, tr: TrainRuntime, a: Ahead | None, sit: Situation, drivers: bool) -> float:
        """One train's roles now, then its command and plant step; the speed for SUMO. ``drivers``: an installed
        extension may drive trains (:meth:`ExtensionSet.driver_of` is asked)."""
        f = self.formations.of_follower.get(tr.train_id)
        fstate = self.formations.manager.state(f.id) if f is not None else "free"
        leader = self.formations.leader_of(f) if f is not None else None
        ato = tr.controllers["ato"]
        if fstate in COUPLED_STATES and tr.controllers.get("ato_closing") is not None and not tr.degraded:
            ato = tr.controllers["ato_closing"]
        # an extension flying a plan for this train, or None
        driver = self.extensions.driver_of(tr.train_id) if drivers else None
        vc_role = (
            f is not None
            and fstate in COUPLED_STATES
            and leader is not None
            and (leader.on_line or leader.status == "arrived")  # arrived this step: it stands there, still ahead
            and tr.controllers.get("coupled") is not None
        )
        if driver is None and self._is_line_train(tr, a, ato):
            if not vc_role:
                return self._line_step(t, tr, a, ato, sit)
            if type(tr.controllers["coupled"]) is Cacc:
                assert f is not None and leader is not None
                return self._coupled_step(t, tr, a, ato, sit, f, leader)
        commands = self._role_commands(t, tr, a, sit, ato, driver, vc_role, fstate, f, leader)
        return self._finish(t, tr, commands, sit.grad)

    def _is_line_train(self, tr: TrainRuntime, a: Ahead | None, ato: Any) -> bool:
        """No formation role and no plan flown (the caller checked), the line ATO, the line separation if a train is
        ahead, no collision avoidance, the standard plant and no actuator fault: the compiled line step decides."""
        return (
            type(ato) is Ato
            and (a is None or type(tr.controllers["separation"]) is Separation)
            and tr.exact_plant is None
            and tr.controllers.get("ca") is None
            and not self.dist.biases  # no injected actuator bias and no actuator noise (drawn in _apply) on it
            and not (self.dist.actuator_sd_mps2 > 0.0 and self._actuator_noise_on(tr))
        )

    def _role_commands(
        self,
        t: float,
        tr: TrainRuntime,
        a: Ahead | None,
        sit: Situation,
        ato: Any,
        driver: Any,
        vc_role: bool,
        fstate: str,
        f: Any,
        leader: TrainRuntime | None,
    ) -> dict[str, Command]:
        """Every role's command, the ATO's first (it wins a tie). The line controllers
        (:class:`~controllers.ato.Ato`, :class:`~controllers.separation.Separation`) are asked on plain values
        (their ``decide``); every other controller gets its :class:`Observation`, built from the same values
        (``base``, only when one is needed)."""
        own_pos, own_v, grad, limits, target, authority, tail_m = (
            sit.own_pos_m, sit.own_v_mps, sit.grad, sit.limits, sit.target, sit.authority_m, sit.tail_m
        )  # fmt: skip
        veh = tr.trip.vehicle
        applied_now = tr.plant.applied_accel_mps2
        base: dict[str, Any] | None = None
        commands: dict[str, Command] = {}
        if type(ato) is Ato:  # the line ATO reads no extras
            accel, emergency, phase = ato.decide(
                veh,
                self.dt,
                own_pos,
                own_v,
                applied_now,
                veh.length_m,
                grad,
                tr.view.line_speed_mps,
                limits,
                target,
                authority,
                tail_m,
            )
            commands["ato"] = Command(accel, emergency=emergency, info={"phase": phase})
        else:
            base = self._base(t, tr, sit)
            commands["ato"] = ato.command(Observation(**base, extras=self.extensions.ato_extras(t, tr)))

        if driver is not None:  # the plan's commands stand in for the other roles
            base = base or self._base(t, tr, sit)
            driver.commands(t, tr, a, base, commands, own_pos, own_v, fstate)
            return commands
        used_vc = False
        if vc_role:
            assert f is not None and leader is not None
            used_vc = self._coupled(t, tr, f, fstate, leader, sit, base, commands)
        if a is not None and not (used_vc and leader is not None and a.train_id == leader.train_id):
            sep = tr.controllers["separation"]
            if type(sep) is Separation:
                known = self._known_rear(tr, a, sit)
                if known is not None:
                    commands["separation"] = sep.decide(veh, self.dt, own_pos, own_v, applied_now, grad, *known)
            else:
                pred = self.knowledge.known_state(tr, self.trains[a.train_id], "t2g", "ground", ahead=True)
                if pred is not None:
                    tr.stale_max_s = max(tr.stale_max_s, pred.age_s)
                    base = base or self._base(t, tr, sit)
                    commands["separation"] = sep.command(Observation(**base, predecessor=pred, formation_state=fstate))
        ca_ctl = tr.controllers.get("ca")
        if ca_ctl is not None:  # collision avoidance on the train's own sensor: works with the radio down
            self._collision_avoidance(t, tr, a, ca_ctl, base or self._base(t, tr, sit), fstate, commands)
        return commands

    def _known_rear(self, tr: TrainRuntime, a: Ahead, sit: Situation) -> tuple[float, float] | None:
        """The rear of the train ahead and the age of that knowledge at the step's time, as the ground reports it
        (all that moving-block separation reads): the situation's (:meth:`Knowledge.ground_rears`), or asked of the
        knowledge here where that pass has none (a NaN rear, :data:`~railsim.engine.knowledge.ASK`); the train's
        staleness record follows it."""
        known: tuple[float, float] | None = sit.rear
        if sit.rear[0] != sit.rear[0]:  # NaN: ask
            known = self.knowledge.known_rear_age(tr, self.trains[a.train_id], "t2g", "ground", ahead=True)
        if known is not None and known[1] > tr.stale_max_s:
            tr.stale_max_s = known[1]
        return known

    def _coupled(
        self,
        t: float,
        tr: TrainRuntime,
        f: Any,
        fstate: str,
        leader: TrainRuntime,
        sit: Situation,
        base: dict[str, Any] | None,
        commands: dict[str, Command],
    ) -> bool:
        """The coupled controller on t2t data if fresh enough; degrade/restore events. True if it commanded.
        The CACC is asked on plain values (:meth:`controllers.cacc.Cacc.decide`); any other coupled controller gets
        its :class:`Observation` (built from ``base``, made here if the caller has none yet)."""
        pred = self._leader_state(t, tr, leader)
        if pred is None:
            return False
        tracking = self._vc_tracking(tr)
        ctl = tr.controllers["coupled"]
        if type(ctl) is Cacc:
            own_pos, own_v, grad = sit.own_pos_m, sit.own_v_mps, sit.grad
            applied_now = tr.plant.applied_accel_mps2
            vc_cmd = ctl.decide(
                tr.trip.vehicle, self.dt, own_pos, own_v, applied_now, grad, pred, float(f.target_gap_m), tracking
            )
        else:
            obs = Observation(
                **(base or self._base(t, tr, sit)),
                predecessor=pred,
                formation_state=fstate,
                target_gap_m=float(f.target_gap_m),
                extras={} if tracking else {"vc_tracking": False},
            )
            vc_cmd = ctl.command(obs)
        commands["coupled"] = vc_cmd
        self._vc_commanded(t, tr, leader, pred, vc_cmd.info or {})
        return True

    def _leader_state(self, t: float, tr: TrainRuntime, leader: TrainRuntime) -> PredecessorState | None:
        """The leader's state from t2t data if fresh enough for the coupled role, else None (and ``vc_degraded``
        when the follower was not degraded yet)."""
        pred = self.knowledge.known_state(tr, leader, "t2t", tr.train_id)
        # hysteresis: degrade when the leader's data is older than max_message_age_s, restore only once it is at
        # least one step fresher (a delay equal to the limit would otherwise flip the mode every step)
        age_limit = self.settings.max_message_age_s - (self.dt if tr.degraded else 0.0)
        if pred is not None and pred.age_s <= age_limit:
            return pred
        if not tr.degraded:
            tr.degraded = True
            self.events.record(t, "vc_degraded", tr.train_id, age_s=None if pred is None else round(pred.age_s, 3))
        return None

    def _vc_tracking(self, tr: TrainRuntime) -> bool:
        """Does the coupled controller track its gap now? Not when both units stop at this platform: the ATO stops
        the follower exactly behind the leader's mark and the coupled controller keeps only its safety cap (its
        slow gap loop would halt the follower short)."""
        stop, offset = self.stops.current(tr)
        return not (stop is not None and offset > 0.0 and self.formations.in_final_approach(tr, stop.mark_m - offset))

    def _vc_commanded(
        self, t: float, tr: TrainRuntime, leader: TrainRuntime, pred: PredecessorState, info: Mapping[str, Any]
    ) -> None:
        """What the coupled controller's command leaves on the train (solve time, objective, effective target gap,
        staleness) and its events (a leader's plan used/lost; ``vc_restored``)."""
        tr.vc_solve_s = float(info["solve_time_s"]) if info.get("solve_time_s") is not None else None
        tr.vc_objective = float(info["J"]) if info.get("J") is not None else None
        tgt = info.get("target_gap_m")
        tr.vc_target_gap_m = float(tgt) if tgt is not None else None
        tr.stale_max_s = max(tr.stale_max_s, pred.age_s)
        if info.get("event") in PLAN_EVENTS:  # the follower stopped/restarted using its leader's t2t plan
            self.events.record(t, info["event"], tr.train_id, leader=leader.train_id, age_s=info.get("plan_age_s"))
        if tr.degraded:
            tr.degraded = False
            self.events.record(t, "vc_restored", tr.train_id)

    def _collision_avoidance(
        self,
        t: float,
        tr: TrainRuntime,
        a: Ahead | None,
        ca_ctl: Any,
        base: dict[str, Any],
        fstate: str,
        commands: dict[str, Command],
    ) -> None:
        sensor = self.safety.sensor(tr, a)
        # what the other roles command (their minimum): an additive CA plans its braking on top of it (A27)
        sensor["service_accel_mps2"] = min(c.accel_mps2 for c in commands.values())
        ca_cmd = ca_ctl.command(Observation(**base, extras={"sensor": sensor}, formation_state=fstate))
        commands["ca"] = ca_cmd
        event = ca_cmd.info.get("event") if ca_cmd.info else None
        if event in ("ca_on", "ca_off"):
            gap = float(ca_cmd.info.get("gap_m", INF))
            self.events.record(
                t,
                "ca_trigger" if event == "ca_on" else "ca_release",
                tr.train_id,
                gap_m=round(gap, 3) if math.isfinite(gap) else None,
                trigger_m=ca_cmd.info.get("trigger_m"),
            )

    # ------------------------------------------------------------------ the compiled line step
    def _line_step(self, t: float, tr: TrainRuntime, a: Ahead | None, ato: Ato, sit: Situation) -> float:
        """A line train's decision, arbitration and plant step in one compiled call
        (:func:`railsim.engine.line_step_kernel.step`, no coupled role): the line ATO, then the line separation
        against the known rear of the train ahead, the smaller acceleration winning (the ATO on a tie, as
        :func:`controllers.base.arbitrate`), then the plant. It is what :meth:`_role_commands` and :meth:`_finish`
        would do for these two roles — neither law falls back, adds, or carries a plan — on the same values. A
        non-finite winning command comes back unstepped and goes to :meth:`_apply`, which records it and brakes."""
        known = self._known_rear(tr, a, sit) if a is not None else None
        out = self._step(*self._line_args(tr, ato, sit, known, line_step_kernel.NO_COUPLED))
        return self._stepped(t, tr, out, sit.grad)

    def _coupled_step(
        self, t: float, tr: TrainRuntime, a: Ahead | None, ato: Ato, sit: Situation, f: Any, leader: TrainRuntime
    ) -> float:
        """A coupled follower whose coupled role is the CACC, otherwise a line train (:meth:`_is_line_train`), in
        the same compiled call as a line train, with its coupled role's inputs: the ATO, the CACC on the leader's
        t2t state, the separation against a train between them, the minimum in that order, the plant — what
        :meth:`_role_commands` (with :meth:`_coupled`) and :meth:`_finish` would do on the same values. With its
        leader's data too old the follower is degraded and steps as a line train."""
        pred = self._leader_state(t, tr, leader)
        if pred is None:
            return self._line_step(t, tr, a, ato, sit)
        tracking = self._vc_tracking(tr)
        ctl: Cacc = tr.controllers["coupled"]
        veh = tr.trip.vehicle
        coupled = self._coupled_inputs(tr, ctl.packed(veh, self.dt))
        line_step_kernel.set_lead(coupled, pred, ctl.feed_forward_mps2(pred, veh), float(f.target_gap_m), tracking)
        known = self._known_rear(tr, a, sit) if a is not None and a.train_id != leader.train_id else None
        out = self._step(*self._line_args(tr, ato, sit, known, coupled))
        self._vc_commanded(t, tr, leader, pred, {"target_gap_m": out[9]})
        return self._stepped(t, tr, out, sit.grad)

    def _coupled_inputs(self, tr: TrainRuntime, cacc_p: np.ndarray) -> np.ndarray:
        """The follower's coupled-role array for the compiled step (:func:`line_step_kernel.coupled_inputs`), kept
        per train and made anew when its CACC packs its law anew (another vehicle or step length)."""
        entry = self._coupled_in.get(tr.train_id)
        if entry is None or entry[0] is not cacc_p:
            arr = kernel_entry.checked_array(line_step_kernel.coupled_inputs(cacc_p), 1)
            entry = self._coupled_in[tr.train_id] = (cacc_p, arr)
        return entry[1]

    def _first_step(self, *args: Any) -> tuple[Any, ...]:
        """The run's first compiled step, through the dispatcher; later ones call its entry point if they can."""
        out = line_step_kernel.step(*args)
        self._step = kernel_entry.direct(line_step_kernel.step, args, line_step_kernel.SIGNATURE)
        return out

    def _line_args(
        self, tr: TrainRuntime, ato: Ato, sit: Situation, known: tuple[float, float] | None, coupled: np.ndarray
    ) -> tuple[Any, ...]:
        """The inputs of :func:`~railsim.engine.line_step_kernel.step`: the packed laws and plant, the situation,
        the plant state, the known rear of the train ahead, and the coupled role's inputs (``NO_COUPLED``: none)."""
        target = sit.target
        authority = sit.authority_m
        veh = tr.trip.vehicle
        plant = tr.plant
        ato_p, sep_p, plant_p = self._line_inputs(tr, ato, veh)
        mark_m, window_start_m, window_end_m, dwelling = target if target is not None else NO_STOP
        rear_m, age_s = known if known is not None else (0.0, 0.0)
        return (
            ato_p,
            sep_p if known is not None else _NO_PACK,
            plant_p,
            self._method_i,
            self.dt,
            sit.own_pos_m,
            sit.own_v_mps,
            plant.speed_mps,
            plant.applied_accel_mps2,
            plant.target_accel_mps2,
            veh.length_m,
            sit.grad,
            tr.view.line_speed_mps,
            sit.limits_arr,
            target is not None,
            mark_m,
            window_start_m,
            window_end_m,
            dwelling,
            authority is not None,
            authority if authority is not None else 0.0,
            sit.tail_m,
            known is not None,
            rear_m,
            age_s,
            coupled,
        )

    def _stepped(self, t: float, tr: TrainRuntime, out: tuple[Any, ...], grad: float) -> float:
        """A compiled step's result kept: the winning role's emergency events and the plant's step (:meth:`_commit`);
        a non-finite command goes to :meth:`_apply` (recorded, braked)."""
        accel, emergency, role_i, ok, v_next, a_k, u_k, energy_j, mask = out[:9]
        role = line_step_kernel.ROLES[role_i]
        if not ok:
            return self._apply(t, tr, role, accel, emergency, None, grad)  # non-finite: recorded, braked
        if emergency or tr.emergency_since_s is not None:
            self._emergency_events(t, tr, role, emergency)
        tr.last_plan = None
        return self._commit(tr, role, accel, v_next, a_k, u_k, energy_j, mask)

    def _line_inputs(self, tr: TrainRuntime, ato: Ato, veh: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The compiled line step's inputs that change only with the train's controllers or vehicle: the packed
        ATO, separation (when it is the line law) and plant. Remembered per train, checked by the identity of what
        they were packed from, so a controller or vehicle handed to the train later is packed anew."""
        sep = tr.controllers.get("separation")
        entry = self._line_in.get(tr.train_id)
        if entry is None or entry[0] is not ato or entry[1] is not sep or entry[2] is not veh:
            sep_p = sep.packed(veh, self.dt) if type(sep) is Separation else _NO_PACK
            arr = kernel_entry.checked_array
            packed = (arr(ato.packed(veh, self.dt), 1), arr(sep_p, 1), arr(self._plant_packed(veh), 1))
            entry = self._line_in[tr.train_id] = (ato, sep, veh, packed)
        return entry[3]

    def _plant_packed(self, veh: Any) -> np.ndarray:
        """The plant kernel's packed vehicle for this run's step (once per vehicle)."""
        packed = self._plant_p.get(id(veh))
        if packed is None or packed[0] is not veh:
            packed = self._plant_p[id(veh)] = (veh, plant_kernel.pack(veh, self.dt))
        return packed[1]

    # ------------------------------------------------------------------ actuator faults
    def _actuator_noise_on(self, tr: TrainRuntime) -> bool:
        """Is actuator noise drawn for this train's command (scenario ``faults.actuator_noise``)?"""
        noise_trains = self.dist.actuator_trains
        return self.dist.actuator_sd_mps2 > 0.0 and (noise_trains is None or tr.train_id in noise_trains)

    # ------------------------------------------------------------------ arbitration and plant
    def _finish(self, t: float, tr: TrainRuntime, commands: dict[str, Command], grad: float) -> float:
        """Arbitrate the roles' commands (minimum, or additive) and advance the plant; returns the speed for SUMO."""
        veh = tr.trip.vehicle
        for r, c in commands.items():  # every role's fallback counts, not only the winner's
            if c.fallback:
                tr.fallbacks += 1
                self.fallbacks.report(t, tr.train_id, r, _controller_name(tr, r), fallback_reason(c))
        role, cmd = arbitrate(commands, veh.emergency_decel_mps2)  # an additive role stops at the brake envelope
        return self._apply(t, tr, role, cmd.accel_mps2, cmd.emergency, cmd, grad)

    def _apply(
        self, t: float, tr: TrainRuntime, role: str, accel: float, emergency: bool, cmd: Command | None, grad: float
    ) -> float:
        """The winning command (``accel``/``emergency``; ``cmd`` itself when there is one, for its plan and an
        exact plant): emergency-brake events, the non-finite guard, actuator noise and biases, the plant step."""
        veh = tr.trip.vehicle
        self._emergency_events(t, tr, role, emergency)
        if not math.isfinite(accel):
            self.events.record(t, "controller_nan", tr.train_id, role=role)
            log.error("%s: %s controller returned %r; braking", tr.train_id, role, accel)
            reason = f"non-finite command {accel!r}; service brake"
            cmd = Command(-veh.service_decel_mps2, fallback=True)
            accel, emergency = cmd.accel_mps2, cmd.emergency
            tr.fallbacks += 1
            self.fallbacks.report(t, tr.train_id, role, _controller_name(tr, role), reason)
        if tr.exact_plant is not None:
            return tr.exact_step(t, role, cmd or Command(accel, emergency=emergency), grad, self.dt)
        u = accel
        if self._actuator_noise_on(tr):
            u += float(self.dist.actuator_rng.normal(0.0, self.dist.actuator_sd_mps2))  # the papers' disturbance
        if self.dist.biases:
            u = self.dist.biased(t, tr.train_id, u)  # a faulty actuator (injected fault, logged at start)
        plan = cmd.info.get("plan") if cmd is not None and cmd.info else None
        tr.last_plan = {"t0_s": t, **plan} if plan else None  # entry 0 = decision time unless the plan says so
        v_next, a, u_k, _, _, energy_j, mask = dynamics.step_values(
            veh, tr.plant, u, self.dt, grad, emergency, self.step_method
        )
        return self._commit(tr, role, accel, v_next, a, u_k, energy_j, mask)

    def _emergency_events(self, t: float, tr: TrainRuntime, role: str, emergency: bool) -> None:
        """An emergency-braking interval's start and end, as events."""
        if emergency and tr.emergency_since_s is None:
            tr.emergency_since_s = t
            self.events.record(t, "emergency_brake_on", tr.train_id, role=role)
        elif not emergency and tr.emergency_since_s is not None:
            self.events.record(
                t, "emergency_brake_off", tr.train_id, role=role, duration_s=round(t - tr.emergency_since_s, 3)
            )
            tr.emergency_since_s = None

    def _commit(
        self, tr: TrainRuntime, role: str, accel: float, v_next: float, a: float, u_k: float, energy_j: float, mask: int
    ) -> float:
        """Keep the plant step's result (jerk, state, energy, saturations, role); return the speed for SUMO."""
        plant = tr.plant
        v_now = plant.speed_mps
        jerk = abs(a - plant.applied_accel_mps2) / self.dt
        if jerk > tr.max_jerk_mps3:  # (max(): the same, without the call)
            tr.max_jerk_mps3 = jerk
        tr.plant = dynamics.PlantState(v_next, a, u_k)
        tr.energy_j += energy_j
        if mask:
            for s in dynamics.flags_from_mask(mask):
                tr.saturations[s] = tr.saturations.get(s, 0) + 1
        tr.last_role = role
        tr.last_cmd_mps2 = accel
        # what SUMO moves the train by during the coming step: Euler/ballistic take the new speed; the papers'
        # explicit Euler x(k+1) = x(k) + T·v(k) ("forward") needs the speed *before* the update (spec 002 §7.3)
        tr.sent_speed_mps = v_now if self._forward else v_next
        return tr.sent_speed_mps


def _controller_name(tr: TrainRuntime, role: str) -> str:
    """The class of the controller that plays ``role`` for ``tr`` (the role's name when none is registered)."""
    ctl = tr.controllers.get(role)
    return type(ctl).__name__ if ctl is not None else role
