"""The room at a terminus beyond single track: whether a train coming in through the last section still fits there.

A train whose trip ends beyond its last single-track section stands at the terminus, and only the trains leaving
make room there: let in while the terminus is full, it would stand in the section, holding it against the very
trains that would make room (:mod:`railsim.engine.section_requests`, "Order on single track").
:meth:`TerminusRoom._room_beyond` is the test :class:`~railsim.engine.events.tracks.TrackSections` asks before it
grants such a train the section: the room from the section's end to the end of the destination platform — or,
where the unit turns beyond the platform (round a loop, or by a reversal on a track beyond), the whole track it has
there (:meth:`TerminusRoom._turning_track_m`) — less every train standing or bound to stand there, and the trips
due to start there with a unit of their own (:meth:`TerminusRoom._departures_due_m`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from railsim.engine.events.tracks import SectionRequest
from railsim.engine.section_room import SectionRoom
from railsim.engine.single_track import RouteSection
from railsim.engine.stop_timing import separation_margin_m
from railsim.engine.train import TrainRuntime

TERMINUS_DEPARTURE_HORIZON_S = 300.0  # a departure from a terminus due this soon takes room there (_room_beyond)


class TerminusRoom(SectionRoom):
    """The room at a terminus beyond single track (module docstring): a base class of
    :class:`~railsim.engine.section_requests.SectionRequests`, which holds the fleet, the sections and requests,
    the settings and the rotations' successors."""

    sections: dict[str, list[RouteSection]]  # train id -> contested sections on its route
    section_requests: dict[str, dict[str, SectionRequest]]  # train id -> section id -> request
    clock: Any  # the event layer's time (now_s)
    successor: Callable[[str], str | None]  # the trip the unit of this trip runs next (rotations), or None

    def _room_beyond(self, req: SectionRequest) -> bool:
        """True if the terminus beyond ``req``'s section (its train's trip ends there: ``yields``) has room for it
        (module docstring): from ``clearance_m`` past the section's end to the end of its destination
        platform — or, where its unit turns beyond the platform (round a loop, or by a reversal on a track beyond),
        the whole track it has there up to where its next trip waits for the section (:meth:`_turning_track_m`,
        less the overlap) — less the length and separation margin of every other train standing or bound to stand
        there: the trains of its direction granted the section and not yet arrived, and the units on the line
        within that reach before the section on their way out, not yet granted it. With nobody there a train
        always fits. Counting the platform alone, one tram at a time turned at a loop that holds four (Jena,
        Zwätzen Schleife)."""
        tr = self.fleet.trains[req.holder_ids[0]]
        last = next((s for s in self.sections[tr.train_id] if s.section_id == req.section_id), None)
        if last is None or any(
            s.end_m > last.end_m and s.section_id.startswith("track:") for s in self.sections[tr.train_id]
        ):
            return True  # not the section the train turns beyond (a group's earlier member)
        room_m = tr.trip.stops[-1].served_end_m - (last.end_m + self.settings.clearance_m)
        reach_m = room_m
        loop_m = self._turning_track_m(tr, last)
        if loop_m is not None and loop_m - self.settings.protection_margin_m - self.settings.clearance_m > room_m:
            room_m = loop_m - self.settings.protection_margin_m - self.settings.clearance_m
            reach_m = loop_m
        used_m = 0.0
        for other in self.fleet.active():
            if other.train_id in req.holder_ids:
                continue
            theirs = next((s for s in self.sections.get(other.train_id, ()) if s.section_id == last.section_id), None)
            if theirs is None:
                continue
            mine = self.section_requests[other.train_id].get(last.section_id)
            if theirs.direction == last.direction:
                there = mine is not None and mine.granted
            else:
                there = (mine is None or not mine.granted) and theirs.guard_m - other.front_m <= reach_m
            if there:
                used_m += other.trip.vehicle.length_m + separation_margin_m(other)
        if loop_m is not None:
            used_m += self._departures_due_m(last, reach_m)
        return used_m == 0.0 or used_m + tr.trip.vehicle.length_m <= room_m

    def _departures_due_m(self, last: RouteSection, reach_m: float) -> float:
        """Room the trips starting at the terminus beyond ``last`` with a unit of their own (no unit turns into
        them) will take: each not on the line yet and due within :data:`TERMINUS_DEPARTURE_HORIZON_S`, starting
        within ``reach_m`` before the section the other way. Let in for the whole loop, turning trams found a
        fresh departure put on in it ahead of them (Jena, Zwätzen Schleife)."""
        now_s = self.clock.now_s
        chained = {self.successor(tid) for tid in self.fleet.trains}
        used_m = 0.0
        for tid, other in self.fleet.trains.items():
            if other.status != "scheduled" or tid in chained:
                continue
            if other.trip.depart_s + other.trip.departure_delay_s > now_s + TERMINUS_DEPARTURE_HORIZON_S:
                continue
            theirs = next((s for s in self.sections.get(tid, ()) if s.section_id == last.section_id), None)
            if theirs is not None and theirs.direction != last.direction and theirs.guard_m <= reach_m:
                used_m += other.trip.vehicle.length_m + separation_margin_m(other)
        return used_m

    def _turning_track_m(self, tr: TrainRuntime, last: RouteSection) -> float | None:
        """The track a unit turning beyond ``last`` has between leaving the section and coming back to it: from
        the section's end on ``tr``'s route, on to its arrival track and round its turning path (a loop, or a
        reversal beyond the platform) to the protection point where its next trip enters the section again. Its
        next trip's route starts at the start of ``tr``'s last edge (the turnback path first), which ties the two
        frames together. None without a next trip, or where it turns inside the section (a stub: no track
        beyond it)."""
        succ_id = self.successor(tr.train_id)
        if succ_id is None:
            return None
        back = next((s for s in self.sections.get(succ_id, ()) if s.section_id == last.section_id), None)
        if back is None or back.start_m <= 0.0:
            return None
        return float(tr.view.edge_start_m[-1]) + back.guard_m - last.end_m
