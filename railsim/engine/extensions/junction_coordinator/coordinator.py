"""Online junction coordination: the cooperative-game planner driving trains through a SUMO Y-junction.

Paper E (spec 004) plans, at one instant, how two or three trains on converging tracks should accelerate so
that they pass the switches in a safe order and arrive at the coupling point F as a virtually coupled platoon.
:mod:`controllers.junction` is that planner as a pure function (states in, :class:`JunctionPlan` out). This
module is the *ground side* that runs it inside the engine (spec 004 §7, the readings we chose are marked):

1. **Trigger.** The plan is made at the first step at which every train named in the scenario's
   ``junction.trains`` is on the line. Inputs are what the ground knows: each train's last t2g report,
   extrapolated at constant speed to now (the insertion state before the first report), and the switch
   positions from the interlocking.
2. **Distances.** Each train's path is read from its route: which leg it takes at ``sw1``/``sw2`` and how far its
   front is from each switch. *Reading:* the planner's "switch" is the **start of the turnout speed restriction**
   in front of the switch point (where the leg limit of 15/10 m/s begins on the track), so that a plan passing
   the switch at ≤ the leg limit also keeps the limit over the turnout that SUMO and our ATO enforce.
   ``S4``/``S5`` follow from the same points and F.
3. **Execution.** Each train tracks its plan on board: the reference ``(s, v, a)(τ)`` is the plan's
   acceleration-over-distance profile integrated from the plan instant; the command is
   ``a_ref + k_v (v_ref − v) + k_s (s_ref − s)`` (``k_v`` = 1 /s, ``k_s`` = 0.25 /s², a critically damped
   tracking loop), clipped to the planner's ``[a_min, a_max]``. It is arbitrated (minimum) with the train's ATO,
   which keeps line/turnout speed limits, the platform stop and the movement authority of the interlocking.
   The command is the net acceleration made applied (:meth:`railsim.physics.vehicle.VehicleParams.net_to_applied`:
   running resistance and gradient added back), so a unit with Davis resistance flies the plan's accelerations
   and the platoon leader past F holds its speed instead of coasting down.
   Against the train ahead, planned trains use the coupled controller's **relative-braking-distance safety cap**
   only (``vc_tracking = False``), not moving-block separation: the plan itself brings them to metres apart.
4. **Switches.** The locks of ``sw1``/``sw2`` for planned trains are requested by this coordinator, not by the
   engine's distance rule, **in the plan's passing order**; consecutive trains on the same leg share one group
   lock (so a follower 10 m behind is not stopped by its leader's release). The interlocking's throw time
   (10 s) and FIFO service are unchanged. Before the order freezes a re-plan that changes the order cancels the
   not-yet-granted requests and re-queues them.
5. **Re-planning** every ``replan_s`` seconds and at once when a train deviates from its reference by more than
   5 m or 0.5 m/s (spec §7.3), warm-started from the previous plan. The passing order is **frozen** once any
   train is within its service braking distance of a switch ahead (the planner's point of no return); then the
   formations are formed in that order (each train follows the one before it at the planner's standstill gap
   ``S_0``, or ``junction.target_gap_m``) and asked to couple. With ``junction.fixed_order`` the order is the
   listed one from the first plan on (a formation's leader first: the planner does not choose it), so it is
   frozen and the formations are formed at once. *Reading:* our planner cannot keep a train that
   is past the merge switch in the game, so re-planning stops when the first train passes ``sw2``; the rest is
   closed-loop tracking of the last plan.
6. **Hand-over.** A train whose front reaches F leaves the plan: the leader continues on its ATO, followers on
   the coupled controller of their formation (spec §7 "after coupling, hand the followers over").
7. **Naive baselines** (``naive1`` closest-first, ``naive2`` fastest-first, spec §4.2) use the same machinery
   with a rule instead of a plan: locks in priority order, each train runs towards the limit speed of its next
   switch (the braking curve of :func:`controllers.junction.baselines.approach_speed_cap`) and waits for its
   lock through the interlocking's movement authority.

``qp_order`` (:mod:`controllers.junction.qp`) differs where SUMO runs showed missed couplings: its model
is the engine's (:func:`.readings.engine_corrected_params`, :func:`.readings.interlocking_model`,
turnouts held over the train's length, approached inside the ATO's envelope); a granted lock fixes the order at
its switch; the reference is the plan's exact trajectory from the planner's initial state; followers fly the plan in
the leader's time (:func:`.tracking.leader_time_reference`); it re-plans on deviations, to polish an
unconverged first plan, and once when the order freezes (no periodic re-plans).

Measured outcome: the coordinator records every planned train's path position and speed at every step from
the first plan on and scores them with :func:`controllers.junction.simulate.measure` — the same code that
scores the numpy reproduction — so "coupled at F" means the spec's Eq. 2–3 at the moment the leader reaches F.
Plans are deterministic for a seed: the PSO gets its own generator drawn from the run's seed and no wall-time
cap (the benchmark, not the run, measures planner time).
"""

