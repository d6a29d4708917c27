"""A scenario's world as a :class:`~network.topology.NetworkBundle`, whichever kind it is.

A scenario's ``world:`` is either a world railsim builds — a shipped one by name or a line description
(:func:`network.build.build`: netconvert, cached by content hash) — or an existing SUMO net read as it is
(:func:`network.external.load_net`). :func:`load_world` hands back the same bundle contract for both, and
:func:`sumo_args` the SUMO options a world needs when it is simulated.
"""

from __future__ import annotations

from typing import Any

from network.build import build
from network.external import INSERTION_CHECKS, load_net
from network.topology import NetworkBundle


def load_world(world: Any, source: Any = None) -> NetworkBundle:
    """The bundle of a scenario's ``world`` (:class:`railsim.scenario.WorldSpec`): built, or read from a net.
    ``source`` (the scenario file) names the file in the errors of a net that cannot be read."""
    if world.kind != "net":
        name_or_path, params = world.build_args()
        return build(name_or_path, **params)
    return load_net(
        world.net,
        world.additional,
        signals=world.signals,
        vclass=world.vclass,
        throw_time_s=world.throw_time_s,
        running_side=world.running_side,
        unrestricted_lanes=world.unrestricted_lanes,
        where=(source, "world"),
    )


def sumo_args(bundle: NetworkBundle) -> tuple[str, ...]:
    """Extra SUMO options for simulating ``bundle`` (none for generated worlds).

    On an external net SUMO's ``oncomingTrain``/``bidi`` insertion checks are switched off (all the others stay):
    SUMO otherwise holds a train at its depart platform on a bidi edge for as long as any train whose route
    uses the partner edge is on the way (75 s in the passing-loop test), which breaks the timetable; railsim's
    trains are placed where the scenario says and our occupancy and interlocking judge safety.
    """
    if bundle.graph.graph.get("kind") != "external":
        return ()
    return ("--insertion-checks", INSERTION_CHECKS)
