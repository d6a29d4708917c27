"""Late collaborators: the few slots of a port that can only be filled after the port is built.

Ports get their collaborators at construction (:class:`railsim.engine.loop.Simulation` builds them in the order
their dependencies allow). Two kinds of dependency cannot be passed that way:

* **true cycles** — the formation book asks the dispatcher to insert a follower behind its leader while the
  dispatcher asks the formation book who couples on departure; the formation book asks the stop book where a
  train stops while the stop book asks the formation book how far behind its mark a follower halts;
* **the SUMO bridge**, which exists only while the run is under way (the ports are built before SUMO starts).

Such a slot starts as :class:`Unwired` (using it raises, naming the slot) and is filled exactly once by the
port's own typed ``wire``/``connect`` method through :func:`set_once`. :func:`unwired_slots` lists the slots of an
object that still hold their placeholder, so a test can check that a built engine left none behind.
"""

from __future__ import annotations

from typing import Any, NoReturn


class Unwired:
    """The placeholder of a slot the engine has not wired yet: calling it or reading from it raises."""

    __slots__ = ("slot",)

    def __init__(self, slot: str) -> None:
        self.slot = slot

    def __call__(self, *args: object, **kwargs: object) -> NoReturn:
        raise RuntimeError(f"{self.slot} used before the engine wired it")

    def __getattr__(self, name: str) -> NoReturn:
        if name.startswith("__"):  # introspection (copy, pickle, vars) sees a plain object
            raise AttributeError(name)
        raise RuntimeError(f"{self.slot}.{name} used before the engine wired it")

    def __repr__(self) -> str:
        return f"Unwired({self.slot!r})"


def unwired(owner: str, name: str) -> Any:
    """A placeholder for slot ``owner.name``, typed as the slot it stands in for (mypy checks what is wired)."""
    return Unwired(f"{owner}.{name}")


def set_once(port: object, name: str, value: object) -> None:
    """Fill slot ``name`` of ``port``; wiring a slot twice (or a name that is no slot) is a programming error."""
    if not isinstance(getattr(port, name, None), Unwired):
        raise RuntimeError(f"{type(port).__name__}.{name} is not an unwired slot (wired twice?)")
    setattr(port, name, value)


def unwired_slots(port: object) -> list[str]:
    """The names of ``port``'s attributes that still hold their :class:`Unwired` placeholder."""
    return sorted(name for name, value in getattr(port, "__dict__", {}).items() if isinstance(value, Unwired))
