"""Paper-specific behaviour that plugs into the step loop, selected by the scenario — never a branch in the loop.

Each extension module has ``install(ctx) -> object | None``: it looks at the scenario, and if it applies, it
registers its hooks on the ports in :class:`ExtensionContext` and returns itself (kept by the loop for the
phase hooks and the summary); otherwise it returns None. The hook points:

=======================  ====================================================================================
``dispatcher.on_inserted``  a train entered the world (exact plants create their state here)
``formations.follower_hooks``  per follower and step, before the formation state machine is fed (Paper D FSM)
``knowledge.extra_receivers``  extra t2t receivers of a train's report (Paper C graph neighbours)
``control.ato_extras``     extra observation fields for the ATO role (graph neighbours, carriage states)
``control.command_source``  an extension that commands some trains itself (the junction planner)
``locks.managed_by``       switch requests an extension makes itself (the junction planner's passing order)
``before_bookkeeping(t)``  a phase hook on the returned object, after the truth checks (junction planning)
``before_comms(t, active)``  a phase hook, after bookkeeping and before reports are sent (Paper C graph)
``summary()``             a dict merged into ``summary.json`` under the extension's ``summary_key``
=======================  ====================================================================================

Families: :mod:`.paper001` (carriage-by-carriage plant), :mod:`.paper002` (cooperative graph),
:mod:`.paper003` (monorail drive and follower state machine), :mod:`.paper004` (junction planner online).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from railsim.errors import ConfigError


@dataclass
class ExtensionContext:
    """The ports an extension may hook into, and the few facts it may read."""

    scenario: Any
    fleet: Any  # railsim.engine.fleet.Fleet
    formations: Any  # railsim.engine.coupling.FormationBook
    dispatcher: Any  # railsim.engine.insertion.Dispatcher
    knowledge: Any  # railsim.engine.knowledge.Knowledge
    locks: Any  # railsim.engine.locking.RouteLocks
    control: Any  # railsim.engine.control.ControlStage
    events: Any  # railsim.engine.events.log.EventLog
    layer: Any  # railsim.engine.events.clock.EventLayer
    interlocking: Any
    channels: dict[str, Any]
    settings: Any
    switch_throw_s: dict[str, float]
    dt_s: float
    step_method: str
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


def install_all(ctx: ExtensionContext) -> list[Any]:
    """Install every extension that applies to the scenario, in a fixed order (the junction planner last: it
    draws a seed from the run's generator)."""
    from railsim.engine.extensions import paper001, paper002, paper003, paper004

    installed = []
    for module in (paper001, paper003, paper002, paper004):
        ext = module.install(ctx)
        if ext is not None:
            installed.append(ext)
    return installed