from __future__ import annotations

import dataclasses
import logging
import math
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from controllers.base import Command, Observation
from controllers.junction import baselines
from controllers.junction.model import JunctionParams, SwitchState
from controllers.junction.planner import (
    OPTIMISERS,
    JunctionPlan,
    PlannerError,
    TrainState,
    YJunctionLayout,
    build_problem,
    past_point_of_no_return,
    plan,
    replan,
)
from controllers.junction.pso import improved_pso_params, plain_pso_params
from controllers.junction.qp import QpOrderParams
from controllers.junction.simulate import measure
from railsim.engine.extensions.base import Extension
from railsim.engine.extensions.context import ExtensionContext
from railsim.engine.extensions.junction_coordinator.ground import SWITCHES, ground_front, ground_states, switch_states
from railsim.engine.extensions.junction_coordinator.readings import (
    engine_corrected_params,
    interlocking_model,
    safe_gap_m,
    switch_interval_s,
    turnout_start,
)
from railsim.engine.extensions.junction_coordinator.tracking import PlannedTrain, leader_time_reference
from railsim.errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    from railsim.engine.events.interlocking import Leg
    from railsim.engine.occupancy import Ahead
    from railsim.engine.train import TrainRuntime
    from railsim.scenario import Scenario

log = logging.getLogger(__name__)

K_V_PER_S = 1.0  # tracking gains (critically damped double integrator, ω = 0.5 rad/s)
K_S_PER_S2 = 0.25
DEVIATION_M = 5.0  # re-plan at once beyond these tracking errors (spec §7.3)
DEVIATION_MPS = 0.5
MIN_REPLAN_GAP_S = 0.5
POLISH_REPLANS = 3  # qp_order: warm re-plans finishing a first plan (unlimited: 5/30 scenario-2 runs drifted 7-16 m)
# qp_order plans stay inside the ATO's envelope (its speed law a = 0.4/s·(v_target − v) lags its targets):
ATO_CRUISE_MARGIN_MPS = 3.0  # below v_max, where the law caps full acceleration
APPROACH_HOLD_M = 20.0  # at the turnout speed this far before a turnout (braking into it at half the ATO's rate)


