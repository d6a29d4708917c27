"""Paper D (spec 003) in the engine: the monorail drive and the follower state machine.

* **Drive** (``plant: monorail``): dead time, first-order lag, output efficiency and a load-dependent envelope
  (:mod:`railsim.physics.monorail`), integrated exactly within the step; SUMO gets the step's mean speed.
  Injected actuator biases add to the command before the drive sees it.
* **Follower state machine** (spec §3.1/§3.2.4), for formations whose ``coupled`` role is a monorail
  controller: fed the true gap and closing speed every step, it logs every state change (``vc_state``) and
  turns *passive* (spacing opening past d_max) and *active* (spacing closing below d_min) decoupling into a
  decouple request to the formation. Collision avoidance stays with the ``ca`` role (``ca_enabled=False``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from controllers.monorail.states import StateParams, VcInputs, VcMemory, VcState, transition
from railsim.engine.extensions import ExtensionContext, plant_kind, require_euler
from railsim.engine.occupancy import Ahead
from railsim.engine.train import TrainRuntime
from railsim.physics import monorail

MONORAIL_COUPLED_TYPES = ("monorail_apf", "monorail_dmpc")
CLOCK_TOLERANCE_S = 1e-6


class MonorailPlant:
    """One vehicle's monorail drive (an :class:`~railsim.engine.train.ExactPlant`)."""

    def __init__(
        self,
        params: monorail.MonorailParams,
        t: float,
        chainage_m: float,
        speed_mps: float,
        biased: Callable[[float, str, float], float],
    ) -> None:
        self.params = params
        self.state = monorail.PlantState(t_s=t, x_m=chainage_m, v_mps=speed_mps)
        self.biased = biased

    def advance(
        self, t: float, tr: TrainRuntime, cmd: Any, grad_permille: float, dt_s: float
    ) -> tuple[float, float, float]:
        u = self.biased(t, tr.train_id, cmd.accel_mps2)
        state = self.state
        if abs(state.t_s - t) > CLOCK_TOLERANCE_S:  # keep the drive's clock on the engine's (after a hold by SUMO)
            state = monorail.PlantState(
                t_s=t,
                x_m=state.x_m,
                v_mps=state.v_mps,
                a_mps2=state.a_mps2,
                active_command_mps2=state.active_command_mps2,
                active_issue_s=state.active_issue_s,
                pending=state.pending,
            )
        mass = tr.trip.vehicle.mass_kg
        new = monorail.plant_step(state, u, dt_s, self.params, mass, grad_permille)
        mean_v = 0.5 * (state.v_mps + new.v_mps)
        tr.energy_j += max(new.a_mps2, 0.0) * mass * mean_v * dt_s
        self.state = new
        return new.x_m - state.x_m, new.v_mps, new.a_mps2

    def resync(self, t: float, chainage_m: float, speed_mps: float) -> None:
        self.state = monorail.PlantState(t_s=t, x_m=chainage_m, v_mps=speed_mps)


class Paper003:
    """Monorail drives on the vehicles that ask for them; the state machine on monorail formations."""

    summary_key = None

    def __init__(self, ctx: ExtensionContext) -> None:
        self.ctx = ctx
        self.memory: dict[str, tuple[VcMemory, StateParams]] = {}
        ctx.dispatcher.on_inserted.append(self._on_inserted)
        ctx.formations.follower_hooks.append(self._follower_fsm)

    def _on_inserted(self, t: float, tr: TrainRuntime, chainage_m: float) -> None:
        kind, params = plant_kind(self.ctx, tr.trip.vehicle_name)
        if kind == "monorail":
            tr.exact_plant = MonorailPlant(
                monorail.MonorailParams(**params), t, chainage_m, tr.trip.start_speed_mps, self.ctx.control.dist.biased
            )

    def _follower_fsm(self, t: float, tr: TrainRuntime, f: Any, a: Ahead) -> None:
        name = tr.trip.roles.get("coupled")
        if name is None or self.ctx.scenario.controllers[name].type not in MONORAIL_COUPLED_TYPES:
            return
        manager = self.ctx.formations.manager
        fstate = manager.state(f.id)
        if tr.train_id not in self.memory:
            self.memory[tr.train_id] = (
                VcMemory(VcState.INDEPENDENT, since_s=t),
                StateParams(target_gap_m=float(f.target_gap_m)),
            )
        mem, params = self.memory[tr.train_id]
        other = self.ctx.fleet.trains[a.train_id]
        inp = VcInputs(
            t_s=t,
            gap_m=a.gap_m,
            closing_speed_mps=tr.plant.speed_mps - other.plant.speed_mps,
            speed_mps=tr.plant.speed_mps,
            couple_command=fstate in ("coupling", "coupled"),
            ca_enabled=False,
        )
        new, events = transition(mem, inp, params)
        self.memory[tr.train_id] = (new, params)
        for ev in events:
            state, _, reason = ev.partition(":")
            self.ctx.events.record(
                t, "vc_state", tr.train_id, state=state, reason=reason or None, gap_m=round(a.gap_m, 3)
            )
            if state == "decoupling" and reason in ("passive", "active") and fstate in ("coupling", "coupled"):
                self.ctx.events.record(t, f"{reason}_decoupling", f.id, gap_m=round(a.gap_m, 3))
                manager.request_decouple(f.id)


def install(ctx: ExtensionContext) -> Paper003 | None:
    monorail_plant = any(p.kind == "monorail" for p in ctx.scenario.plants.values())
    monorail_fsm = any(c.type in MONORAIL_COUPLED_TYPES for c in ctx.scenario.controllers.values())
    if not (monorail_plant or monorail_fsm):
        return None
    require_euler(ctx, "monorail")
    return Paper003(ctx)
