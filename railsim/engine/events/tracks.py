"""Single-track sections as interlocking resources: one direction at a time, reserved before entry.

A single-track section is a maximal run of ``bidi`` track between passing places (switch nodes): trains in the
same direction may be in it together (moving-block separation keeps them apart), a train in the opposite
direction may not. A train reserves the section before its protection point and releases it when its rear has
left; a reservation is granted when nobody holds the section in the other direction **and** no earlier request
for the other direction waits (first come, first served between directions, so a stream of trains one way
cannot starve the other). Two exceptions keep the trains moving. A request never waits for one that itself
waits for a section its own train holds: that group cannot be served before this train has gone on (a group
waiting outside kept a train standing between two sections from the section it needed, while the group waited
for what that train's opposite number held). And a train whose trip ends beyond the single track (a terminus: its
unit comes back through the section or leaves service there) **yields**: requests of the other direction go first, however late —
they are the trains leaving that terminus and making room there; let in first, the arriving trams found the
turning loop full of units waiting to leave through the section they held. Nor is such a request granted while
the terminus has no **room** for its train, nor before such requests of its direction made earlier beside the units standing there and the trains already let in
(``room_beyond``, asked of :mod:`railsim.engine.section_requests`): granted the approach together, four trams
filled the Zwätzen Schleife loop, and the last stood in the single track behind a unit waiting to leave through it.

Reservations are immediate (no throw): :meth:`TrackSections.request` grants at once if it can, else queues;
every :meth:`TrackSections.release` re-examines the queue. :meth:`TrackSections.request_all` asks for several
sections as one **group**: all are granted in the same instant or none is (a train entering single track that
runs on through further sections before the next passing place; :mod:`railsim.engine.locking`). Each member keeps
its place in its own section's queue, so a group blocks later requests of the other direction in every section it
waits for, and no train of the other direction can take one section of the group while the group waits for another.
A waiting request for one section **widens** into such a group (:meth:`TrackSections.extend`, keeping its turn)
when the room its train would wait in beyond the section has filled since it asked. And a waiting request is **let
through** (:meth:`TrackSections.let_through`) ahead of the other direction's when the train side finds a train
holding the section the same way standing behind it: that train cannot pass it, so the request is part of that
grant — and so are the other sections of its group that train holds too, whichever requests rank first there. For the same reason a request of the other direction does not go first against a train whose follower
holds the section that train waits for (:meth:`TrackSections._behind`): the follower leaves it only after that train
has passed through, so the request would wait for the very train it kept waiting (Jena: a tram granted the approach
behind a unit that had just turned in front of it, the unit waiting behind an opposing tram that waited for the
follower) — nor against a train that a holder of a section the request waits for stands in a line behind, each
train right behind the next (:meth:`TrackSections._in_line`): that holder too leaves only after that train has moved
on. And a train that comes to stand in front of a train of its direction that asked earlier (a unit turned
back there) takes its place in the order between directions (:meth:`TrackSections._since`). Events (subject =
section id): ``section_requested``, ``section_reserved``, ``section_released``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from railsim.engine.events.log import EventLog

# A track section's direction from this one on is a train's own (the train side gives it to a train reversing inside
# the section, or shut in behind it while it turns in a stub beyond): nobody else shares it.
OWN_DIRECTION = 2


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
    yields: bool = False  # its train's trip ends beyond the section (a terminus): the other direction goes first
    # where the section begins on its train's route, set by the train side for a route that runs through the same
    # section more than once (None: its first time through)
    pass_m: float | None = None

    @property
    def granted(self) -> bool:
        return self.granted_s is not None


@dataclass
class _Section:
    holders: list[SectionRequest] = field(default_factory=list)
    queue: list[SectionRequest] = field(default_factory=list)


class TrackSections:
    """Every single-track section of a run that trains use in both directions."""

    def __init__(
        self, events: EventLog, section_ids: list[str], room_beyond: Callable[[SectionRequest], bool] | None = None
    ) -> None:
        self.events = events
        self._sections = {sid: _Section() for sid in section_ids}
        self.versions: dict[str, int] = {}  # train id -> changes to its section requests (:meth:`version`)
        # for a request that yields: is there room for its train at the terminus beyond? (module docstring)
        self.room_beyond = room_beyond
        # train id -> the train directly in front of it on its route, as the train side last saw it (:meth:`_behind`)
        self.in_front: dict[str, str | None] = {}

    def __contains__(self, section_id: str) -> bool:
        return section_id in self._sections

    def request(self, t_s: float, holder_ids: tuple[str, ...], section_id: str, direction: int) -> SectionRequest:
        return self.request_all(t_s, holder_ids, [(section_id, direction)])[0]

    def request_all(
        self, t_s: float, holder_ids: tuple[str, ...], wanted: list[tuple[str, int]], yields: bool = False
    ) -> list[SectionRequest]:
        """Request the sections ``wanted`` ((section id, direction) in route order) as one group: granted all in
        the same instant, or none; ``yields``: the train turns beyond them (module docstring)."""
        reqs = [SectionRequest(holder_ids, sid, direction, t_s, yields=yields) for sid, direction in wanted]
        self._changed(holder_ids)
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

    def extend(
        self, t_s: float, req: SectionRequest, wanted: list[tuple[str, int]], yields: bool = False
    ) -> list[SectionRequest]:
        """Widen the waiting request ``req`` into a group with the sections ``wanted`` ((section id, direction) in
        route order, after ``req``'s): all granted in the same instant, or none. The new requests count as made
        when ``req`` was (it keeps its turn against the other direction); ``yields`` as in :meth:`request_all`, for
        the whole group. Returns the new requests."""
        assert not req.granted and not req.group and req in self._sections[req.section_id].queue
        new = [SectionRequest(req.holder_ids, sid, d, req.requested_s, yields=yields) for sid, d in wanted]
        self._changed(req.holder_ids)
        req.group = [req, *new]
        req.yields = yields
        for r in new:
            r.group = req.group
            self._sections[r.section_id].queue.append(r)
            self.events.record(
                t_s,
                "section_requested",
                r.section_id,
                trains=list(r.holder_ids),
                direction=r.direction,
                **{"with": [x.section_id for x in req.group if x is not r]},
            )
        for r in req.group:  # the other direction may go first now (_waits_for)
            self._serve(t_s, r.section_id)
        return new

    def let_through(self, t_s: float, req: SectionRequest, behind: tuple[str, ...] = ()) -> bool:
        """Grant the waiting ``req`` at once, before the requests of the other direction it would wait for, as
        the caller found that a train holding the section ``req``'s way stands behind ``req``'s train and cannot
        pass through before it (module docstring); the other sections of its group only if they are grantable,
        or held their way by a train of ``behind`` (the train behind, holding them too: it cannot pass through
        them before ``req``'s train either, whichever requests of the other direction go first there, nor before
        the trains turning beyond them that asked earlier). True if granted."""
        sec = self._sections[req.section_id]
        if req not in sec.queue or not any(h.direction == req.direction for h in sec.holders):
            return False
        if any(h.direction != req.direction for h in sec.holders):
            return False
        if any(not self._grantable(r) and not self._held_behind(r, behind) for r in req.group if r is not req):
            return False
        for r in req.group or [req]:
            self._sections[r.section_id].queue.remove(r)
            self._sections[r.section_id].holders.append(r)
            r.granted_s = t_s
            self._changed(r.holder_ids)
            self.events.record(t_s, "section_reserved", r.section_id, trains=list(r.holder_ids), direction=r.direction)
        return True

    def _held_behind(self, req: SectionRequest, behind: tuple[str, ...]) -> bool:
        """``req`` waits in its section's queue, nobody holds the section the other way, and a train of ``behind``
        holds it ``req``'s way (:meth:`let_through`)."""
        sec = self._sections[req.section_id]
        if req not in sec.queue or any(h.direction != req.direction for h in sec.holders):
            return False
        return any(not set(h.holder_ids).isdisjoint(behind) for h in sec.holders)

    def set_in_front(self, t_s: float, train_id: str, front_id: str | None) -> None:
        """The train side saw ``front_id`` (None: none) right in front of ``train_id``: when that changed, the
        sections ``front_id`` waits for are served again, as its place in their order may have moved on
        (:meth:`_since`, :meth:`_behind`)."""
        if self.in_front.get(train_id, "") == front_id:
            return
        self.in_front[train_id] = front_id
        if front_id is not None:
            for sid, sec in self._sections.items():
                if any(front_id in q.holder_ids for q in sec.queue):
                    self._serve(t_s, sid)

    def release(self, t_s: float, train_id: str, req: SectionRequest) -> None:
        """``train_id`` has left the section (its rear is past the end); the request ends when all its holders did."""
        sec = self._sections[req.section_id]
        req.released_by.add(train_id)
        self._changed(req.holder_ids)
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
        self._changed((train_id, *req.holder_ids))
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

    def _changed(self, trains: tuple[str, ...]) -> None:
        """A section request of ``trains`` was made, granted, widened, handed over or released (:meth:`version`)."""
        versions = self.versions
        for h in trains:
            versions[h] = versions.get(h, 0) + 1

    def version(self, train_id: str) -> int:
        """A count that moves on whenever a section request ``train_id`` is one of the holders of is made,
        granted, widened, handed over or released: while it stays the same, so do the train's requests and which
        of them are granted (the train side keeps each request it makes in its own book in the same step)."""
        return self.versions.get(train_id, 0)

    def _grantable(self, req: SectionRequest) -> bool:
        """``req`` waits in its section's queue, nobody holds the section the other way, and no request for the
        other direction that goes first waits there (:meth:`_first`)."""
        sec = self._sections[req.section_id]
        if req not in sec.queue or any(h.direction != req.direction for h in sec.holders):
            return False
        if req.yields and self.room_beyond is not None:
            earlier = sec.queue[: sec.queue.index(req)]
            if any(w.yields and w.direction == req.direction for w in earlier) or not self.room_beyond(req):
                return False  # the turning trains are let in in the order they asked, each when there is room
        return not any(self._first(w, req) for w in sec.queue)

    def _first(self, w: SectionRequest, req: SectionRequest) -> bool:
        """True if waiting request ``w`` is served before ``req``: it is for the other direction, does not wait for
        a section ``req``'s train holds, and is the earlier one — unless exactly one of the two yields (module
        docstring)."""
        if w.direction == req.direction or self._waits_for(w, req.holder_ids):
            return False
        if w.yields != req.yields:
            return req.yields
        return self._since(w) < self._since(req)

    def _since(self, req: SectionRequest) -> float:
        """When ``req`` counts as made against the other direction: when it was, or when a train standing right
        behind one of its trains (``in_front``) asked for a section of its group the same way, if earlier — the
        train in front takes that place, as the one behind cannot go before it (module docstring)."""
        since = req.requested_s
        for r in req.group or [req]:
            sec = self._sections[r.section_id]
            for q in (*sec.holders, *sec.queue):
                if (
                    q.requested_s < since
                    and q.direction == r.direction
                    and any(self.in_front.get(x) in req.holder_ids for x in q.holder_ids)
                ):
                    since = q.requested_s
        return since

    def _waits_for(self, w: SectionRequest, trains: tuple[str, ...]) -> bool:
        """True if a member of ``w``'s group waits for a section one of ``trains`` holds the other way, or that a
        train standing behind one of them holds it (:meth:`_behind`)."""
        for r in w.group or [w]:
            for h in self._sections[r.section_id].holders:
                if h.direction != r.direction and (
                    not set(h.holder_ids).isdisjoint(trains) or self._behind(h, trains) or self._in_line(h, trains)
                ):
                    return True
        return False

    def _in_line(self, h: SectionRequest, trains: tuple[str, ...]) -> bool:
        """True if a train holding ``h`` stands in a line behind one of ``trains``: following the trains in front
        (``in_front``, as the train side last saw them) from it reaches one of them. It cannot leave the section
        before that train has moved on, so a request waiting for ``h``'s section cannot be served before that
        train's either. A tram holding the section beyond Platz der Einheit/West stood behind two trams at the
        platform, the first waiting for the section before it, which an opposing group waiting for the first
        tram's section had asked for earlier (Potsdam, all lines every 680 s: deadlock at 3,244.5 s)."""
        for x in h.holder_ids:
            seen = {x}
            front = self.in_front.get(x)
            while front is not None and front not in seen:
                if front in trains:
                    return True
                seen.add(front)
                front = self.in_front.get(front)
        return False

    def _behind(self, h: SectionRequest, trains: tuple[str, ...]) -> bool:
        """True if a train holding ``h`` stands right behind one of ``trains`` (``in_front``) that waits for ``h``'s
        section the same way: it cannot leave the section before that train has passed through it, so a request of
        the other direction waiting for it cannot be served before that train's either (module docstring)."""
        waiting = {
            x for q in self._sections[h.section_id].queue if q.direction == h.direction for x in q.holder_ids
        }.intersection(trains)
        return bool(waiting) and any(self.in_front.get(x) in waiting for x in h.holder_ids)

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
                self._changed(r.holder_ids)
                self.events.record(
                    t_s, "section_reserved", r.section_id, trains=list(r.holder_ids), direction=r.direction
                )

    def requests(self, section_id: str) -> tuple[SectionRequest, ...]:
        """The requests holding ``section_id`` and those waiting for it."""
        sec = self._sections[section_id]
        return tuple(sec.holders) + tuple(sec.queue)

    def waiting(self, section_id: str) -> tuple[SectionRequest, ...]:
        """The requests waiting for ``section_id`` (not yet granted), in the order they were made."""
        return tuple(self._sections[section_id].queue)

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
        out += [h for r in sec.queue if self._first(r, req) for h in r.holder_ids]
        return tuple(dict.fromkeys(x for x in out if x not in req.holder_ids))
