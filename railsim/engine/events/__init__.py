"""The simpy event layer: what happens between (and across) SUMO steps.

One module per concept (docs/architecture.md):

- :mod:`~railsim.engine.events.clock` — :class:`EventLayer`, the simpy environment advanced to SUMO time;
- :mod:`~railsim.engine.events.log` — :class:`EventLog`, one row per timed event;
- :mod:`~railsim.engine.events.formations` — virtual-coupling state machines (couple/decouple commands);
- :mod:`~railsim.engine.events.interlocking` — switch locks with throw times, FIFO;
- :mod:`~railsim.engine.events.comms` — delayed, lossy radio channels with outage windows;
- :mod:`~railsim.engine.events.dispatch` — departures due at exact timetable times.

Typical wiring in the engine::

    layer = EventLayer(t0_s, rng=rng)
    formations, interlocking = FormationManager(layer), Interlocking(layer)
    t2t = Channel(layer, "t2t", DelaySpec("normal", mean_s=0.1, std_s=0.03), loss_prob=0.01)
    for k in range(n_steps):
        t = t0_s + k * dt
        layer.advance_to(t)          # deliveries, throws, grants, due commands — all at exact times
        ...                          # observe, control, step SUMO
"""

from railsim.engine.events.clock import EventLayer, ExactEnvironment, ScheduledCall, TimeoutAt
from railsim.engine.events.comms import CHANNEL_NAMES, Channel, ChannelStats, DelaySpec, Message, Outage
from railsim.engine.events.dispatch import Dispatcher
from railsim.engine.events.formations import Formation, FormationManager, FormationState, FormationStats
from railsim.engine.events.interlocking import LEGS, Interlocking, LockRequest, RequestState, Switch
from railsim.engine.events.log import EventLog, LogEntry

__all__ = [
    "CHANNEL_NAMES",
    "LEGS",
    "Channel",
    "ChannelStats",
    "DelaySpec",
    "Dispatcher",
    "EventLayer",
    "EventLog",
    "ExactEnvironment",
    "Formation",
    "FormationManager",
    "FormationState",
    "FormationStats",
    "Interlocking",
    "LockRequest",
    "LogEntry",
    "Message",
    "Outage",
    "RequestState",
    "ScheduledCall",
    "Switch",
    "TimeoutAt",
]
