"""Timed scenario events (``events:``) and injected faults, scheduled on the simpy clock at set-up.

**One table per kind:** each event kind is one entry of :data:`railsim.scenario.events.EVENT_KINDS` (its
fields and validation) and one entry here, :data:`EVENT_HANDLERS`, under the kind's ``handler_key`` (the
function that schedules it); ``tests/unit/test_engine_ports.py`` checks the two tables name the same kinds. Each handler gets the ports it acts on (:class:`TimedPorts`), the event's index
and the event.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from railsim.engine.coupling import FormationBook
from railsim.engine.events.clock import EventLayer
from railsim.engine.events.log import EventLog
from railsim.engine.fleet import Fleet
from railsim.engine.insertion import Dispatcher
from railsim.engine.safety import SafetyMonitor
from railsim.scenario.events import event_kind


@dataclass
class TimedPorts:
    layer: EventLayer
    events: EventLog
    fleet: Fleet
    formations: FormationBook
    dispatcher: Dispatcher
    safety: SafetyMonitor


def _obstacle(p: TimedPorts, n: int, ev: Any) -> None:
    p.layer.at(float(ev.at_s), lambda _t: p.safety.place_obstacle(f"obstacle{n}", ev), "obstacle_due", ev.train)


def _leave(p: TimedPorts, n: int, ev: Any) -> None:
    p.layer.at(float(ev.at_s), lambda _t: p.dispatcher.leave(p.fleet.trains[ev.train]), "leave_due", ev.train)


def _couple(p: TimedPorts, n: int, ev: Any) -> None:
    p.formations.manager.request_couple(ev.formation, at_s=float(ev.at_s))


def _decouple(p: TimedPorts, n: int, ev: Any) -> None:
    p.formations.manager.request_decouple(ev.formation, at_s=float(ev.at_s))


EVENT_HANDLERS: dict[str, Callable[[TimedPorts, int, Any], None]] = {
    "obstacle": _obstacle,
    "leave": _leave,
    "couple": _couple,
    "decouple": _decouple,
}


def _fault_logger(p: TimedPorts, bias: Any) -> Callable[[float], None]:
    def call(_t: float) -> None:
        p.events.record(
            p.layer.now_s,
            "actuator_fault",
            bias.train,
            accel_mps2=bias.accel_mps2,
            until_s=bias.until_s if math.isfinite(bias.until_s) else None,
        )

    return call


def schedule(p: TimedPorts, scenario: Any) -> None:
    """Formation triggers at fixed times, injected actuator faults (made visible in events.csv), timed events."""
    p.formations.schedule_commands(scenario.formations)
    for bias in scenario.faults.actuator_bias:
        p.layer.at(bias.from_s, _fault_logger(p, bias), "actuator_fault_due", bias.train)
    for n, ev in enumerate(scenario.events):
        EVENT_HANDLERS[event_kind(ev.type).handler_key](p, n, ev)
