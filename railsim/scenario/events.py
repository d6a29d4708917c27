"""The scenario's timed events (``events:``) and the table of event kinds.

An event is a command at simulation time ``at_s``::

    events:
      - {at_s: 600, type: couple, formation: pair1}
      - {at_s: 900, type: leave, train: airport.003}
      - {at_s: 120, type: obstacle, train: mono.000, ahead_m: 400, duration_s: 60}

Every event kind is **one entry** of :data:`EVENT_KINDS`, made by :func:`register_event_kind`: its name
(the YAML ``type``), its fields (each an :class:`EventField`: the YAML key, which is also the
:class:`~railsim.scenario.model.EventSpec` attribute the engine reads, how to check it, whether it is
required) and an optional engine-handler key. The validator (:func:`events`) and the error messages
("expected one of couple, decouple, leave, obstacle", the allowed keys) are derived from the table, so
adding a kind touches one entry here (plus, if it needs a value no kind had before, one optional attribute
of ``EventSpec``) and one handler in the engine.

The engine looks a kind up by the event's ``type``::

    kind = event_kind(ev.type)          # railsim.scenario.events.EventKind
    handlers[kind.handler_key](ev)      # the engine's own table: handler key -> callable

``handler_key`` is the kind's ``handler`` when one is given, else its name; today every kind is handled
under its own name (``"couple"``, ``"decouple"``, ``"leave"``, ``"obstacle"``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from railsim.scenario.model import EventSpec, FormationSpec, ServiceSpec
from railsim.scenario.validate import Checker, did_you_mean, short_repr
from railsim.scenario.validate_services import trip_name

_EVENT_REQUIRED = ("at_s", "type")  # every event has these; the kinds add their own fields


@dataclass(frozen=True)
class EventContext:
    """What an event's fields may refer to: the scenario's (already validated) formations and services."""

    formations: Sequence[FormationSpec]
    services: Sequence[ServiceSpec]


# A field check: (checker, value, field path, context) -> the checked value stored in the EventSpec.
FieldCheck = Callable[[Checker, Any, str, EventContext], Any]


@dataclass(frozen=True)
class EventField:
    """One field of an event kind: YAML ``key`` (= :class:`EventSpec` attribute), its check, required or not."""

    key: str
    check: FieldCheck
    required: bool = True


@dataclass(frozen=True)
class EventKind:
    """One kind of timed event: the YAML ``type`` value ``name``, its ``fields`` and how the engine runs it.

    ``why_required`` is appended to "missing required key" when a required field is absent (it tells the
    user what the field is for). ``handler`` optionally names the engine's handler for this kind; the engine
    uses :attr:`handler_key`.
    """

    name: str
    fields: tuple[EventField, ...]
    description: str = ""
    why_required: str = ""
    handler: str | None = None

    @property
    def handler_key(self) -> str:
        """The key the engine looks its handler up by: ``handler``, or the kind's name."""
        return self.handler or self.name

    def parse(
        self, ck: Checker, m: dict[str, Any], path: str, at_s: float, ctx: EventContext
    ) -> tuple[EventSpec, dict[str, Any]]:
        """The event ``m`` (keys already checked) → its :class:`EventSpec` and resolved raw mapping.

        Every required field's presence is checked first, then the present fields are checked in order.
        """
        reason = f" ({self.why_required})" if self.why_required else ""
        for f in self.fields:
            if f.required and f.key not in m:
                raise ck.fail(f"{path}.{f.key}", f"missing required key{reason}")
        values = {f.key: f.check(ck, m[f.key], f"{path}.{f.key}", ctx) for f in self.fields if f.key in m}
        return EventSpec(at_s, self.name, **values), {"at_s": at_s, "type": self.name, **values}


EVENT_KINDS: dict[str, EventKind] = {}  # type name -> kind, in registration order (the order messages list)
_SPEC_ATTRIBUTES = frozenset(f.name for f in dataclasses.fields(EventSpec)) - set(_EVENT_REQUIRED)


