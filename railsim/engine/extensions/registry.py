"""Which extensions exist, and installing those a scenario needs, in a fixed order.

The order is the order their hooks run in: exact plants first, then the graph, the merge order, the junction coordinator last (it
draws a seed from the run's generator, so it must draw after every other consumer of that stream).
"""

from __future__ import annotations

from railsim.engine.extensions.base import Extension
from railsim.engine.extensions.context import ExtensionContext
from railsim.engine.extensions.junction_coordinator import JunctionCoordinator
from railsim.engine.extensions.merge_order import MergeOrder
from railsim.engine.extensions.paper001 import CarriagePlants
from railsim.engine.extensions.paper002 import CooperativeGraph
from railsim.engine.extensions.paper003 import MonorailDrive

EXTENSIONS: tuple[type[Extension], ...] = (
    CarriagePlants,
    MonorailDrive,
    CooperativeGraph,
    MergeOrder,
    JunctionCoordinator,
)


def install_all(ctx: ExtensionContext) -> list[Extension]:
    """Build every extension that applies to the scenario, in :data:`EXTENSIONS` order."""
    return [cls(ctx) for cls in EXTENSIONS if cls.applies(ctx.scenario)]
