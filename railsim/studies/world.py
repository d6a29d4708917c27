"""The world check of a scenario: build (or read) its world and check every station and switch id it names.

:func:`railsim.scenario.load` validates a scenario on its own; the ids of stations and switches can only be checked
against the built world, and building a world runs netconvert (cached by content hash in ``network.build``, so only
the first build of a world is slow). :func:`world_check` does that second level for ``railsim validate``
(:mod:`railsim.cli.scenario`) and for every case of a sweep before anything runs
(:func:`railsim.studies.sweep.validate_cases`).

A shipped world or a line description is built with ``network.build``; a ``net`` world (a user's ``.net.xml``) is
read as it is (:func:`network.world.load_world`: stations from its trainStops). Mismatches raise
:class:`railsim.errors.ConfigError` from :func:`railsim.scenario.check_against_world`, naming file and field.

:func:`run_checks` adds everything ``railsim run`` checks before its first step, by building the engine's
:class:`railsim.engine.Simulation` without an output folder and never running it (routes, reversals, coupling
stations, formation trip references, insertion positions, the interlocking): one set of checks and one message
per mistake for ``validate`` and ``run``. SUMO is not started.

It lives here, not in :mod:`railsim.cli`, because studies may not import the command line; the world check's
natural home is :mod:`railsim.scenario`, next to ``check_against_world``, but the scenario layer may not import
the engine that :func:`run_checks` needs.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from railsim import scenario as scenario_mod


def _network_build() -> Callable[..., Any] | None:
    """``network.build``: the one place the world check reaches the network package (tests replace it)."""
    import network

    return network.build


def world_check(scn: scenario_mod.Scenario) -> str | None:
    """Build the scenario's world and check station/switch ids. Returns a reason when the check was skipped."""
    build = _network_build()
    if build is None:
        return "world check skipped: network.build is not available yet"
    if scn.world.kind == "net":  # a user's .net.xml is read (stations from its trainStops), not built
        from network.world import load_world

        bundle = load_world(scn.world, scn.source)
    else:
        name_or_path, params = scn.world.build_args()
        bundle = build(name_or_path, **params)
    scenario_mod.check_against_world(
        scn, bundle.stations.keys(), bundle.switches.keys(), getattr(bundle, "station_aliases", None)
    )
    return None


def _simulation() -> Callable[..., Any]:
    """``railsim.engine.Simulation``: the one place the checks reach the engine (tests replace it)."""
    from railsim.engine import Simulation

    return Simulation


def run_checks(scn: scenario_mod.Scenario) -> str | None:
    """:func:`world_check`, then every check ``railsim run`` makes before its first step (module docstring).
    Returns a reason when the checks were skipped; raises ConfigError naming file and field."""
    skipped = world_check(scn)
    if skipped:
        return skipped
    _simulation()(scn, None, progress=False)
    return None
