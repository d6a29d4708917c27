"""Paper B (spec 001) in the engine: vehicles with ``plant: multipoint`` are integrated carriage by carriage.

The carriage model (:mod:`railsim.physics.multipoint`) integrates continuously (RK4 sub-steps), so carriage 1
moves by ``Δx`` that is not ``v_new·dt``. SUMO's Euler update moves a train by the speed it is given times dt,
so the control stage hands it ``Δx/dt`` — the step's mean speed — and SUMO's front stays exactly on carriage 1
(:meth:`railsim.engine.train.TrainRuntime.exact_step`). Model-based ATOs get the carriages' relative state
(couplers) as ``extras["multipoint_rel_state"]``. The plant's ``wind`` (Scenario C, spec A14) acts on the plant
only; the controllers are not told.

**Paper B's measures** (``summary.json`` → ``paper001``, one entry per carriage-plant train; definitions in
:mod:`controllers.ato_mpc.metrics`): every step the plant logs the forces it received (whichever role won, so the
envelope counts are on what the carriages really got), carriage 1's position and speed after the step, and — when
the ATO commanded — its running phase, the section's time-indexed expected position/speed and stop point
(:mod:`controllers.ato_mpc.ato_role`). ``e_x_m`` (the paper's E_d) and ``e_v_mps`` average the running steps;
``stop_errors_m`` are ``|stop − x_1|`` at the first standstill within 50 m of each stop — where the law itself
brought the train to rest, before the hold supervisor of :class:`~controllers.ato_mpc.core.AtoDriver` clamps it;
``e_p_m`` is their mean; force and force-rate violations count against the plant's own Table-1 envelope.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from controllers.ato_mpc.metrics import actuator_metrics, tracking_metrics
from railsim.engine.extensions.base import Extension
from railsim.engine.extensions.context import ExtensionContext, plant_kind, require_euler
from railsim.engine.train import TrainRuntime
from railsim.physics import multipoint

if TYPE_CHECKING:  # pragma: no cover
    from railsim.scenario import Scenario


STOP_RADIUS_M = 50.0  # a standstill this close to the stop point counts as the law's stop (as the numpy runner)


@dataclass
class StepLog:
    """What the plant saw each step, for Paper B's measures (see the module docstring)."""

    forces_n: list[np.ndarray] = field(default_factory=list)
    x1_m: list[float] = field(default_factory=list)
    v1_mps: list[float] = field(default_factory=list)
    running: list[bool] = field(default_factory=list)  # the ATO commanded in its running phase
    x_ref_m: list[float] = field(default_factory=list)
    v_ref_mps: list[float] = field(default_factory=list)
    stop_errors_m: dict[float, float] = field(default_factory=dict)  # stop point -> |stop − x_1| at first rest


