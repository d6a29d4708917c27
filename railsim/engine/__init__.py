"""The engine: one simulation's step loop and the ports it drives (docs/architecture.md, "The step loop").

:func:`run` is the public entry point; :class:`Simulation` owns time and the order of the phases.
"""

from railsim.engine.loop import EngineSettings, Simulation, run

__all__ = ["EngineSettings", "Simulation", "run"]
