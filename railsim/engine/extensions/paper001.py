"""Paper B (spec 001) in the engine: vehicles with ``plant: multipoint`` are integrated carriage by carriage.

The carriage model (:mod:`railsim.physics.multipoint`) integrates continuously (RK4 sub-steps), so carriage 1
moves by ``Δx`` that is not ``v_new·dt``. SUMO's Euler update moves a train by the speed it is given times dt,
so the control stage hands it ``Δx/dt`` — the step's mean speed — and SUMO's front stays exactly on carriage 1
(:meth:`railsim.engine.control.ControlStage._exact_finish`). Model-based ATOs get the carriages' relative state
(couplers) as ``extras["multipoint_rel_state"]``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from railsim.engine.extensions import ExtensionContext, plant_kind, require_euler
from railsim.engine.train import TrainRuntime
from railsim.physics import multipoint


class MultipointPlant:
    """One train's carriage model (an :class:`~railsim.engine.train.ExactPlant`)."""

    def __init__(self, params: multipoint.MultipointParams, chainage_m: float, speed_mps: float) -> None:
        self.params = params
        self.state = multipoint.initial_state(params, chainage_m, speed_mps)

    def advance(
        self, t: float, tr: TrainRuntime, cmd: Any, grad_permille: float, dt_s: float
    ) -> tuple[float, float, float]:
        p, state = self.params, self.state
        forces = carriage_forces(cmd, p)
        view = tr.view
        new = multipoint.step(
            p, state, forces, dt_s, lambda xs: np.array([view.gradient_at(float(x)) for x in np.atleast_1d(xs)]), t
        )
        advance = float(new.lead_position_m - state.lead_position_m)
        mass = p.n_cars * p.car_mass_kg
        applied = float(np.clip(forces, p.force_min_n, p.force_max_n).sum()) / mass
        mean_v = 0.5 * (np.asarray(state.speeds_mps) + np.asarray(new.speeds_mps))
        tr.energy_j += float(np.sum(np.maximum(np.clip(forces, p.force_min_n, p.force_max_n), 0.0) * mean_v)) * dt_s
        self.state = new
        return advance, float(new.lead_speed_mps), applied

    def resync(self, t: float, chainage_m: float, speed_mps: float) -> None:
        self.state = multipoint.initial_state(self.params, chainage_m, speed_mps)


def carriage_forces(cmd: Any, p: multipoint.MultipointParams) -> np.ndarray:
    """Per-carriage forces [N]: the controller's own (``info["forces_n"]``) or its acceleration spread evenly."""
    forces = cmd.info.get("forces_n") if cmd.info else None
    if forces is not None and len(forces) == p.n_cars:
        return np.asarray(forces, dtype=float)
    return np.full(p.n_cars, float(cmd.accel_mps2) * p.car_mass_kg)


class Paper001:
    """Installs carriage plants on the vehicles that ask for them."""

    summary_key = None

    def __init__(self, ctx: ExtensionContext) -> None:
        self.ctx = ctx
        ctx.dispatcher.on_inserted.append(self._on_inserted)
        ctx.control.ato_extras.append(self._ato_extras)

    def _on_inserted(self, t: float, tr: TrainRuntime, chainage_m: float) -> None:
        kind, params = plant_kind(self.ctx, tr.trip.vehicle_name)
        if kind == "multipoint":
            tr.exact_plant = MultipointPlant(multipoint.MultipointParams(**params), chainage_m, tr.trip.start_speed_mps)

    @staticmethod
    def _ato_extras(t: float, tr: TrainRuntime) -> dict[str, Any]:
        if isinstance(tr.exact_plant, MultipointPlant):  # the carriages' relative state for model-based ATOs
            return {"multipoint_rel_state": tr.exact_plant.state.relative()}
        return {}


def install(ctx: ExtensionContext) -> Paper001 | None:
    if not any(p.kind == "multipoint" for p in ctx.scenario.plants.values()):
        return None
    require_euler(ctx, "multipoint")
    return Paper001(ctx)
