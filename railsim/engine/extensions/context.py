"""What an extension is given: the facts and the few engine services the installed extensions read, typed.

An extension never sees the simulation or a whole port. It gets the scenario, the trains, the event log, the
interlocking, the radio channels and the engine's settings (the real classes), and two narrow questions as
protocols: :class:`FormationView` (formations in force, and registering one at run time) and
:class:`KnownStates` (what one train knows of another). A new extension that needs more adds a field here —
typed, and named for the question it answers.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from railsim.errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    from controllers.base import PredecessorState
    from railsim.engine.events import Channel, EventLog, FormationManager, Interlocking
    from railsim.engine.settings import EngineSettings
    from railsim.engine.train import TrainRuntime
    from railsim.scenario import FormationSpec, Scenario


class FormationView(Protocol):
    """The formations in force (the engine's formation book), as an extension may use them."""

    @property
    def manager(self) -> FormationManager:
        """The formation state machine (states, couple/decouple requests, statistics)."""

    @property
    def of_follower(self) -> Mapping[str, FormationSpec]:
        """Follower train id -> its formation."""

    def leader_of(self, f: FormationSpec) -> TrainRuntime:
        """The leading train of formation ``f``."""

    def add(self, f: FormationSpec, where: str = "formations") -> None:
        """Register a formation formed at run time (``where`` names it in error messages)."""

    def note_on_run_infeasible(self, formation_id: str, detail: Mapping[str, float | None]) -> None:
        """Note that a formation cannot couple on the run where it asked, and the numbers why (the summary's)."""


class KnownStates(Protocol):
    """What one train knows of another from delivered reports (the engine's knowledge port)."""

    def known_state(
        self, observer: TrainRuntime, other: TrainRuntime, channel: str, receiver: str, ahead: bool = False
    ) -> PredecessorState | None:
        """``other`` as ``observer`` knows it via ``channel`` (``receiver``: the observer's or ``"ground"``)."""


@dataclass(frozen=True)
class ExtensionContext:
    """Everything an extension may read or call (module docstring)."""

    scenario: Scenario
    trains: dict[str, TrainRuntime]  # every trip's train, by id
    formations: FormationView
    knowledge: KnownStates
    events: EventLog
    interlocking: Interlocking
    channels: dict[str, Channel]  # the radio channels by name (t2t, t2g)
    settings: EngineSettings
    actuator_bias: Callable[[float, str, float], float]  # (t, train, u) -> u plus the scenario's injected biases
    switch_throw_s: dict[str, float]  # throw time per switch of the world
    dt_s: float
    step_method: str  # SUMO's position update (euler, ballistic)
    draw_seed: Callable[[], int]  # a seed from the run's generator (call only if the extension applies)


def require_euler(ctx: ExtensionContext, kind: str) -> None:
    """Exact plants hand SUMO the step's mean speed, which is only right with SUMO's Euler update."""
    for vname, plant in ctx.scenario.plants.items():
        if plant.kind == kind and ctx.step_method != "euler":
            raise ConfigError(
                ctx.scenario.source,
                "simulation.step_method",
                f"vehicle {vname!r} uses the {plant.kind} plant, which needs step_method euler "
                f"(SUMO is handed the step's mean speed), got {ctx.step_method!r}",
            )


def plant_kind(ctx: ExtensionContext, vehicle_name: str) -> tuple[str | None, dict[str, Any]]:
    """The scenario's plant for a vehicle: ``(kind, params)`` or ``(None, {})`` for the default point mass."""
    plant = ctx.scenario.plants.get(vehicle_name)
    return (plant.kind, dict(plant.params)) if plant is not None else (None, {})
