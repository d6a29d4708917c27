"""Paper-specific behaviour that plugs into the step loop, selected by the scenario — never a branch in the loop.

An extension is a subclass of :class:`~railsim.engine.extensions.base.Extension` that overrides only the hooks it
uses (:mod:`.base` lists them and the port that calls each); it is built with an
:class:`~railsim.engine.extensions.context.ExtensionContext` — the typed facts and narrow services it may use —
when its :meth:`~railsim.engine.extensions.base.Extension.applies` says the scenario needs it
(:func:`.registry.install_all`).

The extensions: :class:`.paper001.CarriagePlants` (Paper B's carriage-by-carriage plant and measures),
:class:`.paper003.MonorailDrive` (Paper D's monorail drive and follower state machine),
:class:`.paper002.CooperativeGraph` (Paper C's cooperative graph) and
:class:`.junction_coordinator.JunctionCoordinator` (Paper E's junction planner run online by the ground).
"""

from railsim.engine.extensions.base import Extension, ExtensionSet
from railsim.engine.extensions.context import ExtensionContext

__all__ = ["Extension", "ExtensionContext", "ExtensionSet"]
