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
from typing import TYPE_CHECKING, Any

from controllers.monorail.states import StateParams, VcInputs, VcMemory, VcState, transition
from railsim.engine.extensions.base import Extension
from railsim.engine.extensions.context import ExtensionContext, plant_kind, require_euler
from railsim.engine.occupancy import Ahead
from railsim.engine.train import TrainRuntime
from railsim.physics import monorail

if TYPE_CHECKING:  # pragma: no cover
    from railsim.scenario import FormationSpec, Scenario

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


class MonorailDrive(Extension):
    """Monorail drives on the vehicles that ask for them; the state machine on monorail formations."""

    @classmethod
    def applies(cls, scenario: Scenario) -> bool:
        monorail_plant = any(p.kind == "monorail" for p in scenario.plants.values())
        return monorail_plant or any(c.type in MONORAIL_COUPLED_TYPES for c in scenario.controllers.values())

    def __init__(self, ctx: ExtensionContext) -> None:
        require_euler(ctx, "monorail")
        super().__init__(ctx)
        self.memory: dict[str, tuple[VcMemory, StateParams]] = {}

    def on_inserted(self, t: float, tr: TrainRuntime, chainage_m: float) -> None:
        kind, params = plant_kind(self.ctx, tr.trip.vehicle_name)
        if kind == "monorail":
            tr.exact_plant = MonorailPlant(
                monorail.MonorailParams(**params), t, chainage_m, tr.trip.start_speed_mps, self.ctx.actuator_bias
            )

    def follower_step(self, t: float, tr: TrainRuntime, f: FormationSpec, a: Ahead) -> None:
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
        other = self.ctx.trains[a.train_id]
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