class JunctionCoordinator(Extension):
    """The ground-side junction planner of one scenario (see the module docstring)."""

    summary_key = "junction"

    @classmethod
    def applies(cls, scenario: Scenario) -> bool:
        """The junction planner runs online when the scenario has a ``junction:`` section."""
        return scenario.junction is not None

    def __init__(self, ctx: ExtensionContext) -> None:
        spec = ctx.scenario.junction
        if spec is None:
            raise ValueError("the junction coordinator needs the scenario's junction: section")
        super().__init__(ctx)
        self.spec = spec
        self.method: str = spec.method
        src = ctx.scenario.source
        self.members: dict[str, PlannedTrain] = {}
        lengths = []
        for i, tid in enumerate(spec.trains):
            tr = ctx.trains[tid]
            self.members[tid] = self._member(tr, f"junction.trains[{i}]")
            lengths.append(tr.trip.vehicle.length_m)
        legs2 = {m.legs["sw2"] for m in self.members.values() if "sw1" not in m.legs}
        trunk2 = {m.legs["sw2"] for m in self.members.values() if "sw1" in m.legs}
        if len(legs2) > 1 or len(trunk2) > 1 or (legs2 and trunk2 and legs2 == trunk2):
            raise ConfigError(src, "junction.trains", "trains joining at sw2 must come from two tracks, one per leg")
        branch2 = next(iter(legs2)) if legs2 else ("normal" if trunk2 == {"reverse"} else "reverse")
        ref = next((m for m in self.members.values() if "sw1" in m.legs), None)
        any_m = next(iter(self.members.values()))
        s4 = (ref.switch_m["sw2"] - ref.switch_m["sw1"]) if ref is not None else 200.0
        s5 = any_m.F_m - any_m.switch_m["sw2"]
        self.layout = YJunctionLayout(S4_m=s4, S5_m=s5, sw1_branch_leg="reverse", sw2_branch_leg=branch2)  # type: ignore[arg-type]
        throw_s = max(ctx.switch_throw_s[sid] for sid in SWITCHES if sid in ctx.switch_throw_s)
        try:
            probe = JunctionParams(**{"pred_length_m": max(lengths), **spec.params})
            if "standstill_gap_m" not in spec.params:
                probe = dataclasses.replace(
                    probe,
                    standstill_gap_m=max(
                        probe.standstill_gap_m, safe_gap_m(ctx, list(self.members), probe.normal_speed_mps)
                    ),
                )
            self.switch_interval_s = switch_interval_s(
                ctx.settings, self.members.values(), probe, throw_s, max(lengths)
            )
            self.params = (
                dataclasses.replace(probe, throw_time_s=self.switch_interval_s)
                if "throw_time_s" not in spec.params
                else probe
            )
            self.qp: QpOrderParams | None = None
            if self.method == "qp_order":
                # the model the engine flies: the guard of the followers' CACC, the turnout zone, the interlocking
                self.params = engine_corrected_params(ctx, list(self.members), self.params, spec.params)
                il = interlocking_model(ctx, list(self.members), self._turnout_m(), max(lengths), throw_s)
                self.qp = QpOrderParams(
                    zone_m=self._turnout_m() + max(lengths),
                    # inside the ATO's envelope: its braking curve into a turnout and its cruise law below v_max
                    approach_decel_mps2=0.5 * il.brake_decel_mps2,
                    approach_hold_m=APPROACH_HOLD_M,
                    line_speed_margin_mps=ATO_CRUISE_MARGIN_MPS,
                    interlocking=il,
                )
            base = improved_pso_params() if self.method != "plain_pso" else plain_pso_params()
            # the first plan may take longer (1000 iterations, ~0.4 s); re-plans keep the online budget (200)
            self.pso = dataclasses.replace(base, **{"max_iterations": 1000, **spec.pso})
            self.replan_pso = dataclasses.replace(self.pso, **{"max_iterations": 200, **spec.replan_pso})
        except ValueError as exc:
            raise ConfigError(src, "junction.params", str(exc)) from None
        self.target_gap_m = float(spec.target_gap_m if spec.target_gap_m is not None else self.params.standstill_gap_m)
        self.rng = np.random.default_rng(ctx.draw_seed())  # the planner's own stream
        self.plan: JunctionPlan | None = None
        self.problem0: Any = None
        self.t0_s: float | None = None
        self.order: tuple[str, ...] = ()
        self.frozen = False
        self.formed = False
        self.formed_s = math.nan
        self.replanning = self.method in OPTIMISERS
        self.last_plan_s = -math.inf
        self.polishes = 0  # qp_order polishing re-plans made
        self.plans: list[dict[str, Any]] = []
        self.traj_t: list[float] = []
        self.traj_s: list[list[float]] = []
        self.traj_v: list[list[float]] = []
        self.requests: dict[str, list[Any]] = {sid: [] for sid in SWITCHES}
        self.handover_s: dict[str, float] = {}

    # ------------------------------------------------------------------ set-up
    def _member(self, tr: TrainRuntime, where: str) -> PlannedTrain:
        route = tr.trip.route
        src = self.ctx.scenario.source
        points = {rs.switch_id: rs for rs in route.switches if rs.switch_id in SWITCHES}
        F = [p.point_m for p in route.points if p.point_id == "F"]
        if "sw2" not in points or not F:
            raise ConfigError(
                src,
                where,
                f"{tr.train_id}: the junction planner needs a route through switch sw2 "
                f"to point F (the y_junction world); route {route.id} has "
                f"switches {[rs.switch_id for rs in route.switches]}",
            )
        switch_m = {sid: turnout_start(tr, rs.point_m) for sid, rs in points.items()}
        return PlannedTrain(
            tr.train_id,
            switch_m,
            {sid: rs.leg for sid, rs in points.items()},
            {sid: rs.point_m for sid, rs in points.items()},
            F[0],
        )

    def _turnout_m(self) -> float:
        """Length of the turnout speed restriction in front of the switch points (the planner's switch lies there)."""
        return max((m.point_m[sid] - m.switch_m[sid] for m in self.members.values() for sid in m.legs), default=0.0)

    # ------------------------------------------------------------------ queries from the engine
    def manages_lock(self, train_id: str, switch_id: str) -> bool:
        """True if this coordinator (not the engine's distance rule) requests ``switch_id`` for ``train_id``."""
        m = self.members.get(train_id)
        return m is not None and switch_id in m.legs

    def drives(self, train_id: str) -> bool:
        """True while the junction role drives this train: until it reaches F, and for the platoon's leader until
        the last train has reached F (it holds its speed there so that the platoon closes up behind it)."""
        m = self.members.get(train_id)
        if m is None:
            return False
        if not m.handed_over:
            return True
        if self.fixed_order_coupled():
            return False  # the platoon is coupled: nothing left to hold the speed for (its ATO stops it at its halt)
        return bool(self.order) and train_id == self.order[0] and not all(x.handed_over for x in self.members.values())

    def fixed_order_coupled(self) -> bool:
        """With ``junction.fixed_order`` (a formation coupling before its leader's stop): every formation the
        coordinator formed is coupled. The PSO methods and the paper's runs keep the leader's hold until the last
        train has reached F."""
        if not (self.spec.fixed_order and self.formed):
            return False
        man = self.ctx.formations.manager
        ids = [f for f in man.ids() if f.startswith("junction_")]
        return bool(ids) and all(man.state(f) == "coupled" for f in ids)

    def command(self, t: float, tr: TrainRuntime, own_pos_m: float, own_v_mps: float) -> float | None:
        """The junction role's acceleration for a planned train (None before the first plan)."""
        m = self.members[tr.train_id]
        p = self.params
        if m.handed_over:
            return 0.0  # the platoon leader past F: hold the coupled speed until the others are through
        if self.plan is None and self.method in OPTIMISERS:
            return None
        if self.method in ("naive1", "naive2"):
            return m.naive_command(p, own_pos_m, own_v_mps, self.ctx.dt_s)
        s_ref, v_ref, rate = self._reference(m, t)
        s = own_pos_m - m.ref_front_m
        a_ff = m.accel_at(s_ref) * rate * rate
        u = a_ff + K_V_PER_S * (v_ref - own_v_mps) + K_S_PER_S2 * (s_ref - s)
        return float(np.clip(u, p.accel_min_mps2, p.accel_max_mps2))

    def _reference(self, m: PlannedTrain, t: float) -> tuple[float, float, float]:
        """Reference distance, speed and time rate of a planned train at ``t``: the clock's for the PSO methods and
        the platoon leader; ``qp_order``'s followers fly the plan in the leader's time (:func:`leader_time_reference`)."""
        if self.method != "qp_order" or not self.order or m.train_id == self.order[0]:
            return (*m.reference(t), 1.0)
        lead = self.members[self.order[0]]
        if lead.handed_over:
            return (*m.reference(t), 1.0)
        front, v_lead = ground_front(self.ctx.channels, self.ctx.trains[lead.train_id], t)
        return leader_time_reference(m, lead, front, v_lead)

    def commands(
        self,
        t: float,
        tr: TrainRuntime,
        a: Ahead | None,
        base: dict[str, Any],
        commands: dict[str, Command],
        own_pos_m: float,
        own_v_mps: float,
        fstate: str,
    ) -> None:
        """A train under the plan: the plan's command, and only a relative-braking-distance safety cap against
        the train ahead (the coupled controller without gap tracking) — see the module docstring, step 3."""
        u = self.command(t, tr, own_pos_m, own_v_mps)
        if u is not None:
            # the plan's accelerations are net ones (the planner's double integrator): the applied command adds the
            # running resistance and gradient back (zero for the paper's point masses), as the ATO's does
            commands["junction"] = Command(tr.trip.vehicle.net_to_applied(u, own_v_mps, base["own"].gradient_permille))
        if a is None:
            return
        other = self.ctx.trains[a.train_id]
        f = self.ctx.formations.of_follower.get(tr.train_id)
        own_leader = f is not None and self.ctx.formations.leader_of(f).train_id == other.train_id
        pred = self.ctx.knowledge.known_state(
            tr, other, "t2t" if own_leader else "t2g", tr.train_id if own_leader else "ground"
        )
        guard = tr.controllers.get("coupled")
        if pred is None:
            return
        if guard is None:
            commands["separation"] = tr.controllers["separation"].command(
                Observation(**base, predecessor=pred, formation_state=fstate)
            )
            return
        commands["guard"] = guard.command(
            Observation(
                **base,
                predecessor=pred,
                formation_state="coupling",
                target_gap_m=self.target_gap_m,
                extras={"vc_tracking": False},
            )
        )

    # ------------------------------------------------------------------ the per-step update
    def before_bookkeeping(self, t: float) -> None:
        """The loop's phase hook: plan, re-plan, lock order, formations, hand-over at F (module docstring)."""
        self.update(t)

    def update(self, t: float) -> None:
        """Plan, re-plan, lock, form, hand over and record (called every step before the controllers run)."""
        trains = [self.ctx.trains[tid] for tid in self.members]
        if any(tr.status not in ("running",) for tr in trains) and self.t0_s is None:
            return  # not every planned train is on the line yet
        if self.t0_s is None:
            self._first_plan(t, trains)
        else:
            self._maybe_replan(t, trains)
        for tr in trains:
            m = self.members[tr.train_id]
            if not m.handed_over and tr.front_m >= m.F_m:
                m.handed_over = True
                self.handover_s[tr.train_id] = t
                self.ctx.events.record(
                    t, "junction_handover", tr.train_id, at="F", speed_mps=round(tr.plant.speed_mps, 3)
                )
        if not self.formed and (
            self.frozen or any(tr.front_m >= self.members[tr.train_id].point_m["sw2"] for tr in trains)
        ):
            self._form(t)
        self._record(t, trains)

    def _record(self, t: float, trains: list[TrainRuntime]) -> None:
        if self.t0_s is None:
            return
        if self.traj_t and all(
            tr.status != "running" or tr.front_m - self.members[tr.train_id].F_m > 1.0 for tr in trains
        ):
            return  # every planned train is past F: the junction process is over
        self.traj_t.append(t - self.t0_s)
        s0 = {tid: m.s0_m or 0.0 for tid, m in self.members.items()}
        self.traj_s.append([tr.front_m - s0[tr.train_id] if tr.status == "running" else math.nan for tr in trains])
        self.traj_v.append([tr.plant.speed_mps for tr in trains])

    def _switch_states(self) -> list[SwitchState]:
        return switch_states(self.ctx.interlocking, self.members, self.method == "qp_order")

    def _first_plan(self, t: float, trains: list[TrainRuntime]) -> None:
        states, fronts = ground_states(self.ctx.channels, self.members, trains, t, self.params.min_speed_mps)
        self.t0_s = t
        truth = []
        for tr in trains:
            m = self.members[tr.train_id]
            m.s0_m = tr.front_m
            track, dist = m.track(tr.front_m)
            truth.append(TrainState(tr.train_id, track, dist, max(tr.plant.speed_mps, self.params.min_speed_mps)))  # type: ignore[arg-type]
        try:
            # the referee scores the run against the true states at the plan instant (the plan uses the ground's)
            self.problem0 = build_problem(truth, (), self.layout, self.params)
            if self.method in ("naive1", "naive2"):
                prio = baselines.priority_order(build_problem(states, (), self.layout, self.params), self.method)  # type: ignore[arg-type]
                ids = [tr.train_id for tr in self.problem0.trains]
                order = tuple(ids[k] for k in prio)
                self._apply_order(t, order, naive=True)
                self.frozen = True
                self.ctx.events.record(t, "junction_plan", "junction", method=self.method, order=list(order))
                return
            new = plan(
                states,
                self._switch_states(),
                self.layout,
                self.params,
                self.method,  # type: ignore[arg-type]
                self.pso,
                self.rng,
                qp=self.qp,
                order=tuple(self.members) if self.spec.fixed_order else None,
            )
        except PlannerError as exc:
            raise ConfigError(
                self.ctx.scenario.source, "junction", f"the planner cannot plan at t={t:g} s: {exc}"
            ) from None
        self._adopt(t, new, trains, states, fronts)

    def _maybe_replan(self, t: float, trains: list[TrainRuntime]) -> None:
        if not self.replanning or self.plan is None:
            return
        if any(tr.front_m >= self.members[tr.train_id].point_m["sw2"] for tr in trains):
            self.replanning = False  # the first train is through the merge switch: track the last plan to F
            self.ctx.events.record(t, "junction_replanning_ended", "junction", reason="a train passed sw2")
            return
        # qp_order's plans are flyable as made: it re-plans on a tracking deviation only (a periodic re-plan from
        # the ground's extrapolated states restarts the plan from slightly wrong states and drifts it later)
        due = self.method != "qp_order" and t - self.last_plan_s >= self.spec.replan_s - 1e-9
        # ... or to polish an unconverged plan, a few times only (each starts from the ground's extrapolated states)
        gap_ok = t - self.last_plan_s >= MIN_REPLAN_GAP_S
        if gap_ok and not (due or self.plan.converged or self.polishes >= POLISH_REPLANS):
            due, self.polishes = True, self.polishes + 1
        # ... and once when the order freezes (a train at its point of no return): a warm re-plan from there, a
        # smaller problem, improves on the budgeted first plan (scenario 1: coupling 80.5 → 71 s)
        if not due and gap_ok and self.method == "qp_order" and not self.frozen:
            ground, _ = ground_states(self.ctx.channels, self.members, trains, t, self.params.min_speed_mps)
            due = bool(past_point_of_no_return(ground, self.params))
        if not due and gap_ok:
            for tr in trains:
                m = self.members[tr.train_id]
                s_ref, v_ref, _ = self._reference(m, t)
                if (
                    abs(tr.front_m - m.ref_front_m - s_ref) > DEVIATION_M
                    or abs(tr.plant.speed_mps - v_ref) > DEVIATION_MPS
                ):
                    due = True
                    self.ctx.events.record(
                        t,
                        "junction_deviation",
                        tr.train_id,
                        ds_m=round(tr.front_m - m.ref_front_m - s_ref, 2),
                        dv_mps=round(tr.plant.speed_mps - v_ref, 3),
                    )
                    break
        if not due:
            return
        states, fronts = ground_states(self.ctx.channels, self.members, trains, t, self.params.min_speed_mps)
        if any(s.distance_to_switch_m < 0.0 for s in states):
            return  # a train is inside a turnout (between restriction start and point): keep the current plan
        try:
            new = replan(
                self.plan,
                states,
                self._switch_states(),
                self.layout,
                self.params,
                self.method,  # type: ignore[arg-type]
                self.replan_pso,
                self.rng,
                keep_order=self.frozen or self.spec.fixed_order,
                qp=self.qp,
            )
        except PlannerError as exc:
            self.ctx.events.record(t, "junction_plan_failed", "junction", error=str(exc))
            log.warning("junction re-plan at t=%.1f s failed (%s); keeping the current plan", t, exc)
            self.last_plan_s = t
            return
        if not new.feasible and self.plan.feasible and not new.frozen_order:
            # an infeasible re-plan never replaces a feasible plan (the documented fallback: keep tracking it)
            self.ctx.events.record(t, "junction_plan_rejected", "junction", violation=round(new.violation, 4))
            self.last_plan_s = t
            return
        self._adopt(t, new, trains, states, fronts)

    def _adopt(
        self,
        t: float,
        new: JunctionPlan,
        trains: list[TrainRuntime],
        states: list[TrainState],
        fronts: dict[str, float],
    ) -> None:
        """Adopt a plan: every train's tracking reference, the record, the lock order.

        The PSO methods start each reference from the train's true front and speed (the original coordinator).
        ``qp_order`` starts it where the plan starts — the ground's front and speed the planner was given — so
        the reference *is* the planned trajectory and the feedback pulls the train onto it (a train slower than
        the ground believed is not handed a reference that decelerates it further by the plan's accelerations).
        """
        self.plan = new
        self.last_plan_s = t
        speed = {s.train_id: s.speed_mps for s in states}
        for tr in trains:
            tp = new.train(tr.train_id)
            if self.method == "qp_order":
                front, v0 = fronts[tr.train_id], speed[tr.train_id]
            else:
                front, v0 = tr.front_m, tr.plant.speed_mps
            if self.method == "qp_order":
                self.members[tr.train_id].set_reference_exact(self.params.min_speed_mps, t, front, v0, tp.segments)
            else:
                self.members[tr.train_id].set_reference(self.params.min_speed_mps, t, front, v0, tp.segments)
        self.plans.append(
            {
                "t_s": t,
                "order": list(new.order),
                "feasible": new.feasible,
                "cost": new.cost,
                "violation": new.violation,
                "frozen": new.frozen_order,
                "wall_time_s": new.wall_time_s,
                "iterations": new.iterations,
                "coupling_time_s": t + new.coupling_time_s,
                "coupled_speed_mps": new.coupled_speed_mps,
            }
        )
        self.ctx.events.record(
            t,
            "junction_plan",
            "junction",
            method=self.method,
            order=list(new.order),
            feasible=new.feasible,
            cost=round(new.cost, 4),
            frozen=new.frozen_order,
            wall_time_s=round(new.wall_time_s, 4),
            predicted_coupling_s=round(t + new.coupling_time_s, 2),
        )
        if new.frozen_order and not self.frozen:
            self.frozen = True
            self.ctx.events.record(t, "junction_order_frozen", "junction", order=list(new.order))
        self._apply_order(t, tuple(new.order), naive=False)

    # ------------------------------------------------------------------ locks and formations
    def _apply_order(self, t: float, order: tuple[str, ...], naive: bool) -> None:
        """Queue the switch locks of the planned trains in passing order (consecutive same-leg trains share one)."""
        if order == self.order:
            return
        self.order = order
        il = self.ctx.interlocking
        for sid in SWITCHES:
            users = [tid for tid in order if sid in self.members[tid].legs]
            if not users:
                continue
            for req in self.requests[sid]:  # re-queue: drop what is not granted yet
                if not il.is_granted(req):
                    il.cancel(req)
                    for h in req.holder_ids:
                        self.ctx.trains[h].locks.pop(sid, None)
            self.requests[sid] = [r for r in self.requests[sid] if il.is_granted(r)]
            waiting = [tid for tid in users if sid not in self.ctx.trains[tid].locks]
            groups: list[list[str]] = []
            for tid in waiting:
                leg = self.members[tid].legs[sid]
                if groups and self.members[groups[-1][-1]].legs[sid] == leg:
                    groups[-1].append(tid)
                else:
                    groups.append([tid])
            for g in groups:
                req = il.request(
                    tuple(g), sid, cast("Leg", self.members[g[0]].legs[sid])
                )  # checked by the interlocking
                self.requests[sid].append(req)
                for h in g:
                    self.ctx.trains[h].locks[sid] = req

    def _form(self, t: float) -> None:
        """Form the formations in passing order: each train follows the one before it, coupling from now."""
        from railsim.scenario import FormationSpec, TripRef

        self.formed = True
        self.formed_s = t
        order = self.order or tuple(self.members)
        for lead, fol in zip(order, order[1:]):
            lt, ft = self.ctx.trains[lead].trip, self.ctx.trains[fol].trip
            fid = f"junction_{lead}_{fol}"
            spec = FormationSpec(
                id=fid,
                leader=TripRef(lt.service_id, lt.index),
                follower=TripRef(ft.service_id, ft.index),
                target_gap_m=self.target_gap_m,
            )
            self.ctx.formations.add(spec, "junction")
            self.ctx.formations.manager.request_couple(fid)
        self.ctx.events.record(t, "junction_formed", "junction", order=list(order))

    # ------------------------------------------------------------------ results
    def summary(self) -> dict[str, Any]:
        """Outcome of the junction process (spec 004 metrics, measured on the SUMO trajectories)."""
        out: dict[str, Any] = {
            "method": self.method,
            "trains": list(self.members),
            "order": list(self.order),
            "plans": len(self.plans),
            "initial_plan_feasible": self.plans[0]["feasible"] if self.plans else None,
            "plan_wall_time_s_mean": float(np.mean([p["wall_time_s"] for p in self.plans])) if self.plans else None,
            "plan_wall_time_s_max": float(np.max([p["wall_time_s"] for p in self.plans])) if self.plans else None,
            "handover_s": dict(self.handover_s),
        }
        if self.problem0 is None or len(self.traj_t) < 2:
            return out
        t = np.array(self.traj_t)
        s = np.array(self.traj_s, dtype=float)
        v = np.array(self.traj_v, dtype=float)
        keep = np.all(np.isfinite(s), axis=1)
        o = measure(self.problem0, t[keep], s[keep], v[keep])
        for k, val in dataclasses.asdict(o).items():
            if isinstance(val, float) and not math.isfinite(val):
                val = None
            elif isinstance(val, tuple):
                val = list(val)
            out[k] = val
        if out.get("coupling_time_s") is not None:
            out["coupling_time_s"] = float(out["coupling_time_s"])
        form = [f for f in self.ctx.formations.manager.ids() if f.startswith("junction_")]
        times = [self.ctx.formations.manager.stats(fid).time_to_couple_s for fid in form]
        out["formations"] = form
        out["formations_coupled"] = sum(1 for c in times if c)
        # every formation locked in (Eq. 2-3 held for the hold time): when the last one did, from the first plan
        out["all_coupled_s"] = (
            self.formed_s - self.t0_s + max(c[0] for c in times)
            if times and all(times) and self.t0_s is not None
            else None
        )
        return out
