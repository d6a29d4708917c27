"""The clock of the event layer: a simpy environment that follows SUMO's time.

SUMO advances in fixed steps (dt = 0.1–1 s); the things that happen *between* steps — a message that
arrives 37 ms after it was sent, a beam switch that finishes throwing 15 s after it started, a departure
due at 08:00:00 — are simpy events with exact times. The engine owns the step loop (docs/architecture.md) and, at
every step k, calls ``layer.advance_to(t_k)``. That runs every event whose time is **≤ t_k**, in time order
(ties in the order they were scheduled), and leaves ``layer.now_s == t_k``. Then the engine reads the
results (mailboxes, lock grants, formation states) and acts for the step.

Reading of the boundary: an event due at exactly ``t_k`` has happened when the engine looks at step k
(plain ``env.run(until=t_k)`` would leave it for the next step, one dt late).

Time is monotonic. ``advance_to(t)`` with ``t`` before ``now_s`` raises :class:`ValueError` (the engine has a
bug). ``advance_to(now_s)`` does not move time; it only runs events that became due *at* ``now_s`` since the
last call — e.g. a zero-delay consequence of a request the engine made after advancing. With nothing due it
does nothing.

Exact times
-----------
simpy schedules an event at ``now + delay``, and in floating point no delay may land exactly on a given
``t`` (from now = 6.144, the sums jump from 28.364999999999995 to 28.365000000000002 and never hit 28.365).
So the layer's environment is simpy's :class:`~simpy.Environment` with one addition, scheduling at an
absolute time (:class:`ExactEnvironment`, :class:`TimeoutAt`), and every timer of the layer
(:meth:`EventLayer.timeout_at`) goes through it: a time written in the log equals the time that was asked for,
bit for bit. ``now_s`` after ``advance_to(t)`` is ``t`` itself: the layer sets simpy's clock there once the
events due have run (a step with nothing due touches simpy no further).
This reaches into simpy's event queue exactly as ``Environment.schedule`` does (``_queue``, ``_eid``, and
``_ok``/``_value`` as ``simpy.Timeout`` sets them; ``_now`` as ``Environment.step`` sets it, for light deliveries
and the end of an advance); the clock tests pin it against the installed simpy.
Relative timers (a throw lasting ``throw_time_s``, a message delay) stay plain ``env.timeout``: there the
promised time *is* ``now + delay``.

Light deliveries
----------------
A radio message is the most frequent timed thing (one per train and step and channel). It needs no simpy
process, only "call this with that at ``t``", so :meth:`EventLayer.deliver_at` keeps such calls in a heap of
plain tuples beside simpy's queue. Each takes an event id from simpy's own counter when it is queued, and
:meth:`EventLayer.advance_to` merges the two queues by ``(time, priority, event id)`` — exactly the order simpy
would have run the same calls as timeouts scheduled at those moments, with ``now_s`` standing at the call's time.

A channel with random delays has thousands of messages in flight; it keeps them itself, as a :class:`Source`
(:meth:`EventLayer.add_source`): each message still takes its event id when it goes in flight, and the source tells
the layer the ``(time, id)`` of its next delivery. When that is the earliest thing due, the layer asks the source to
deliver everything of its own that sorts before the next thing that is not (the heads of the heap, of simpy's
queue and, where someone watches deliveries, of the other sources) — in one call, without a heap entry per message.
Nothing else happens in between, so the order is the one a light delivery per message would give.

Randomness
----------
The layer holds the scenario's ``numpy.random.Generator``. Modules that draw random numbers ask for their
own child stream (:meth:`EventLayer.spawn_rng`), so adding draws in one module (say, more messages on a
channel) does not reshuffle another module's draws. No ``random`` module, no global state.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator, Iterable
from dataclasses import dataclass, field
from heapq import heappop, heappush
from itertools import islice

import numpy as np
import simpy
from simpy.events import NORMAL, EventPriority

from railsim.engine.events.log import EventLog


class ExactEnvironment(simpy.Environment):
    """simpy's environment plus :meth:`schedule_at`: put an event in the queue at an absolute time."""

    def schedule_at(self, event: simpy.Event, t_s: float, priority: EventPriority = NORMAL) -> None:
        """Schedule ``event`` at exactly ``t_s`` (≥ now); same queue and tie-breaking as ``schedule``."""
        if not t_s >= self._now:
            raise ValueError(f"time {t_s!r} s is before now ({self._now!r} s)")
        # The queue entry layout is simpy's own (time, priority, event id, event), as in Environment.schedule.
        heappush(self._queue, (t_s, priority, next(self._eid), event))