class MultipointPlant:
    """One train's carriage model (an :class:`~railsim.engine.train.ExactPlant`)."""

    def __init__(
        self,
        params: multipoint.MultipointParams,
        chainage_m: float,
        speed_mps: float,
        wind: multipoint.WindDisturbance = multipoint.NO_WIND,
    ) -> None:
        self.params = params
        self.wind = wind
        self.state = multipoint.initial_state(params, chainage_m, speed_mps)
        self.log = StepLog()

    def advance(
        self, t: float, tr: TrainRuntime, cmd: Any, grad_permille: float, dt_s: float
    ) -> tuple[float, float, float]:
        p, state = self.params, self.state
        forces = carriage_forces(cmd, p)
        view = tr.view
        new = multipoint.step(
            p,
            state,
            forces,
            dt_s,
            lambda xs: np.array([view.gradient_at(float(x)) for x in np.atleast_1d(xs)]),
            t,
            self.wind,
        )
        self._record(cmd, forces, state, new)
        advance = float(new.lead_position_m - state.lead_position_m)
        mass = p.n_cars * p.car_mass_kg
        applied = float(np.clip(forces, p.force_min_n, p.force_max_n).sum()) / mass
        mean_v = 0.5 * (np.asarray(state.speeds_mps) + np.asarray(new.speeds_mps))
        tr.energy_j += float(np.sum(np.maximum(np.clip(forces, p.force_min_n, p.force_max_n), 0.0) * mean_v)) * dt_s
        self.state = new
        return advance, float(new.lead_speed_mps), applied

    def resync(self, t: float, chainage_m: float, speed_mps: float) -> None:
        self.state = multipoint.initial_state(self.params, chainage_m, speed_mps)

    def _record(
        self, cmd: Any, forces: np.ndarray, old: multipoint.MultipointState, new: multipoint.MultipointState
    ) -> None:
        log, info = self.log, (cmd.info or {})
        log.forces_n.append(np.clip(forces, self.params.force_min_n, self.params.force_max_n))
        log.x1_m.append(new.lead_position_m)
        log.v1_mps.append(new.lead_speed_mps)
        ref = info.get("x_ref_m") is not None and info.get("phase") == "run"
        log.running.append(ref)
        log.x_ref_m.append(float(info["x_ref_m"]) if ref else np.nan)
        log.v_ref_mps.append(float(info["v_ref_mps"]) if ref else np.nan)
        stop = info.get("stop_m")
        came_to_rest = new.held and not old.held
        if stop is not None and came_to_rest and abs(float(stop) - new.lead_position_m) <= STOP_RADIUS_M:
            log.stop_errors_m.setdefault(float(stop), abs(float(stop) - new.lead_position_m))

    def measures(self, period_s: float) -> dict[str, Any]:
        """Paper B's measures of this train (see the module docstring)."""
        log = self.log
        run = np.asarray(log.running, dtype=bool)
        stops = list(log.stop_errors_m.values())
        errors = tracking_metrics(
            np.asarray(log.x1_m), np.asarray(log.v1_mps), np.asarray(log.x_ref_m), np.asarray(log.v_ref_mps), run
        )
        return {
            **{k: (v if np.isfinite(v) else None) for k, v in errors.items()},  # None: the ATO never ran
            "e_p_m": float(np.mean(stops)) if stops else None,
            "stop_errors_m": [round(e, 6) for e in stops],
            **actuator_metrics(np.asarray(log.forces_n), self.params, period_s),
            "running_steps": int(run.sum()),
            "wind": self.wind.kind,
        }


def carriage_forces(cmd: Any, p: multipoint.MultipointParams) -> np.ndarray:
    """Per-carriage forces [N]: the controller's own (``info["forces_n"]``) or its acceleration spread evenly."""
    forces = cmd.info.get("forces_n") if cmd.info else None
    if forces is not None and len(forces) == p.n_cars:
        return np.asarray(forces, dtype=float)
    return np.full(p.n_cars, float(cmd.accel_mps2) * p.car_mass_kg)


class CarriagePlants(Extension):
    """Installs carriage plants on the vehicles that ask for them; Paper B's measures in ``summary.json``."""

    summary_key = "paper001"

    @classmethod
    def applies(cls, scenario: Scenario) -> bool:
        return any(p.kind == "multipoint" for p in scenario.plants.values())

    def __init__(self, ctx: ExtensionContext) -> None:
        require_euler(ctx, "multipoint")
        super().__init__(ctx)
        self.plants: dict[str, MultipointPlant] = {}

    def on_inserted(self, t: float, tr: TrainRuntime, chainage_m: float) -> None:
        kind, params = plant_kind(self.ctx, tr.trip.vehicle_name)
        if kind == "multipoint":
            wind = multipoint.WindDisturbance(**params.pop("wind", {}))
            plant = MultipointPlant(multipoint.MultipointParams(**params), chainage_m, tr.trip.start_speed_mps, wind)
            tr.exact_plant = plant
            self.plants[tr.train_id] = plant

    def summary(self) -> dict[str, Any]:
        """Per carriage-plant train: Paper B's measures (E_d = ``e_x_m``, E_v, E_p, E_u, envelope violations)."""
        return {tid: plant.measures(self.ctx.dt_s) for tid, plant in sorted(self.plants.items())}

    def ato_extras(self, t: float, tr: TrainRuntime) -> dict[str, Any]:
        if isinstance(tr.exact_plant, MultipointPlant):  # the carriages' relative state for model-based ATOs
            return {"multipoint_rel_state": tr.exact_plant.state.relative()}
        return {}
