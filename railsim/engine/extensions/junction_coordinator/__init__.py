"""The junction coordinator: Paper E's cooperative-game planner run online by the ground, driving trains through a
SUMO Y-junction (:mod:`.coordinator` explains every step).

Modules: :mod:`.coordinator` (plan, re-plan, lock order, formations, hand-over, the measured outcome),
:mod:`.ground` (what the ground knows of the trains and switches), :mod:`.readings` (the planner's parameters
fixed from the engine's rules), :mod:`.tracking` (a planned train's path and tracking reference).
"""

from railsim.engine.extensions.junction_coordinator.coordinator import JunctionCoordinator

__all__ = ["JunctionCoordinator"]