class TimeoutAt(simpy.Event):
    """Like :class:`simpy.Timeout`, but at an absolute time ``t_s`` instead of after a delay."""

    def __init__(self, env: ExactEnvironment, t_s: float, value: object = None) -> None:
        super().__init__(env)
        # Triggered at creation, exactly as simpy.Timeout does it; processed when the clock reaches t_s.
        self._ok = True
        self._value = value
        env.schedule_at(self, t_s)


class Source:
    """Timed deliveries kept by their owner in their own order (a channel's messages in flight, see "Light
    deliveries"), each with an event id from simpy's counter. ``head_t``/``head_eid``: the time and id of the next
    one (``head_t`` infinite: none); ``watched_now``: someone outside sees each delivery (then the layer has it
    deliver one at a time, the clock at its time)."""

    def __init__(self) -> None:
        self.head_t = math.inf
        self.head_eid = 0
        self.watched_now = False

    def deliver_before(self, limit_t: float, limit_p: int, limit_eid: int, until_s: float, one: bool) -> None:
        """Deliver, in ``(time, id)`` order, those due at or before ``until_s`` that sort before ``(limit_t,
        limit_p, limit_eid)`` (time, priority, id of the next thing that is not this source's); only the first of
        them if ``one``. Afterwards ``head_t``/``head_eid`` name the next one left."""
        raise NotImplementedError


@dataclass(eq=False)
class ScheduledCall:
    """Handle for a callback scheduled with :meth:`EventLayer.at` or :meth:`EventLayer.every`."""

    t_s: float
    kind: str | None
    subject: str
    fired_count: int = 0
    cancelled: bool = field(default=False)

    def cancel(self) -> None:
        """Do not fire (any more). Cancelling twice, or after firing, is harmless."""
        self.cancelled = True