def register_event_kind(kind: EventKind) -> EventKind:
    """Add ``kind`` to :data:`EVENT_KINDS` (a name may be registered once; fields must be EventSpec attributes)."""
    if kind.name in EVENT_KINDS:
        raise ValueError(f"event kind {kind.name!r} is already registered")
    unknown = [f.key for f in kind.fields if f.key not in _SPEC_ATTRIBUTES]
    if unknown:
        raise ValueError(
            f"event kind {kind.name!r}: fields {unknown} are not EventSpec attributes "
            f"({', '.join(sorted(_SPEC_ATTRIBUTES))}); add them to railsim.scenario.model.EventSpec"
        )
    EVENT_KINDS[kind.name] = kind
    return kind


def event_kind(type_name: str) -> EventKind:
    """The registered kind of an event ``type`` (KeyError if none)."""
    return EVENT_KINDS[type_name]


def event_keys() -> tuple[str, ...]:
    """The keys the kinds add to ``at_s`` and ``type``: every kind's fields, first use first. An event may carry
    any of them (a field of another kind is accepted and ignored, as it always was)."""
    keys = dict.fromkeys(f.key for kind in EVENT_KINDS.values() for f in kind.fields)
    return tuple(keys)


# ---- field checks ---------------------------------------------------------------------------------------------


def _formation_id(ck: Checker, value: Any, path: str, ctx: EventContext) -> str:
    ids = [f.id for f in ctx.formations]
    if not isinstance(value, str) or value not in ids:
        hint = did_you_mean(value, ids) if isinstance(value, str) else ""
        listed = ", ".join(ids) if ids else "none defined"
        raise ck.fail(path, f"expected a formation id ({listed}), got {short_repr(value)}{hint}")
    return value


def _train(ck: Checker, value: Any, path: str, ctx: EventContext) -> str:
    return trip_name(ck, value, path, ctx.services)


def _positive(ck: Checker, value: Any, path: str, ctx: EventContext) -> float:
    return ck.number(value, path, gt=0.0)


# ---- the built-in kinds ---------------------------------------------------------------------------------------

_FORMATION = EventField("formation", _formation_id)
register_event_kind(
    EventKind("couple", (_FORMATION,), "start coupling the formation now (whatever its couple trigger says)")
)
register_event_kind(EventKind("decouple", (_FORMATION,), "decouple the formation now"))
register_event_kind(
    EventKind(
        "leave",
        (EventField("train", _train),),
        "the train leaves the line (removed, e.g. to another track)",
        why_required="a leave event names the train",
    )
)
register_event_kind(
    EventKind(
        "obstacle",
        (
            EventField("train", _train),
            EventField("ahead_m", _positive),
            EventField("duration_s", _positive, required=False),
        ),
        "a static obstacle appears ahead_m ahead of the train's front; removed after duration_s (absent: stays)",
        why_required="an obstacle appears ahead of a train",
    )
)

EVENT_TYPES: tuple[str, ...] = tuple(EVENT_KINDS)  # the built-in kinds (EVENT_KINDS also holds later ones)


# ---- the section --------------------------------------------------------------------------------------------


def events(
    ck: Checker, value: Any, formations: Sequence[FormationSpec], services: Sequence[ServiceSpec] = ()
) -> tuple[tuple[EventSpec, ...], list[Any]]:
    """``events:`` → the events in file order, each checked by its kind's entry in :data:`EVENT_KINDS`."""
    if not isinstance(value, list):
        raise ck.expect("events", "a list of events", value)
    ctx = EventContext(formations=formations, services=services)
    optional, types = event_keys(), tuple(EVENT_KINDS)
    specs: list[EventSpec] = []
    raws: list[Any] = []
    for i, body in enumerate(value):
        path = f"events[{i}]"
        m = ck.mapping(body, path, _EVENT_REQUIRED, optional)
        at_s = ck.number(m["at_s"], f"{path}.at_s", ge=0.0)
        kind = EVENT_KINDS[ck.string(m["type"], f"{path}.type", types)]
        spec, raw = kind.parse(ck, m, path, at_s, ctx)
        specs.append(spec)
        raws.append(raw)
    return tuple(specs), raws
