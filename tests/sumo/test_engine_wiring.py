"""A built engine leaves no collaborator slot unwired, and no port keeps a no-op default in place of one.

Ports get their collaborators at construction; the few that cannot (two true cycles, and the SUMO bridge that
exists only during a run) start as :class:`railsim.engine.wiring.Unwired` placeholders and are wired once
(:mod:`railsim.engine.wiring`). This builds a real engine on a small scenario and checks every port reachable
from it: after construction only the bridge's slots may wait, after the run none.
"""

from __future__ import annotations

import types
from collections.abc import Iterator

import pytest

from railsim import scenario as scn
from railsim.engine.extensions import ExtensionSet
from railsim.engine.loop import Simulation
from railsim.engine.wiring import Unwired, unwired_slots
from tests.helpers import DATA

BRIDGE_SLOTS = {"Dispatcher.bridge", "Turnbacks.bridge", "StopBook.drop_stop"}  # connected when the run starts


def _ports(root: object) -> Iterator[object]:
    """Every engine object reachable from ``root`` through attributes (the ports and what they hold)."""
    seen: set[int] = set()
    stack = [root]
    while stack:
        obj = stack.pop()
        if id(obj) in seen or isinstance(obj, Unwired) or not type(obj).__module__.startswith("railsim.engine"):
            continue
        seen.add(id(obj))
        yield obj
        stack.extend(v for v in getattr(obj, "__dict__", {}).values())


def _unwired(sim: Simulation) -> set[str]:
    return {f"{type(port).__name__}.{name}" for port in _ports(sim) for name in unwired_slots(port)}


def _default_lambdas(sim: Simulation) -> set[str]:
    """Attributes holding a lambda a port made for itself in its constructor (a no-op default standing in for a
    collaborator)."""
    out = set()
    for port in _ports(sim):
        for name, value in getattr(port, "__dict__", {}).items():
            if isinstance(value, types.FunctionType) and value.__name__ == "<lambda>":
                if ".__init__.<locals>" in value.__qualname__ and not value.__qualname__.startswith("Simulation."):
                    out.add(f"{type(port).__name__}.{name}")
    return out


def test_no_slot_keeps_its_default_once_the_engine_is_built_and_running(
    tmp_path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("RAILSIM_CACHE", str(tmp_path / "cache"))
    sim = Simulation(scn.load(DATA / "scenarios" / "mini_line.yaml"), None, progress=False)
    assert len(list(_ports(sim))) > 10  # the walk reaches the ports
    assert _unwired(sim) == BRIDGE_SLOTS
    assert _default_lambdas(sim) == set()
    extension_sets = [p for p in _ports(sim) if isinstance(p, ExtensionSet)]
    assert extension_sets and all(s.installed is not None for s in extension_sets)
    assert {id(s) for s in extension_sets} == {id(sim.extensions)}  # one set, shared by every port

    sim.run()
    assert _unwired(sim) == set()