class EventLayer:
    """Owns the simpy environment, the event log and the random generator of one simulation.

    Args:
        t0_s: simulated time at which the environment starts (the scenario's start time).
        rng: the scenario's seeded generator; the only source of randomness of the layer.
        log: an existing log to append to (a new one by default).
    """

    def __init__(self, t0_s: float, rng: np.random.Generator, log: EventLog | None = None) -> None:
        t0_s = float(t0_s)
        if not math.isfinite(t0_s):
            raise ValueError(f"start time must be finite, got {t0_s!r}")
        if not isinstance(rng, np.random.Generator):
            raise TypeError("rng must be a numpy.random.Generator (seeded by the scenario)")
        self.env = ExactEnvironment(initial_time=t0_s)
        self.log = log if log is not None else EventLog()
        self.rng = rng
        # light deliveries: (time, priority, simpy event id, callback, value), see "Light deliveries"
        self._light: list[tuple[float, EventPriority, int, Callable[[object], object], object]] = []
        self._sources: list[Source] = []  # deliveries their owners keep (:meth:`add_source`)

    @property
    def now_s(self) -> float:
        """Current simulated time, seconds."""
        return float(self.env.now)

    def advance_to(self, t_s: float) -> None:
        """Run every event due at or before ``t_s``; afterwards ``now_s == t_s``.

        Nothing due (the common case: the engine calls this twice a step) costs two comparisons with the heads of
        the two queues; the clock then just stands at ``t_s``. Otherwise the events run in order and the clock is
        set to ``t_s`` after the last of them — what a no-op marker event at ``t_s`` would do, without one.
        """
        t_s = float(t_s)
        env = self.env
        if not math.isfinite(t_s):
            raise ValueError(f"cannot advance to a non-finite time {t_s!r}")
        if t_s < env._now:
            raise ValueError(f"time goes forward only: asked to advance to {t_s!r} s, now is {env.now!r} s")
        light = self._light
        queue = env._queue
        sources = self._sources
        if (not light or light[0][0] > t_s) and (not queue or queue[0][0] > t_s) and self._sources_after(t_s):
            env._now = t_s
            return
        while True:
            # the earliest of the heap's head, simpy's head and each source's next delivery, by (time, priority, id)
            kind = 0
            best_t, best_p, best_e = math.inf, 0, 0
            if light:
                head = light[0]
                kind, best_t, best_p, best_e = 1, head[0], head[1], head[2]
            if queue:
                q = queue[0]
                if kind == 0 or _before(q[0], q[1], q[2], best_t, best_p, best_e):
                    kind, best_t, best_p, best_e = 2, q[0], q[1], q[2]
            src: Source | None = None
            for s in sources:
                if s.head_t <= t_s and (kind == 0 or _before(s.head_t, NORMAL, s.head_eid, best_t, best_p, best_e)):
                    kind, best_t, best_p, best_e, src = 3, s.head_t, NORMAL, s.head_eid, s
            if kind == 0 or best_t > t_s:
                break
            if kind == 1:
                when, _, _, callback, value = heappop(light)
                env._now = when  # as simpy's step sets it: the call sees the clock at its own time
                callback(value)
            elif kind == 2:
                env.step()
            else:
                assert src is not None
                self._drain(src, t_s)
        env._now = t_s

    def _sources_after(self, t_s: float) -> bool:
        """Is every source's next delivery after ``t_s``?"""
        for s in self._sources:
            if s.head_t <= t_s:
                return False
        return True

    def _drain(self, src: Source, t_s: float) -> None:
        """Let ``src`` deliver what it has before the next thing that is not its own: the heap's head, simpy's
        head and, if ``src`` or another source is watched, that source's next delivery."""
        limit_t, limit_p, limit_e = math.inf, 0, 0
        light = self._light
        queue = self.env._queue
        if light:
            limit_t, limit_p, limit_e = light[0][0], light[0][1], light[0][2]
        if queue:
            q = queue[0]
            if _before(q[0], q[1], q[2], limit_t, limit_p, limit_e):
                limit_t, limit_p, limit_e = q[0], q[1], q[2]
        for s in self._sources:
            if s is not src and (s.watched_now or src.watched_now):
                if _before(s.head_t, NORMAL, s.head_eid, limit_t, limit_p, limit_e):
                    limit_t, limit_p, limit_e = s.head_t, NORMAL, s.head_eid
        src.deliver_before(limit_t, limit_p, limit_e, t_s, src.watched_now)

    def add_source(self, source: Source) -> None:
        """Have :meth:`advance_to` run ``source``'s deliveries in their place among the rest (see "Light
        deliveries")."""
        self._sources.append(source)

    def next_eids(self, n: int) -> list[int]:
        """The next ``n`` event ids from simpy's counter (the tie-break of equal times), as scheduling ``n`` events
        one after another takes them."""
        return list(islice(self.env._eid, n))

    def deliver_at(self, t_s: float, callback: Callable[[object], object], value: object) -> None:
        """Call ``callback(value)`` at exactly ``t_s`` (≥ now), in simpy's order (see "Light deliveries")."""
        self.deliver_all(callback, ((t_s, value),))

    def deliver_all(self, callback: Callable[[object], object], timed: Iterable[tuple[float, object]]) -> None:
        """:meth:`deliver_at` for each ``(t_s, value)`` in turn (the event ids taken in this order)."""
        env = self.env
        now = env._now
        light = self._light
        eid = env._eid
        for t_s, value in timed:
            if not t_s >= now:
                raise ValueError(f"time {t_s!r} s is before now ({now!r} s)")
            heappush(light, (t_s, NORMAL, next(eid), callback, value))

    def timeout_at(self, t_s: float, value: object = None) -> TimeoutAt:
        """A simpy event that fires at exactly ``t_s`` (≥ now); ``yield`` it inside a process."""
        return TimeoutAt(self.env, float(t_s), value)

    def spawn_rng(self) -> np.random.Generator:
        """An independent child stream of the scenario generator (deterministic in call order)."""
        return self.rng.spawn(1)[0]

    def at(self, t_s: float, callback: Callable[[float], object], kind: str | None, subject: str = "") -> ScheduledCall:
        """Call ``callback(t_s)`` at exactly ``t_s``; the firing is logged as ``kind``/``subject`` (not if None).

        ``t_s`` may equal now (it fires on the next :meth:`advance_to`, stamped ``t_s``); before now raises.
        The log row is written before the callback runs, so anything the callback logs comes after it.
        """
        t_s = float(t_s)
        if not math.isfinite(t_s) or t_s < self.env.now:
            raise ValueError(f"cannot schedule {kind} for {subject} at {t_s!r} s (now {self.env.now!r} s)")
        handle = ScheduledCall(t_s, kind, subject)
        self.env.process(self._fire_once(handle, callback))
        return handle

    def _fire_once(
        self, handle: ScheduledCall, callback: Callable[[float], object]
    ) -> Generator[simpy.Event, None, None]:
        yield self.timeout_at(handle.t_s)
        if handle.cancelled:
            return
        handle.fired_count += 1
        if handle.kind is not None:
            self.log.record(handle.t_s, handle.kind, handle.subject)
        callback(handle.t_s)

    def every(
        self,
        period_s: float,
        callback: Callable[[float], object],
        start_s: float | None = None,
        kind: str | None = None,
        subject: str = "",
    ) -> ScheduledCall:
        """Call ``callback(t)`` at ``t = start + n·period_s`` for n = 0, 1, 2, … until cancelled.

        Times are computed as ``start + n·period`` (not accumulated) so they do not drift. Periodic ticks
        are not logged unless ``kind`` is given (they would flood the log). ``start_s`` defaults to now.
        """
        period_s = float(period_s)
        if not (math.isfinite(period_s) and period_s > 0.0):
            raise ValueError(f"period must be a finite number > 0 s, got {period_s!r}")
        start = self.now_s if start_s is None else float(start_s)
        if not math.isfinite(start) or start < self.env.now:
            raise ValueError(f"periodic call cannot start at {start!r} s (now {self.env.now!r} s)")
        handle = ScheduledCall(start, kind, subject)
        self.env.process(self._fire_periodically(handle, period_s, callback))
        return handle

    def _fire_periodically(
        self, handle: ScheduledCall, period_s: float, callback: Callable[[float], object]
    ) -> Generator[simpy.Event, None, None]:
        n = 0
        while True:
            t_s = handle.t_s + n * period_s
            yield self.timeout_at(t_s)
            if handle.cancelled:
                return
            handle.fired_count += 1
            if handle.kind is not None:
                self.log.record(t_s, handle.kind, handle.subject, n=n)
            callback(t_s)
            n += 1


def _before(t1: float, p1: int, e1: int, t2: float, p2: int, e2: int) -> bool:
    """Does ``(t1, p1, e1)`` sort before ``(t2, p2, e2)`` (simpy's order of events: time, priority, id)?"""
    return t1 < t2 or (t1 == t2 and (p1 < p2 or (p1 == p2 and e1 < e2)))
