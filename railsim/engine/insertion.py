"""The dispatcher: trains enter the world (SUMO) when due, leave it when they arrive or leave the line.

* A departure is a simpy event at the trip's departure time (a follower that couples ``on_departure`` is
  instead inserted behind its leader by :class:`~railsim.engine.coupling.FormationBook`).
* **Holding a departure.** A train starting at a platform occupies ``[front − length, front]`` at once. If a
  train approaching on shared track could not stop short of that rear (service braking distance + one reaction
  time + ``insertion_margin_m``), the departure waits (``departure_held`` once, retried every
  ``departure_retry_s``): the dispatcher, not the follower, is responsible for a train appearing on the track.
* **Inserting** hands SUMO the route (trimmed to begin at the edge holding the start chainage), the stops with
  their dwells, and the start speed; extensions hook in (``on_inserted``: exact plants, …) and the formation
  partners register (:meth:`Knowledge.handshake`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from railsim.engine.coupling import FormationBook
from railsim.engine.events.clock import EventLayer
from railsim.engine.events.log import EventLog
from railsim.engine.fleet import Fleet
from railsim.engine.settings import DWELL_REGISTRATION_S, INSERTION_REACTION_S, EngineSettings
from railsim.engine.train import TrainRuntime
from railsim.errors import SimulationError
from railsim.physics import dynamics

InsertHook = Callable[[float, TrainRuntime, float], None]


class Dispatcher:
    """Departures, insertion into SUMO, and removal."""

    def __init__(
        self,
        fleet: Fleet,
        layer: EventLayer,
        events: EventLog,
        settings: EngineSettings,
        formations: FormationBook,
        handshake: Callable[[TrainRuntime], None],
        release_locks: Callable[[TrainRuntime], None],
    ) -> None:
        self.fleet = fleet
        self.layer = layer
        self.events = events
        self.settings = settings
        self.formations = formations
        self.handshake = handshake
        self.release_locks = release_locks
        self.on_inserted: list[InsertHook] = []  # extensions: (t, train, start chainage)
        # before inserting: (t, train, start chainage) -> a reason to hold the departure, or None
        self.admission: list[Callable[[float, TrainRuntime, float], str | None]] = []
        self.bridge: Any = None  # the SUMO bridge, wired when the run starts
        self._held: set[str] = set()  # trips whose departure was held (logged once each)

    def schedule_departures(self) -> None:
        for tr in self.fleet.trains.values():
            if self.formations.couples_on_departure(tr.train_id):
                continue  # inserted behind its leader when the leader stands at the follower's origin
            self.layer.at(tr.trip.depart_s, self._inserter(tr), "departure_due", tr.train_id)

    def _inserter(self, tr: TrainRuntime) -> Callable[[float], None]:
        """A clock callback that inserts ``tr`` (or holds it again)."""

        def call(_t: float) -> None:
            self.insert(tr)

        return call

    def insert_behind(self, tr: TrainRuntime, behind: TrainRuntime, gap_m: float) -> None:
        self.insert(tr, behind, gap_m)

    def insert(self, tr: TrainRuntime, behind: TrainRuntime | None = None, gap_m: float = 0.0) -> None:
        trip = tr.trip
        if tr.status != "scheduled":
            return
        depart_m = trip.depart_chainage_m
        if behind is not None:
            off = behind.view.offset_to(tr.view, behind.front_m - behind.trip.vehicle.length_m)
            if off is None:
                raise SimulationError(f"{tr.train_id} cannot start behind {behind.train_id}: routes share no track")
            depart_m = behind.front_m + off - behind.trip.vehicle.length_m - gap_m
            if depart_m < trip.origin.window_start_m:
                self.events.record(
                    self.layer.now_s,
                    "platform_too_short",
                    tr.train_id,
                    detail=f"front {depart_m:.1f} m < window {trip.origin.window_start_m:.1f} m",
                )
        elif trip.start_speed_mps == 0.0 and trip.start_offset_m == 0.0:
            blocker = self.blocker(tr, depart_m)
            if blocker is not None:  # the dispatcher holds the departure: a train approaching could not stop
                if tr.train_id not in self._held:
                    self._held.add(tr.train_id)
                    self.events.record(self.layer.now_s, "departure_held", tr.train_id, approaching=blocker)
                self.layer.at(
                    self.layer.now_s + self.settings.departure_retry_s,
                    self._inserter(tr),
                    "departure_retry",
                    tr.train_id,
                )
                return
        for admit in self.admission:  # the interlocking reserves what the train starts in (single track)
            reason = admit(self.layer.now_s, tr, depart_m)
            if reason is not None:
                if tr.train_id not in self._held:
                    self._held.add(tr.train_id)
                    self.events.record(self.layer.now_s, "departure_held", tr.train_id, reason=reason)
                self.layer.at(
                    self.layer.now_s + self.settings.departure_retry_s,
                    self._inserter(tr),
                    "departure_retry",
                    tr.train_id,
                )
                return
        from railsim.engine.sumo import StopSpec

        stops = [
            StopSpec(s.stop_id, duration_s=DWELL_REGISTRATION_S if s.is_destination else s.dwell_s)
            for s in trip.stops[1:]
        ]
        # SUMO inserts a vehicle on its route's first edge: a train starting further along (a start offset in
        # motion) gets the route trimmed to begin at the edge that holds its start chainage
        k = tr.view.edge_at(depart_m)
        route_id = trip.route.id if k == 0 else f"{trip.route.id}@{k}"
        self.bridge.add_route(route_id, trip.route.edges[k:])
        self.bridge.add_train(
            tr.train_id,
            route_id,
            trip.vehicle_name,
            depart_m - tr.view.edge_start_m[k],
            stops,
            controlled=True,
            depart_speed_mps=trip.start_speed_mps,
        )
        tr.status = "inserting"
        tr.front_m = depart_m
        tr.plant = dynamics.PlantState(speed_mps=trip.start_speed_mps)
        for hook in self.on_inserted:
            hook(self.layer.now_s, tr, depart_m)
        self.handshake(tr)
        tr.depart_chainage_m = depart_m
        tr.inserted_s = self.layer.now_s
        self.events.record(
            self.layer.now_s, "train_inserted", tr.train_id, service=trip.service_id, chainage_m=round(depart_m, 3)
        )

    def blocker(self, tr: TrainRuntime, depart_m: float) -> str | None:
        """A train on the line that a departure at ``depart_m`` would put in danger, or None (module docstring)."""
        length = tr.trip.vehicle.length_m
        for other in self.fleet.active():
            if other is tr:
                continue
            mapped = other.view.map_body(tr.view, depart_m, length)
            if mapped is None:
                continue
            front_o, rear_o = mapped
            if front_o <= other.front_m - other.trip.vehicle.length_m:
                continue  # it lies behind the other train's rear: the other one is ahead
            v = other.plant.speed_mps
            needed = (
                v * v / (2.0 * other.trip.vehicle.service_decel_mps2)
                + v * INSERTION_REACTION_S
                + self.settings.insertion_margin_m
            )
            if rear_o - other.front_m < needed:
                return other.train_id
        return None

    def leave(self, tr: TrainRuntime) -> None:
        """A train leaves the line (to another track, the depot): removed from the world now, logged."""
        if tr.status not in ("inserting", "running"):
            return
        self.release_locks(tr)
        self.bridge.remove(tr.train_id)
        tr.status = "removed"
        self.events.record(self.layer.now_s, "train_left", tr.train_id, chainage_m=round(tr.front_m, 3))
