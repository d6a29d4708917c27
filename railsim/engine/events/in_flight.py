"""Messages in flight, kept by their channel in the order they will arrive.

A channel with random delays (uniform, normal, lognormal, exponential) has, at every moment, a few steps' worth of
messages on their way: thousands on a large network. Each went in flight with an event id from simpy's counter
(the tie-break of equal times) and must arrive exactly where a timed event of its own would — among the other
timed things of the event layer, in ``(time, priority, id)`` order. :class:`InFlight` keeps them as batches, one
per sending (a step's reports), each sorted by ``(time, id)``, and is a :class:`~railsim.engine.events.clock.Source`
of the event layer: when its next message is the earliest thing due, the layer asks it for everything it holds
that sorts before the next thing that is not its own, and :class:`InFlight` hands those to the channel in one call
(``deliver``), or only the first with its time (``deliver_one``) when someone watches every delivery.

Why the order comes out right without a heap: a batch's ids are consecutive in the order it was sent and a later
batch's ids are all larger, so the due part of every batch, joined in the order the batches were sent and sorted
by time alone with a stable sort, is in ``(time, id)`` order. ``tests/unit/test_events_fast_paths.py`` holds the
channel to one timed delivery per message, ties with each other and with timed events included.
"""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right
from collections.abc import Callable
from typing import Any

from railsim.engine.events.clock import Source


class _Batch:
    """Messages sent at once, sorted by (delivery time, event id), and how many have been handed on."""

    __slots__ = ("times", "eids", "items", "pos")

    def __init__(self, times: list[float], eids: list[int], items: list[Any]) -> None:
        self.times = times
        self.eids = eids
        self.items = items
        self.pos = 0

    def due_end(self, limit_t: float, limit_p: int, limit_eid: int, until_s: float) -> int:
        """The end of the messages due at or before ``until_s`` that sort before ``(limit_t, limit_p, limit_eid)``
        (a message's priority is simpy's NORMAL, 1)."""
        times = self.times
        if limit_t > until_s:
            return bisect_right(times, until_s, self.pos)
        end = bisect_left(times, limit_t, self.pos)
        if limit_p >= 1:  # at the limit's time: those of a smaller id (all, if the limit is less urgent)
            eids = self.eids
            while end < len(times) and times[end] == limit_t and (limit_p > 1 or eids[end] < limit_eid):
                end += 1
        return end


class InFlight(Source):
    """A channel's messages in flight (module docstring). ``deliver(items)``: hand on messages in their order;
    ``deliver_one(t, item)``: one message at its time ``t`` (used while :attr:`watched_now`)."""

    def __init__(self, deliver: Callable[[list[Any]], object], deliver_one: Callable[[float, Any], object]) -> None:
        super().__init__()
        self._deliver = deliver
        self._deliver_one = deliver_one
        self._batches: list[_Batch] = []

    def add(self, times: list[float], eids: list[int], items: list[Any]) -> None:
        """Messages sent at once: their delivery times and event ids (increasing, in the order sent)."""
        order = sorted(range(len(items)), key=times.__getitem__)  # stable: equal times keep their ids' order
        batch = _Batch([times[i] for i in order], [eids[i] for i in order], [items[i] for i in order])
        self._batches.append(batch)
        if _sooner(batch.times[0], batch.eids[0], self.head_t, self.head_eid):
            self.head_t, self.head_eid = batch.times[0], batch.eids[0]

    def deliver_before(self, limit_t: float, limit_p: int, limit_eid: int, until_s: float, one: bool) -> None:
        if one:
            self._first()
        else:
            due_t: list[float] = []
            due: list[Any] = []
            for b in self._batches:
                end = b.due_end(limit_t, limit_p, limit_eid, until_s)
                if end > b.pos:
                    due_t += b.times[b.pos : end]
                    due += b.items[b.pos : end]
                    b.pos = end
            if len(due) > 1:
                due = [due[i] for i in sorted(range(len(due)), key=due_t.__getitem__)]
            if due:
                self._deliver(due)
        self._batches = [b for b in self._batches if b.pos < len(b.items)]
        self.head_t, self.head_eid = math.inf, 0
        for b in self._batches:
            if _sooner(b.times[b.pos], b.eids[b.pos], self.head_t, self.head_eid):
                self.head_t, self.head_eid = b.times[b.pos], b.eids[b.pos]

    def _first(self) -> None:
        """Hand on the first message in flight, with its time."""
        best: _Batch | None = None
        best_t, best_e = math.inf, 0
        for b in self._batches:
            if b.pos < len(b.items) and _sooner(b.times[b.pos], b.eids[b.pos], best_t, best_e):
                best, best_t, best_e = b, b.times[b.pos], b.eids[b.pos]
        if best is not None:
            item = best.items[best.pos]
            best.pos += 1
            self._deliver_one(best_t, item)


def _sooner(t1: float, e1: int, t2: float, e2: int) -> bool:
    """Does the delivery ``(t1, e1)`` come before ``(t2, e2)`` (time, then event id; ``t2`` infinite: none)?"""
    return t1 < t2 or (t1 == t2 and e1 < e2)
