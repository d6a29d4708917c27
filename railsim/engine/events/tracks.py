"""Single-track sections as interlocking resources: one direction at a time, reserved before entry.

A single-track section is a maximal run of ``bidi`` track between passing places (switch nodes): trains in the
same direction may be in it together (moving-block separation keeps them apart), a train in the opposite
direction may not. A train reserves the section before its protection point and releases it when its rear has
left; a reservation is granted when nobody holds the section in the other direction **and** no earlier request
for the other direction waits (first come, first served between directions, so a stream of trains one way
cannot starve the other). A train already on the single track (it holds or has held a section of its trip, so it
may stand between two sections) goes before the trains waiting to enter it: its request is **inside** and is
served before any request of the other direction from outside, however early. Else a group waiting outside kept
a train standing between two sections from the section it needed to go on, while the group waited for what that
train's opposite number held (a deadlock).

Reservations are immediate (no throw): :meth:`TrackSections.request` grants at once if it can, else queues;
every :meth:`TrackSections.release` re-examines the queue. :meth:`TrackSections.request_all` asks for several
sections as one **group**: all are granted in the same instant or none is (a train entering single track that
runs on through further sections before the next passing place; :mod:`railsim.engine.locking`). Each member keeps
its place in its own section's queue, so a group blocks later requests of the other direction in every section it
waits for, and no train of the other direction can take one section of the group while the group waits for another. Events (subject = section id): ``section_requested``,
``section_reserved``, ``section_released``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from railsim.engine.events.log import EventLog


@dataclass(eq=False)
class SectionRequest:
    """One train's (or coupled group's) request for a section in one direction."""

    holder_ids: tuple[str, ...]
    section_id: str
    direction: int
    requested_s: float
    granted_s: float | None = None
    released_by: set[str] = field(default_factory=set)
    group: list[SectionRequest] = field(default_factory=list)  # requests granted only together (request_all)
    inside: bool = False  # made by a train already on the single track: it goes before requests from outside

    @property
    def granted(self) -> bool:
        return self.granted_s is not None


@dataclass
class _Section:
    holders: list[SectionRequest] = field(default_factory=list)
    queue: list[SectionRequest] = field(default_factory=list)


class TrackSections:
    """Every single-track section of a run that trains use in both directions."""

    def __init__(self, events: EventLog, section_ids: list[str]) -> None:
        self.events = events
        self._sections = {sid: _Section() for sid in section_ids}

    def __contains__(self, section_id: str) -> bool:
        return section_id in self._sections

    def request(self, t_s: float, holder_ids: tuple[str, ...], section_id: str, direction: int) -> SectionRequest:
        return self.request_all(t_s, holder_ids, [(section_id, direction)])[0]

    def request_all(
        self, t_s: float, holder_ids: tuple[str, ...], wanted: list[tuple[str, int]], inside: bool = False
    ) -> list[SectionRequest]:
        """Request the sections ``wanted`` ((section id, direction) in route order) as one group: granted all in
        the same instant, or none; ``inside``: the train is already on the single track (module docstring)."""
        reqs = [SectionRequest(holder_ids, sid, direction, t_s, inside=inside) for sid, direction in wanted]
        for req in reqs:
            if len(reqs) > 1:
                req.group = reqs
            self._sections[req.section_id].queue.append(req)
            extra = {"with": [r.section_id for r in reqs if r is not req]} if len(reqs) > 1 else {}
            self.events.record(
                t_s, "section_requested", req.section_id, trains=list(holder_ids), direction=req.direction, **extra
            )
        self._serve(t_s, reqs[0].section_id)
        return reqs

    def release(self, t_s: float, train_id: str, req: SectionRequest) -> None:
        """``train_id`` has left the section (its rear is past the end); the request ends when all its holders did."""
        sec = self._sections[req.section_id]
        req.released_by.add(train_id)
        if req.granted and set(req.holder_ids) <= req.released_by and req in sec.holders:
            sec.holders.remove(req)
            self.events.record(t_s, "section_released", req.section_id, trains=list(req.holder_ids))
            self._serve(t_s, req.section_id)
        elif not req.granted and set(req.holder_ids) <= req.released_by and req in sec.queue:
            sec.queue.remove(req)  # withdrawn before it was granted (the train left the line)
            self._serve(t_s, req.section_id)

    def hand_over(self, t_s: float, req: SectionRequest, train_id: str, direction: int) -> SectionRequest | None:
        """A unit standing in the section starts its next trip (``train_id``, in ``direction``): the granted
        ``req`` passes to it at once, with no waiting train let in between, if every other holder runs in that
        direction; the new request, or None (then ``req`` is released as usual)."""
        sec = self._sections[req.section_id]
        if req not in sec.holders or any(h.direction != direction for h in sec.holders if h is not req):
            return None
        new = SectionRequest((train_id,), req.section_id, direction, t_s, granted_s=t_s)
        sec.holders[sec.holders.index(req)] = new
        self.events.record(
            t_s,
            "section_handed_over",
            req.section_id,
            trains=[train_id],
            after=list(req.holder_ids),
            direction=direction,
        )
        return new

    def _grantable(self, req: SectionRequest) -> bool:
        """``req`` waits in its section's queue, nobody holds the section the other way, and no request for the
        other direction waits there that goes first: an earlier one from the same side (both inside or both
        outside the single track), or one from inside when ``req`` comes from outside."""
        sec = self._sections[req.section_id]
        if req not in sec.queue or any(h.direction != req.direction for h in sec.holders):
            return False
        return not any(w.direction != req.direction and self._first(w, req) for w in sec.queue)

    @staticmethod
    def _first(w: SectionRequest, req: SectionRequest) -> bool:
        """True if waiting request ``w`` is served before ``req`` (module docstring)."""
        if w.inside != req.inside:
            return w.inside
        return w.requested_s < req.requested_s

    def _serve(self, t_s: float, section_id: str) -> None:
        sec = self._sections[section_id]
        for req in list(sec.queue):
            group = req.group or [req]
            if req.granted or not all(self._grantable(r) for r in group):
                continue
            for r in group:
                self._sections[r.section_id].queue.remove(r)
                self._sections[r.section_id].holders.append(r)
                r.granted_s = t_s
                self.events.record(
                    t_s, "section_reserved", r.section_id, trains=list(r.holder_ids), direction=r.direction
                )

    def queued(self, section_id: str) -> tuple[str, ...]:
        """Trains waiting for ``section_id`` (not yet granted)."""
        return tuple(h for req in self._sections[section_id].queue for h in req.holder_ids)

    def holders(self, section_id: str) -> tuple[str, ...]:
        """Trains holding ``section_id`` (any direction)."""
        return tuple(h for req in self._sections[section_id].holders for h in req.holder_ids)

    def waiting_ahead(self, req: SectionRequest) -> tuple[str, ...]:
        """Trains ``req`` waits for: holders in the other direction and requests for the other direction served
        first."""
        sec = self._sections[req.section_id]
        out = [h for r in sec.holders if r.direction != req.direction for h in r.holder_ids]
        out += [h for r in sec.queue if r.direction != req.direction and self._first(r, req) for h in r.holder_ids]
        return tuple(dict.fromkeys(x for x in out if x not in req.holder_ids))
