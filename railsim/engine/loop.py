"""One simulation: the step loop that joins SUMO, the simpy event layer, the plant and the controllers.

Per step ``k`` at time ``t_k`` (DESIGN.md §3)::

    layer.advance_to(t_k)      departures due, message deliveries, switch throws, formation commands
    truth = sumo.read()        odometer → route chainage of every train (ground truth)
    bookkeeping                stop registration / dwell end / arrival, switch lock requests and releases,
                               true gaps → formations and the recorder, collision detection on truth
    comms                      every train reports to the ground (t2g); formation leaders to followers (t2t)
    for each train:            obs = what the train KNOWS (own odometry + delivered messages + authority)
                               u   = min over active roles (ato, separation | coupled controller)
                               v'  = dynamics.step(...)   (envelopes, jerk, lag, resistance, gradient)
    sumo.set_speeds(v'); sumo.step()

Truth vs knowledge: controllers see predecessor states only as delivered messages (stale when late, missing
when lost); the recorder and the formation state machine see ground truth. SUMO's own collision check runs too
and is recorded separately.

Interlocking: every switch on a train's route is requested ``lock_request_distance_m`` before its point; until
granted, the train's movement authority ends ``protection_margin_m`` before the switch point; the lock is
released when the train's rear is ``clearance_m`` past the point. A coupled pair on the same leg holds one lock.

Virtual coupling on a line: a follower in a formation is inserted behind its leader when the formation couples
on departure; while coupling/coupled it stops at stations ``leader length + target gap`` behind the leader's mark
(both units stand on one long platform), and it follows with the ``coupled`` controller on t2t messages. If the
leader's messages are older than ``max_message_age_s`` the follower degrades to ``separation`` on ground data
(logged). Decoupling ``before_switch`` happens when the leader departs the last stop before that switch (or
``decouple_distance_m`` before it), after which the units separate with absolute braking distance and each takes
its own switch lock.

Junctions (scenario ``junction:``, Paper E): :class:`railsim.engine.extensions.junction.JunctionCoordinator` runs on the
ground side each step before the controllers — it plans and re-plans the approach of the named trains to point F,
requests their switch locks in passing order (the distance rule above is off for those), forms the formations in
that order and hands each train over at F. Until then a planned train's roles are ``junction`` (its plan) plus the
ATO and a relative-braking-distance guard against the train ahead.
"""

from __future__ import annotations

import logging
import math
import sys
import time as _time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

import controllers as ctl
from controllers.base import Command, Observation, OwnState, PredecessorState, SpeedLimit, StopTarget, arbitrate
from railsim.physics import dynamics
from railsim.errors import ConfigError, SimulationError
from railsim.engine.occupancy import Ahead, Body, Occupancy
from railsim.engine.routeview import RouteView, route_view
from railsim.engine.trips import Trip, TripStop, make_stops, plan_free_run

log = logging.getLogger(__name__)

INF = float("inf")
APART_GAP_M = 1.0e9  # "gap" reported to a formation whose units are on different tracks


@dataclass(frozen=True)
class EngineSettings:
    """Operating rules of the engine (not of any one controller); scenario ``engine:`` may override."""

    lock_request_distance_m: float = 1500.0
    protection_margin_m: float = 20.0
    clearance_m: float = 10.0
    max_message_age_s: float = 2.0
    decouple_distance_m: float = 2000.0
    lookahead_m: float = 5000.0
    separation_gap_m: float = 300.0  # formation decoupling completes at this true gap (front-to-rear)
    missed_stop_tolerance_m: float = 0.5
    final_approach_margin_m: float = 50.0  # coupled follower: hand the stop to the ATO this far before braking
    sensor_range_m: float = 400.0  # a train's own ranging sensor (collision avoidance) sees this far ahead
    insertion_margin_m: float = 50.0  # a departure waits unless trains approaching behind can stop this far back
    departure_retry_s: float = 1.0  # ... and is tried again after this long


@dataclass
class TrainRuntime:
    """Everything that changes about one trip during the run."""

    trip: Trip
    view: RouteView
    controllers: dict[str, Any]
    plant: dynamics.PlantState = field(default_factory=lambda: dynamics.PlantState(speed_mps=0.0))
    status: str = "scheduled"  # scheduled | inserting | running | arrived | removed
    inserted_s: float | None = None
    departed_s: float | None = None
    arrived_s: float | None = None
    next_stop: int = 1
    front_m: float = 0.0
    halted_s: float | None = None
    halt_error_m: float | None = None
    sumo_stopped: bool = False
    dwell_started_s: float | None = None
    energy_j: float = 0.0
    min_gap_m: float = INF
    coupled_s: float = 0.0
    max_jerk_mps3: float = 0.0
    last_applied_mps2: float = 0.0
    fallbacks: int = 0
    saturations: dict[str, int] = field(default_factory=dict)
    locks: dict[str, Any] = field(default_factory=dict)  # switch id -> LockRequest (own or group)
    released: set[str] = field(default_factory=set)
    violations: set[str] = field(default_factory=set)
    last_role: str = "ato"
    last_cmd_mps2: float = 0.0
    last_gap_m: float = INF
    stale_max_s: float = 0.0
    degraded: bool = False
    stops_served: int = 0
    depart_chainage_m: float = 0.0
    sumo_stopped_now: bool = False
    vc_target_gap_m: float | None = None  # the coupled controller's effective target (gap policy), last step
    last_plan: Any = None  # the winning controller's broadcast plan (Command.info["plan"]) of the last step
    sent_speed_mps: float | None = None  # the speed handed to SUMO last step
    emergency_since_s: float | None = None  # start of the current emergency-braking interval
    vc_solve_s: float | None = None  # the coupled controller's solve time this step (Command.info["solve_time_s"])
    vc_fsm: Any = None  # Paper D follower state machine memory (formations with monorail controllers)
    vc_objective: float | None = None  # and its objective value (Command.info["J"])
    mp_params: Any = None  # railsim.physics.multipoint.MultipointParams when the vehicle uses the carriage model
    mp_state: Any = None  # its MultipointState (carriage 1 = the front SUMO sees)
    mono_params: Any = None  # railsim.physics.monorail.MonorailParams for a monorail-drive vehicle
    mono_state: Any = None  # its PlantState

    train_id: str = ""  # = trip.trip_id (a plain field: it is read millions of times per run)

    def __post_init__(self) -> None:
        self.train_id = self.trip.trip_id


class Simulation:
    """Builds the world and the trains for a scenario and runs the step loop. Use :func:`run`."""

    def __init__(self, scenario: Any, out_dir: Path | None, seed: int | None = None,
                 progress: bool | None = None, settings: EngineSettings | None = None) -> None:
        from railsim import scenario as scn_mod
        from railsim.engine.events import (Channel, DelaySpec, EventLayer, FormationManager, Interlocking,
                                    Outage, Switch)

        self.scenario = scenario
        self.out_dir = Path(out_dir) if out_dir is not None else None
        sim = scenario.simulation
        self.seed = int(sim.seed if seed is None else seed)
        self.dt = float(sim.step_s)
        self.duration_s = float(sim.duration_s)
        self.step_method = sim.step_method
        self.settings = settings or EngineSettings()
        self.progress = sys.stderr.isatty() if progress is None else progress
        self.rng = np.random.default_rng(self.seed)

        from network.external import load_world, sumo_args

        self.bundle = load_world(scenario.world, scenario.source)  # a shipped/line world is built, a net is read
        self.sumo_extra_args = sumo_args(self.bundle)  # () for generated worlds
        scn_mod.check_against_world(scenario, self.bundle.stations.keys(), self.bundle.switches.keys(),
                                    self.bundle.station_aliases)
        if self.bundle.station_aliases:  # an external net: stations named by name or stop id -> station ids
            scenario = self.scenario = scn_mod.with_station_ids(scenario, self.bundle.station_aliases)

        # ---- event layer
        self.layer = EventLayer(t0_s=0.0, rng=np.random.default_rng(self.rng.integers(2**63)))
        self.events = self.layer.log
        self.formations = FormationManager(self.layer)
        self.interlocking = Interlocking(self.layer)
        for sw in self.bundle.switches.values():
            self.interlocking.add_switch(Switch(sw.id, throw_time_s=float(sw.throw_time_s)))
        self.channels: dict[str, Any] = {}
        for name, spec in scenario.faults.comm.items():
            delay = DelaySpec.from_mapping(_delay_mapping(spec.delay), str(scenario.source),
                                           f"faults.comm.{name}.delay_s")
            outages = tuple(Outage(o.start_s, o.end_s, frozenset(o.trains) if o.trains else None)
                            for o in spec.outages)
            self.channels[name] = Channel(self.layer, name, delay, float(spec.loss_prob), outages)
        self.noise_pos_sd = float(scenario.faults.sensor_noise.position_sd_m)
        self.noise_speed_sd = float(scenario.faults.sensor_noise.speed_sd_mps)
        self.noise_rng = np.random.default_rng(self.rng.integers(2**63))
        self.actuator_sd = float(scenario.faults.actuator_noise.accel_sd_mps2)
        self.actuator_rng = np.random.default_rng(self.rng.integers(2**63))

        # ---- trips
        self.trains: dict[str, TrainRuntime] = {}
        self.trips_by_service: dict[str, list[Trip]] = {}
        self._build_trips()
        self.formation_of_follower: dict[str, Any] = {}
        self.formation_of_leader: dict[str, list[Any]] = {}
        self._build_formations()
        for vname, plant in scenario.plants.items():
            if plant.kind in ("multipoint", "monorail") and self.step_method != "euler":
                raise ConfigError(scenario.source, "simulation.step_method",
                                  f"vehicle {vname!r} uses the {plant.kind} plant, which needs step_method euler "
                                  f"(SUMO is handed the step's mean speed), got {self.step_method!r}")
        self.coop_edges = tuple(scenario.cooperative.edges)
        self.coop_members = {e.a for e in self.coop_edges} | {e.b for e in self.coop_edges}
        for tid in self.coop_members:
            if tid not in self.trains:
                raise ConfigError(scenario.source, "cooperative.edges", f"no trip {tid!r}")
        self._coop_graph: Any = None  # the neighbour graph in force (Paper C validator's CommGraph)
        self._held: set[str] = set()  # trips whose departure the dispatcher held (logged once each)
        self.obstacles: dict[str, tuple[str, float]] = {}  # obstacle id -> (SUMO edge, position on it [m])
        self._schedule_departures()
        self._schedule_timed_events()

        # what a train knows of another before any message arrived: (receiver, sender) -> report
        self._registration: dict[tuple[str, str], tuple[str, float, float, float, float]] = {}
        self._coop_neighbours: dict[str, dict[str, tuple[float, ...]]] = {}
        self.occupancy = Occupancy()
        self.collisions: list[dict[str, Any]] = []
        self._colliding_pairs: set[tuple[str, str]] = set()
        self.sumo_collisions: list[dict[str, Any]] = []
        from railsim.record.recorder import Recorder

        self.recorder = Recorder(self, stride_s=float(scenario.outputs.trace_stride_s))
        self.junction: Any = None  # the online junction planner (scenario ``junction:``), last: it draws a seed
        if scenario.junction is not None:
            from railsim.engine.extensions.junction import JunctionCoordinator

            self.junction = JunctionCoordinator(self, scenario.junction)
        self.steps = 0
        self.wall_s = 0.0

    # ------------------------------------------------------------------ set-up
    def _controller(self, role: str, trip_roles: dict[str, str], vehicle: Any) -> Any:
        name = trip_roles.get(role)
        if name is None:
            return None
        spec = self.scenario.controllers[name]
        return ctl.create(spec.type, dict(spec.params or {}), vehicle)

    def _closing_ato(self, trip_roles: dict[str, str], vehicle: Any) -> Any:
        """The follower's ATO while coupled: the same ATO without its cruise margin below the line speed.

        Both units of a formation otherwise cruise at the same speed (line speed − margin) and a follower that
        fell back while accelerating could never close up; without the margin it closes at up to that margin
        and still never exceeds the line speed or a restriction. ATOs without a ``speed_margin_mps`` parameter
        are used as they are.
        """
        spec = self.scenario.controllers[trip_roles["ato"]]
        try:
            return ctl.create(spec.type, {**dict(spec.params or {}), "speed_margin_mps": 0.0}, vehicle)
        except (ValueError, TypeError):
            return None

    def _build_trips(self) -> None:
        scn = self.scenario
        for svc in scn.services:
            try:
                route = self.bundle.route_between(svc.from_station, svc.to_station, tuple(svc.via))
            except (KeyError, ValueError) as exc:
                raise ConfigError(scn.source, f"services[{svc.id}]", f"no route: {exc}") from None
            vehicle = scn.vehicles[svc.vehicle]
            stops = make_stops(route, vehicle.length_m, tuple(svc.skip), svc.dwell_default_s,
                               dict(svc.dwell_by_station), svc.from_station, svc.to_station)
            if len(stops) < 2 or stops[0].station_id != svc.from_station or stops[-1].station_id != svc.to_station:
                raise ConfigError(scn.source, f"services[{svc.id}]",
                                  f"route from {svc.from_station} to {svc.to_station} does not serve both stations")
            start_offset = float(svc.start_offset_m)
            if svc.start_before_switch is not None:  # "the front starts distance_m before switch X"
                where = f"services[{svc.id}].start.before_switch"
                points = [rs.point_m for rs in route.switches if rs.switch_id == svc.start_before_switch]
                if not points:
                    raise ConfigError(scn.source, where, f"switch {svc.start_before_switch!r} is not on the route "
                                      f"{route.id} (its switches: {', '.join(rs.switch_id for rs in route.switches)})")
                start_offset = points[0] - float(svc.start_distance_m) - stops[0].mark_m
                if start_offset < 0.0:
                    raise ConfigError(scn.source, f"services[{svc.id}].start.distance_m",
                                      f"{svc.start_distance_m:g} m before {svc.start_before_switch} lies behind the "
                                      f"origin's stopping mark (at most {points[0] - stops[0].mark_m:.1f} m)")
            if start_offset > 0.0:  # a trip that starts in motion skips the stops already behind it
                start_m = stops[0].mark_m + start_offset
                stops = (stops[0],) + tuple(st for st in stops[1:] if st.window_end_m > start_m)
                if len(stops) < 2:
                    raise ConfigError(scn.source, f"services[{svc.id}].start.offset_m",
                                      f"starts beyond its destination {svc.to_station!r}")
            trips = []
            for k, (trip_id, dep) in enumerate(zip(svc.trip_ids, svc.departures_s)):
                trip = Trip(trip_id=trip_id, service_id=svc.id, index=k, vehicle_name=svc.vehicle, vehicle=vehicle,
                            route=route, depart_s=float(dep), stops=stops, roles=dict(svc.roles),
                            start_offset_m=start_offset, start_speed_mps=float(svc.start_speed_mps))
                ato_factory = lambda r=dict(svc.roles), v=vehicle: self._controller("ato", r, v)  # noqa: E731
                arr, depm = plan_free_run(trip, ato_factory, self.dt, self.step_method)
                trip.planned_arrival_s.update(arr)
                trip.planned_departure_s.update(depm)
                ctrls = {role: self._controller(role, trip.roles, vehicle)
                         for role in ("ato", "separation", "coupled", "ca")}
                ctrls["ato_closing"] = self._closing_ato(trip.roles, vehicle)
                self.trains[trip_id] = TrainRuntime(trip=trip, view=route_view(route), controllers=ctrls)
                trips.append(trip)
            self.trips_by_service[svc.id] = trips

    def _trip_ref(self, ref: Any, where: str) -> TrainRuntime:
        trips = self.trips_by_service.get(ref.service)
        if not trips or not (0 <= ref.trip < len(trips)):
            raise ConfigError(self.scenario.source, where, f"no trip {ref.trip} in service {ref.service!r}")
        return self.trains[trips[ref.trip].trip_id]

    def _build_formations(self) -> None:
        for k, f in enumerate(self.scenario.formations):
            self.add_formation(f, f"formations[{k}]")

    def add_formation(self, f: Any, where: str = "formations") -> None:
        """Register formation ``f`` (a :class:`railsim.scenario.FormationSpec`) with the state machine and the
        engine's leader/follower maps: the scenario's at set-up, the junction planner's at run time."""
        from railsim.engine.events.formations import Formation

        leader = self._trip_ref(f.leader, f"{where}.leader")
        follower = self._trip_ref(f.follower, f"{where}.follower")
        # decoupling completes at this true gap: the engine default, or beyond a large target gap
        separation = max(self.settings.separation_gap_m, float(f.target_gap_m) + 100.0)
        form = Formation(id=f.id, leader_id=leader.train_id, follower_id=follower.train_id,
                         target_gap_m=float(f.target_gap_m), separation_gap_m=separation,
                         coupling_timeout_s=float(f.coupling_timeout_s))
        self.formations.add(form)
        if _trig(f.couple, "on_departure"):
            origin = follower.trip.origin.station_id
            planned = leader.trip.planned_departure_s.get(origin)
            if planned is None:
                raise ConfigError(self.scenario.source, f"{where}.couple",
                                  f"the leader's trip does not stop at the follower's origin {origin!r}")
            shift = planned - follower.trip.depart_s
            follower.trip.depart_s = planned
            for d in (follower.trip.planned_arrival_s, follower.trip.planned_departure_s):
                for key in d:
                    d[key] += shift
        self.formation_of_follower[follower.train_id] = f
        self.formation_of_leader.setdefault(leader.train_id, []).append(f)

    def _schedule_departures(self) -> None:
        for tr in self.trains.values():
            f = self.formation_of_follower.get(tr.train_id)
            if f is not None and _trig(f.couple, "on_departure"):
                continue  # inserted behind its leader when the leader stands at the follower's origin
            self.layer.at(tr.trip.depart_s, lambda _t, tr=tr: self._insert(tr), "departure_due", tr.train_id)

    def _schedule_timed_events(self) -> None:
        for f in self.scenario.formations:
            if _trig(f.couple, "at_s"):
                self.formations.request_couple(f.id, at_s=float(f.couple.at_s))
            if _trig(f.decouple, "at_s"):
                self.formations.request_decouple(f.id, at_s=float(f.decouple.at_s))
        for bias in self.scenario.faults.actuator_bias:  # make injected actuator faults visible in events.csv
            self.layer.at(bias.from_s, lambda _t, b=bias: self.events.record(
                self.layer.now_s, "actuator_fault", b.train, accel_mps2=b.accel_mps2,
                until_s=b.until_s if math.isfinite(b.until_s) else None), "actuator_fault_due", bias.train)
        for n, ev in enumerate(self.scenario.events):
            if ev.type == "obstacle":
                self.layer.at(float(ev.at_s), lambda _t, e=ev, k=n: self._place_obstacle(f"obstacle{k}", e),
                              "obstacle_due", ev.train)
            elif ev.type == "leave":
                self.layer.at(float(ev.at_s), lambda _t, tid=ev.train: self._leave(self.trains[tid]), "leave_due",
                              ev.train)
            elif ev.type == "couple":
                self.formations.request_couple(ev.formation, at_s=float(ev.at_s))
            elif ev.type == "decouple":
                self.formations.request_decouple(ev.formation, at_s=float(ev.at_s))

    # ------------------------------------------------------------------ insertion
    def _insert(self, tr: TrainRuntime, behind: TrainRuntime | None = None, gap_m: float = 0.0) -> None:
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
                self.events.record(self.layer.now_s, "platform_too_short", tr.train_id,
                                   detail=f"front {depart_m:.1f} m < window {trip.origin.window_start_m:.1f} m")
        elif trip.start_speed_mps == 0.0 and trip.start_offset_m == 0.0:
            blocker = self._insertion_blocker(tr, depart_m)
            if blocker is not None:  # the dispatcher holds the departure: a train approaching could not stop
                if tr.train_id not in self._held:
                    self._held.add(tr.train_id)
                    self.events.record(self.layer.now_s, "departure_held", tr.train_id, approaching=blocker)
                self.layer.at(self.layer.now_s + self.settings.departure_retry_s, lambda _t, tr=tr: self._insert(tr),
                              "departure_retry", tr.train_id)
                return
        from railsim.engine.sumo import StopSpec

        stops = []
        for s in trip.stops[1:]:
            stops.append(StopSpec(s.stop_id, duration_s=1.0 if s.is_destination else s.dwell_s))
        # SUMO inserts a vehicle on its route's first edge: a train starting further along (a start offset in
        # motion) gets the route trimmed to begin at the edge that holds its start chainage
        k = tr.view.edge_at(depart_m)
        route_id = trip.route.id if k == 0 else f"{trip.route.id}@{k}"
        self.bridge.add_route(route_id, trip.route.edges[k:])
        self.bridge.add_train(tr.train_id, route_id, trip.vehicle_name, depart_m - tr.view.edge_start_m[k], stops,
                              controlled=True, depart_speed_mps=trip.start_speed_mps)
        tr.status = "inserting"
        tr.front_m = depart_m
        tr.plant = dynamics.PlantState(speed_mps=trip.start_speed_mps)
        plant = self.scenario.plants.get(trip.vehicle_name)
        if plant is not None and plant.kind == "multipoint":
            from railsim.physics import multipoint

            tr.mp_params = multipoint.MultipointParams(**dict(plant.params))
            tr.mp_state = multipoint.initial_state(tr.mp_params, depart_m, trip.start_speed_mps)
        elif plant is not None and plant.kind == "monorail":
            from railsim.physics import monorail as vehicle_model

            tr.mono_params = vehicle_model.MonorailParams(**dict(plant.params))
            tr.mono_state = vehicle_model.PlantState(t_s=self.layer.now_s, x_m=depart_m, v_mps=trip.start_speed_mps)
        self._handshake(tr)
        tr.depart_chainage_m = depart_m
        tr.inserted_s = self.layer.now_s
        self.events.record(self.layer.now_s, "train_inserted", tr.train_id, service=trip.service_id,
                           chainage_m=round(depart_m, 3))

    def _insertion_blocker(self, tr: TrainRuntime, depart_m: float) -> str | None:
        """A train on the line that a departure at ``depart_m`` would put in danger, or None.

        A train starting at a platform occupies ``[front - length, front]`` at once. If another train's front is
        behind that rear (on shared track) by less than its service braking distance plus the separation margin
        and one second of running, or already overlaps it, it could not stop: the departure waits (DESIGN §3: the
        dispatcher, not the follower, is responsible for a train appearing on the track).
        """
        length = tr.trip.vehicle.length_m
        for other in self._active():
            if other is tr:
                continue
            mapped = other.view.map_body(tr.view, depart_m, length)
            if mapped is None:
                continue
            front_o, rear_o = mapped
            if front_o <= other.front_m - other.trip.vehicle.length_m:
                continue  # it lies behind the other train's rear: the other one is ahead
            v = other.plant.speed_mps
            needed = v * v / (2.0 * other.trip.vehicle.service_decel_mps2) + v * 1.0 + \
                self.settings.insertion_margin_m
            if rear_o - other.front_m < needed:
                return other.train_id
        return None

    def _place_obstacle(self, oid: str, ev: Any) -> None:
        """A static obstacle appears ``ahead_m`` ahead of a train's front (on that train's route, fixed to the track)."""
        tr = self.trains[ev.train]
        ch = tr.front_m + float(ev.ahead_m)
        i = tr.view.edge_at(ch)
        self.obstacles[oid] = (tr.view.edges[i], ch - tr.view.edge_start_m[i])
        self.events.record(self.layer.now_s, "obstacle_appeared", oid, ahead_of=tr.train_id,
                           chainage_m=round(ch, 3))
        if ev.duration_s is not None:
            def clear(_t: float, oid: str = oid) -> None:
                self.obstacles.pop(oid, None)
                self.events.record(self.layer.now_s, "obstacle_cleared", oid)

            self.layer.at(self.layer.now_s + float(ev.duration_s), clear, "obstacle_clear_due", oid)

    def _obstacle_ahead(self, tr: TrainRuntime) -> tuple[str, float] | None:
        """Nearest obstacle on this train's route ahead of its front: ``(id, gap_m)`` (ground truth)."""
        best = None
        for oid, (edge, pos) in self.obstacles.items():
            j = tr.view.edge_index.get(edge)
            if j is None:
                continue
            gap = tr.view.edge_start_m[j] + pos - tr.front_m
            if gap > -tr.trip.vehicle.length_m and (best is None or gap < best[1]):
                best = (oid, gap)
        return best

    def _sensor(self, tr: TrainRuntime, a: Ahead | None) -> dict[str, Any]:
        """What the train's own ranging sensor reads: nearest train or obstacle ahead within range (truth-based)."""
        reading: dict[str, Any] = {"distance_m": INF, "closing_speed_mps": 0.0, "object": "vehicle"}
        if a is not None and a.gap_m <= self.settings.sensor_range_m:
            other = self.trains[a.train_id]
            reading = {"distance_m": a.gap_m, "closing_speed_mps": tr.plant.speed_mps - other.plant.speed_mps,
                       "object": "vehicle"}
        obs = self._obstacle_ahead(tr)
        if obs is not None and obs[1] <= self.settings.sensor_range_m and obs[1] < reading["distance_m"]:
            reading = {"distance_m": obs[1], "closing_speed_mps": tr.plant.speed_mps, "object": "obstacle"}
        return reading

    def _leave(self, tr: TrainRuntime) -> None:
        """A train leaves the line (to another track, the depot): removed from the world now, logged."""
        if tr.status not in ("inserting", "running"):
            return
        self._release_all_locks(self.layer.now_s, tr)
        self.bridge.remove(tr.train_id)
        tr.status = "removed"
        self.events.record(self.layer.now_s, "train_left", tr.train_id, chainage_m=round(tr.front_m, 3))

    def _handshake(self, tr: TrainRuntime) -> None:
        """Formation partners exchange a registration snapshot when both are on the line.

        Before the first radio message arrives, a follower knows where its leader was at this moment (it was
        placed behind it, or the pair registered together); without it a follower starting in motion would fall
        back to separation on ground data and brake for no reason.
        """
        now = self.layer.now_s
        pairs = []
        f = self.formation_of_follower.get(tr.train_id)
        if f is not None:
            pairs.append((tr, self.trains[self.formations_leader_id(f)]))
        for f2 in self.formation_of_leader.get(tr.train_id, ()):
            pairs.append((self._trip_ref(f2.follower, "formations"), tr))
        for follower, leader in pairs:
            if follower.status in ("inserting", "running") and leader.status in ("inserting", "running"):
                self._registration[(follower.train_id, leader.train_id)] = (
                    leader.trip.route.id, leader.front_m, leader.plant.speed_mps, leader.plant.applied_accel_mps2,
                    now)

    def _cooperative_graph(self, t: float, active: list[TrainRuntime]) -> dict[str, dict[str, tuple[float, ...]]]:
        """Active neighbour edges at ``t`` (both ends on the line), oriented per train; validated when they change.

        The first graph is checked against Paper C's Assumptions 2.1–2.4 and condition (13); every change
        (a join, a leave, an edge added or dropped) re-checks the assumptions and (13) for the new edges
        (:func:`controllers.distributed.validate.check_event_preconditions`). A violation stops the run with
        the validator's message (exit code 2): an unsafe topology change is never silently accepted.
        """
        from controllers.distributed.graph import CommGraph, Edge, EdgeData
        from controllers.distributed.validate import PreconditionError, check_event_preconditions, validate

        on_line = {tr.train_id for tr in active}
        live = [e for e in self.coop_edges if e.from_s <= t < e.until_s and e.a in on_line and e.b in on_line]
        out: dict[str, dict[str, tuple[float, ...]]] = {}
        for e in live:
            out.setdefault(e.a, {})[e.b] = (e.d_m, e.lower_m, e.upper_m)
            out.setdefault(e.b, {})[e.a] = (-e.d_m, -e.upper_m, -e.lower_m)
        nodes = sorted(out)
        graph = CommGraph.build(nodes, [Edge(e.a, e.b, EdgeData(e.d_m, e.lower_m, e.upper_m)) for e in live])
        if self._coop_graph is not None and graph.edges == self._coop_graph.edges and \
                graph.nodes == self._coop_graph.nodes:
            return out
        params = {}
        v_ref = None
        for tid in nodes:
            ctl_ = self.trains[tid].controllers["ato"]
            if not hasattr(ctl_, "train_params"):
                raise ConfigError(self.scenario.source, "cooperative.edges",
                                  f"trip {tid} is in the cooperative graph but its ato controller is not a graph law")
            params[tid] = ctl_.train_params
            v_ref = ctl_.params.v_ref_mps
        x = {tid: self.trains[tid].front_m for tid in nodes}
        v = {tid: self.trains[tid].plant.speed_mps for tid in nodes}
        k = int(round(t / self.dt))
        if nodes:
            if self._coop_graph is None:
                validate(graph, params, self.dt, float(v_ref), x, v, k=k, source=self.scenario.source)
            else:
                problems = check_event_preconditions(self._coop_graph, graph, params, self.dt, float(v_ref), x, v)
                if problems:
                    raise PreconditionError(self.scenario.source, problems, k=k)
        self.events.record(t, "graph_changed", "cooperative", nodes=nodes,
                           edges=sorted(f"{e.a}-{e.b}" for e in live))
        self._coop_graph = graph
        return out

    def _monorail_step(self, t: float, tr: TrainRuntime, role: str, cmd: Command, grad: float) -> float:
        """Advance a monorail-drive train (Paper D §3.4: dead time, lag, efficiency, load-dependent envelope)."""
        from railsim.physics import monorail as vehicle_model

        u = cmd.accel_mps2
        for bias in self.scenario.faults.actuator_bias:
            if bias.train == tr.train_id and bias.from_s <= t < bias.until_s:
                u += bias.accel_mps2
        state = tr.mono_state
        if abs(state.t_s - t) > 1e-6:  # keep the drive's clock on the engine's (e.g. after a hold by SUMO)
            state = vehicle_model.PlantState(t_s=t, x_m=state.x_m, v_mps=state.v_mps, a_mps2=state.a_mps2,
                                             active_command_mps2=state.active_command_mps2,
                                             active_issue_s=state.active_issue_s, pending=state.pending)
        new = vehicle_model.plant_step(state, u, self.dt, tr.mono_params, tr.trip.vehicle.mass_kg, grad)
        mean_v = 0.5 * (state.v_mps + new.v_mps)
        tr.energy_j += max(new.a_mps2, 0.0) * tr.trip.vehicle.mass_kg * mean_v * self.dt
        tr.mono_state = new
        return self._exact_plant_finish(tr, role, cmd, new.x_m - state.x_m, new.v_mps, new.a_mps2)

    def _exact_plant_finish(self, tr: TrainRuntime, role: str, cmd: Command, advance_m: float, v_new: float,
                            applied_mps2: float) -> float:
        """Common end of a step of an exactly integrated plant: SUMO gets the step's mean speed (``Δx/dt``).

        SUMO's Euler update moves a train by the speed it is given times dt; a plant that integrates within the
        step moves by ``Δx`` that is not ``v_new·dt``, so handing SUMO ``Δx/dt`` keeps its front on the plant's.
        """
        jerk = abs(applied_mps2 - tr.plant.applied_accel_mps2) / self.dt
        tr.max_jerk_mps3 = max(tr.max_jerk_mps3, jerk)
        tr.plant = dynamics.PlantState(speed_mps=float(v_new), applied_accel_mps2=float(applied_mps2),
                                       target_accel_mps2=float(applied_mps2))
        tr.last_role = role
        tr.last_cmd_mps2 = cmd.accel_mps2
        tr.last_plan = None
        tr.sent_speed_mps = max(advance_m / self.dt, 0.0)
        return tr.sent_speed_mps

    def _multipoint_step(self, t: float, tr: TrainRuntime, role: str, cmd: Command) -> float:
        """Advance a carriage-model train one step; return the speed that makes SUMO's position exact.

        The carriage model integrates continuously (RK4 sub-steps), so carriage 1 moves by ``Δx`` that is not
        ``v_new·dt``. SUMO's Euler update moves a train by the speed it is given times dt, so we hand it
        ``Δx/dt`` — the step's mean speed — and SUMO's front stays exactly on carriage 1.
        """
        from railsim.physics import multipoint

        p, state = tr.mp_params, tr.mp_state
        forces = _carriage_forces(cmd, p)
        view = tr.view
        new = multipoint.step(p, state, forces, self.dt,
                              lambda xs: np.array([view.gradient_at(float(x)) for x in np.atleast_1d(xs)]), t)
        advance = float(new.lead_position_m - state.lead_position_m)
        mass = p.n_cars * p.car_mass_kg
        applied = float(np.clip(forces, p.force_min_n, p.force_max_n).sum()) / mass
        mean_v = 0.5 * (np.asarray(state.speeds_mps) + np.asarray(new.speeds_mps))
        tr.energy_j += float(np.sum(np.maximum(np.clip(forces, p.force_min_n, p.force_max_n), 0.0) * mean_v)) * self.dt
        tr.mp_state = new
        return self._exact_plant_finish(tr, role, cmd, advance, float(new.lead_speed_mps), applied)

    # ------------------------------------------------------------------ main loop
    def run(self) -> dict[str, Any]:
        from railsim.engine.sumo import SumoBridge, SumoConfig, VTypeSpec

        # SUMO never drives our trains (speedMode 32), but it still checks insertion with the vType's Krauss model:
        # its safe insertion speed is about gap/tau when decel·tau is large, so a tiny tau and a huge decel let a
        # train be inserted exactly where and when the scenario says, at speed, close behind another (our
        # occupancy check, not SUMO, judges safety). Without this SUMO silently delays the insertion.
        vtypes = [VTypeSpec(name, v.length_m, max(v.max_speed_mps * 1.5, 1.0), accel_mps2=1.0,
                            decel_mps2=1000.0, emergency_decel_mps2=1000.0, tau_s=0.001, vclass=self.bundle.vclass)
                  for name, v in self.scenario.vehicles.items()]
        outs = tuple(self.scenario.outputs.sumo)
        additional = list(self.bundle.additional_files) or [self.bundle.stops_file]  # an external net: the user's
        cfg = SumoConfig(net_file=self.bundle.net_file, additional_files=additional, step_s=self.dt,
                         seed=self.seed, step_method=self.step_method, vtypes=vtypes,
                         output_dir=self.out_dir if outs else None, sumo_outputs=outs,
                         extra_args=self.sumo_extra_args)
        t_wall = _time.perf_counter()
        bar = None
        if self.progress:
            from tqdm import tqdm

            bar = tqdm(total=int(self.duration_s), unit="sim-s", desc=self.scenario.name, leave=False)
        with SumoBridge(cfg) as bridge:
            self.bridge = bridge
            t = bridge.time_s
            last_bar = t
            while t <= self.duration_s + 1e-9:
                self._step(t)
                bridge.step()
                self.steps += 1
                t = bridge.time_s
                if bar is not None and t - last_bar >= 10:
                    bar.update(int(t - last_bar))
                    last_bar = t
                if self._all_done():
                    break
            self.end_s = t
        if bar is not None:
            bar.close()
        self.wall_s = _time.perf_counter() - t_wall
        return self.recorder.summary()

    def _all_done(self) -> bool:
        return all(tr.status in ("arrived", "removed") for tr in self.trains.values())

    def _active(self) -> list[TrainRuntime]:
        return [tr for tr in self.trains.values() if tr.status in ("inserting", "running")]

    def _step(self, t: float) -> None:
        self.layer.advance_to(t)
        bridge = self.bridge
        present = set(bridge.present_ids())
        active = [tr for tr in self._active() if tr.train_id in present]
        for tr in self._active():
            if tr.status == "inserting" and tr.train_id in present:
                tr.status = "running"
                tr.departed_s = t
                self.events.record(t, "train_departed", tr.train_id, station=tr.trip.origin.station_id)
        if not active:
            return
        ids = [tr.train_id for tr in active]
        truth = bridge.read(ids)
        for i, tr in enumerate(active):
            tr.front_m = tr.depart_chainage_m + float(truth.odometer_m[i])
            sumo_v = float(truth.speed_mps[i])
            # SUMO applies exactly the speed we sent (speedMode 32) unless it holds the train at a stop
            expected_v = tr.sent_speed_mps if tr.sent_speed_mps is not None else tr.plant.speed_mps
            if abs(sumo_v - expected_v) > 1e-6 and tr.sent_speed_mps is not None:
                if tr.mp_state is not None:
                    from railsim.physics import multipoint

                    tr.mp_state = multipoint.initial_state(tr.mp_params, tr.depart_chainage_m +
                                                           float(truth.odometer_m[i]), sumo_v)
                if tr.mono_state is not None:
                    from railsim.physics import monorail as vehicle_model

                    tr.mono_state = vehicle_model.PlantState(t_s=t, x_m=tr.depart_chainage_m +
                                                             float(truth.odometer_m[i]), v_mps=sumo_v)
                # SUMO holds a dwelling train at 0; adopt SUMO's speed so the plant never drifts from the world
                tr.plant = dynamics.PlantState(speed_mps=sumo_v, applied_accel_mps2=0.0 if sumo_v == 0 else
                                               tr.plant.applied_accel_mps2,
                                               target_accel_mps2=0.0 if sumo_v == 0 else tr.plant.target_accel_mps2)
            tr.sumo_stopped_now = bool(truth.stopped[i])

        self.occupancy.update([Body(tr.train_id, tr.view, tr.front_m, tr.trip.vehicle.length_m) for tr in active])
        ahead: dict[str, Ahead | None] = {}
        for tr in active:
            a = self.occupancy.ahead(tr.train_id, self.settings.lookahead_m)
            ahead[tr.train_id] = a
            self._truth_checks(t, tr, a)
        for c in bridge.collisions():
            c["t_s"] = t
            self.sumo_collisions.append(c)
            self.events.record(t, "sumo_collision", str(c["collider"]), victim=str(c["victim"]), type=str(c["type"]))

        if self.junction is not None:  # plans, re-plans, lock order, formations, hand-over at F
            self.junction.update(t)
        for tr in active:
            self._stop_bookkeeping(t, tr)
            self._formation_bookkeeping(t, tr, ahead[tr.train_id])
            self._interlocking_bookkeeping(t, tr)

        self._coop_neighbours = self._cooperative_graph(t, active) if self.coop_edges else {}
        reports = {tr.train_id: self._report(t, tr) for tr in active}  # the state at t, before the plant step
        # broadcast the state at t (with the plan decided last step) and deliver what is due now: a zero-delay
        # channel gives the neighbours' state at t in the same step (the papers' "perfect communication")
        self._communicate(t, active, reports)
        self.layer.advance_to(t)
        speeds = []
        for tr in active:
            v_next = self._control(t, tr, ahead[tr.train_id])
            speeds.append(v_next)
        bridge.set_speeds(ids, speeds)
        self.recorder.step(t, active, ahead, reports)
        # trains that finished this step leave SUMO now
        for tr in active:
            if tr.status == "arrived":
                bridge.remove(tr.train_id)
                tr.status = "removed"

    # ------------------------------------------------------------------ truth checks
    def _truth_checks(self, t: float, tr: TrainRuntime, a: Ahead | None) -> None:
        if self.obstacles:
            hit = self._obstacle_ahead(tr)
            if hit is not None and hit[1] < 0.0 and (tr.train_id, hit[0]) not in self._colliding_pairs:
                self._colliding_pairs.add((tr.train_id, hit[0]))
                self.collisions.append({"t_s": t, "follower": tr.train_id, "leader": hit[0], "overlap_m": -hit[1],
                                        "chainage_m": tr.front_m})
                self.events.record(t, "collision", tr.train_id, leader=hit[0], overlap_m=round(-hit[1], 3))
                log.error("collision at t=%.1f s: %s hit %s", t, tr.train_id, hit[0])
        if a is None:
            tr.last_gap_m = INF
            return
        tr.last_gap_m = a.gap_m
        if a.gap_m < tr.min_gap_m:
            tr.min_gap_m = a.gap_m
        if a.gap_m < 0.0:
            pair = (tr.train_id, a.train_id)
            if pair not in self._colliding_pairs:
                self._colliding_pairs.add(pair)
                self.collisions.append({"t_s": t, "follower": tr.train_id, "leader": a.train_id,
                                        "overlap_m": -a.gap_m, "chainage_m": tr.front_m})
                self.events.record(t, "collision", tr.train_id, leader=a.train_id, overlap_m=round(-a.gap_m, 3))
                log.error("collision at t=%.1f s: %s ran into %s (overlap %.2f m)", t, tr.train_id, a.train_id,
                          -a.gap_m)

    # ------------------------------------------------------------------ stops
    def _coupled_mark_offset(self, tr: TrainRuntime, stop: TripStop) -> float:
        """How far behind the platform mark a coupled follower halts (leader length + target gap), or 0."""
        f = self.formation_of_follower.get(tr.train_id)
        if f is None:
            return 0.0
        state = self.formations.state(f.id)
        if state not in ("coupling", "coupled", "decoupling"):
            return 0.0
        leader = self.trains[self.formations_leader_id(f)]
        if leader.status in ("running", "inserting"):
            lstop = leader.trip.stops[leader.next_stop] if leader.next_stop < len(leader.trip.stops) else None
        elif leader.arrived_s is not None:
            # it stands at its destination (SUMO no longer holds it): a platoon keeps its places there
            lstop = leader.trip.stops[-1]
        else:
            return 0.0
        if lstop is None or lstop.station_id != stop.station_id:
            return 0.0
        # a chain (A <- B <- C) stands one behind the other: behind the leader's own halt position
        return self._coupled_mark_offset(leader, lstop) + leader.trip.vehicle.length_m + float(f.target_gap_m)

    def formations_leader_id(self, f: Any) -> str:
        return self.trains[self.trips_by_service[f.leader.service][f.leader.trip].trip_id].train_id

    def _current_stop(self, tr: TrainRuntime) -> tuple[TripStop | None, float]:
        if tr.next_stop >= len(tr.trip.stops):
            return None, 0.0
        stop = tr.trip.stops[tr.next_stop]
        return stop, self._coupled_mark_offset(tr, stop)

    def _stop_bookkeeping(self, t: float, tr: TrainRuntime) -> None:
        stop, offset = self._current_stop(tr)
        if stop is None:
            return
        stopped_now = tr.sumo_stopped_now
        v = tr.plant.speed_mps
        mark = stop.mark_m - offset
        if stopped_now and not tr.sumo_stopped:
            tr.sumo_stopped = True
            tr.dwell_started_s = t
            if v > 0.1:
                self.events.record(t, "stop_registered_moving", tr.train_id, station=stop.station_id, speed_mps=v)
                log.error("SUMO registered %s as stopped at %s while moving at %.2f m/s", tr.train_id,
                          stop.station_id, v)
            if tr.halted_s is None:  # SUMO saw the halt before we did (same step)
                tr.halted_s = t
                tr.halt_error_m = tr.front_m - mark
            tr.stops_served += 1
            self.events.record(t, "stop_registered", tr.train_id, station=stop.station_id)
            if stop.is_destination:
                tr.arrived_s = tr.halted_s
                tr.status = "arrived"
                self.recorder.stop_record(tr, stop, tr.halted_s, None, tr.halt_error_m)
                self.events.record(t, "train_arrived", tr.train_id, station=stop.station_id)
                self._release_all_locks(t, tr)
            return
        if tr.sumo_stopped and not stopped_now:
            # dwell over: departure
            tr.sumo_stopped = False
            self.recorder.stop_record(tr, stop, tr.halted_s, t, tr.halt_error_m)
            self.events.record(t, "stop_departed", tr.train_id, station=stop.station_id)
            self._on_departed_station(t, tr, stop)
            tr.next_stop += 1
            tr.halted_s = None
            tr.halt_error_m = None
            return
        if not tr.sumo_stopped and tr.halted_s is None and v == 0.0 and \
                stop.window_start_m - 1e-6 <= tr.front_m <= stop.window_end_m + 1e-6:
            tr.halted_s = t
            tr.halt_error_m = tr.front_m - mark
        if not tr.sumo_stopped and tr.front_m > stop.window_end_m + self.settings.missed_stop_tolerance_m:
            self.events.record(t, "stop_missed", tr.train_id, station=stop.station_id,
                               overrun_m=round(tr.front_m - stop.window_end_m, 3))
            log.warning("%s overran the platform at %s by %.2f m", tr.train_id, stop.station_id,
                        tr.front_m - stop.window_end_m)
            self.recorder.stop_record(tr, stop, None, None, None, missed=True)
            self.bridge.skip_next_stop(tr.train_id)
            tr.next_stop += 1
            tr.halted_s = None
            if stop.is_destination:
                tr.status = "arrived"
                tr.arrived_s = t

    def _on_departed_station(self, t: float, tr: TrainRuntime, stop: TripStop) -> None:
        # a formation follower waiting for its leader to stand here is inserted now... (handled on halt below)
        for f in self.formation_of_leader.get(tr.train_id, ()):  # decouple when the leader departs X
            st = self.formations.state(f.id)
            if st in ("coupling", "coupled"):
                if (_trig(f.decouple, "at_station") and f.decouple.station == stop.station_id) or \
                        self._last_stop_before_switch(tr, stop, f):
                    self.formations.request_decouple(f.id)
        f = self.formation_of_follower.get(tr.train_id)
        if f is not None and _trig(f.couple, "at_station") and f.couple.station == stop.station_id:
            self.formations.request_couple(f.id)

    def _last_stop_before_switch(self, leader: TrainRuntime, stop: TripStop, f: Any) -> bool:
        if not _trig(f.decouple, "before_switch"):
            return False
        sw_id = f.decouple.switch
        later_marks = [s.mark_m for s in leader.trip.stops if s.mark_m > stop.mark_m]
        for rs in leader.trip.route.switches:
            if rs.switch_id == sw_id and 0.0 <= rs.point_m - stop.mark_m <= self.settings.decouple_distance_m:
                # only the last stop before the switch: no other stop of the leader lies in between
                return not any(m < rs.point_m for m in later_marks)
        return False

    # ------------------------------------------------------------------ formations
    def _formation_bookkeeping(self, t: float, tr: TrainRuntime, a: Ahead | None) -> None:
        # insert followers that couple on departure once their leader stands at the follower's origin
        for f in self.formation_of_leader.get(tr.train_id, ()):  # tr is a leader
            follower = self._trip_ref(f.follower, "formations")
            if follower.status == "scheduled" and _trig(f.couple, "on_departure"):
                stop, _ = self._current_stop(tr)
                if stop is not None and tr.sumo_stopped and stop.station_id == follower.trip.origin.station_id:
                    self._insert(follower, behind=tr, gap_m=float(f.target_gap_m))
                    self.formations.request_couple(f.id)
            if _trig(f.decouple, "before_switch") and self.formations.state(f.id) in ("coupling", "coupled"):
                for rs in tr.trip.route.switches:
                    if rs.switch_id == f.decouple.switch and \
                            rs.point_m - tr.front_m <= self.settings.decouple_distance_m and tr.front_m < rs.point_m:
                        nxt, _ = self._current_stop(tr)
                        if nxt is None or nxt.mark_m > rs.point_m:  # no stop left before the switch
                            self.formations.request_decouple(f.id)
        f = self.formation_of_follower.get(tr.train_id)
        if f is not None and a is not None and self._uses_monorail_fsm(tr):
            self._monorail_fsm(t, tr, f, a)
        if f is not None:
            leader = self.trains[self.formations_leader_id(f)]
            if a is not None and a.train_id == leader.train_id:
                # the state machine judges the error against the controller's effective target (gap policy:
                # larger than the standstill target at speed), expressed around the formation's own target
                gap_for_fsm = a.gap_m - (self._effective_target(tr, f) - float(f.target_gap_m))
                self.formations.observe(t, f.id, gap_for_fsm, tr.plant.speed_mps - leader.plant.speed_mps)
            elif self.formations.state(f.id) == "decoupling":
                # the leader is no longer ahead on our track (it took the other leg, or left the line):
                # the units are apart, which completes decoupling
                self.formations.observe(t, f.id, APART_GAP_M, 0.0)
            if self.formations.state(f.id) == "coupled":
                tr.coupled_s += self.dt

    def _uses_monorail_fsm(self, tr: TrainRuntime) -> bool:
        name = tr.trip.roles.get("coupled")
        return name is not None and self.scenario.controllers[name].type in ("monorail_apf", "monorail_dmpc")

    def _monorail_fsm(self, t: float, tr: TrainRuntime, f: Any, a: Ahead) -> None:
        """Paper D's follower state machine (spec §3.1/§3.2.4) on the formation: in-operation decoupling.

        Fed the true gap and closing speed every step; it logs every state change (``vc_state``) and turns
        *passive* (spacing opening past d_max) and *active* (spacing closing below d_min) decoupling into a
        decouple request to the formation. Collision avoidance stays with the ``ca`` role (``ca_enabled=False``).
        """
        from controllers.monorail.states import StateParams, VcInputs, VcMemory, VcState, transition

        fstate = self.formations.state(f.id)
        if tr.vc_fsm is None:
            tr.vc_fsm = (VcMemory(VcState.INDEPENDENT, since_s=t), StateParams(target_gap_m=float(f.target_gap_m)))
        mem, params = tr.vc_fsm
        other = self.trains[a.train_id]
        inp = VcInputs(t_s=t, gap_m=a.gap_m, closing_speed_mps=tr.plant.speed_mps - other.plant.speed_mps,
                       speed_mps=tr.plant.speed_mps, couple_command=fstate in ("coupling", "coupled"),
                       ca_enabled=False)
        new, events = transition(mem, inp, params)
        tr.vc_fsm = (new, params)
        for ev in events:
            state, _, reason = ev.partition(":")
            self.events.record(t, "vc_state", tr.train_id, state=state, reason=reason or None,
                               gap_m=round(a.gap_m, 3))
            if state == "decoupling" and reason in ("passive", "active") and fstate in ("coupling", "coupled"):
                self.events.record(t, f"{reason}_decoupling", f.id, gap_m=round(a.gap_m, 3))
                self.formations.request_decouple(f.id)

    def _effective_target(self, tr: TrainRuntime, f: Any) -> float:
        """Target gap in force for a follower: its controller's policy value if it reported one."""
        return tr.vc_target_gap_m if tr.vc_target_gap_m is not None else float(f.target_gap_m)

    def _formation_tail_m(self, tr: TrainRuntime) -> float:
        """Length behind a formation leader's rear that belongs to its coupled formation (gap + follower), or 0."""
        tail = 0.0
        for f in self.formation_of_leader.get(tr.train_id, ()):  # usually one follower
            if self.formations.state(f.id) not in ("coupling", "coupled"):
                continue
            fol = self._trip_ref(f.follower, "formations")
            if fol.status == "running":
                tail = max(tail, self._effective_target(fol, f) + fol.trip.vehicle.length_m +
                           self._formation_tail_m(fol))
        return tail

    def _in_final_approach(self, tr: TrainRuntime, mark_m: float) -> bool:
        """Close enough to ``mark_m`` that station braking is (about to be) under way."""
        v = tr.plant.speed_mps
        plan_decel = 0.5 * tr.trip.vehicle.service_decel_mps2  # gentler than the ATO's: starts the hand-over early
        return mark_m - tr.front_m <= v * v / (2.0 * plan_decel) + self.settings.final_approach_margin_m

    # ------------------------------------------------------------------ interlocking
    def _interlocking_bookkeeping(self, t: float, tr: TrainRuntime) -> None:
        length = tr.trip.vehicle.length_m
        for rs in tr.trip.route.switches:
            sid = rs.switch_id
            if sid in tr.released:
                continue
            if rs.point_m < tr.trip.depart_chainage_m - length:
                continue
            if sid not in tr.locks and rs.point_m - tr.front_m <= self.settings.lock_request_distance_m and \
                    not (self.junction is not None and self.junction.manages_lock(tr.train_id, sid)):
                holders = self._lock_group(tr, rs)
                if holders is not None:
                    req = self.interlocking.request(holders, sid, rs.leg)
                    for h in holders:
                        self.trains[h].locks[sid] = req
            if sid in tr.locks and tr.front_m > rs.point_m and sid not in tr.violations and \
                    not self.interlocking.is_locked_for(tr.train_id, sid, rs.leg):
                tr.violations.add(sid)
                self.events.record(t, "switch_violation", tr.train_id, switch=sid, leg=rs.leg)
                log.error("%s passed switch %s without its lock", tr.train_id, sid)
            if sid in tr.locks and tr.front_m - length > rs.point_m + self.settings.clearance_m:
                self.interlocking.release(tr.train_id, sid)
                tr.released.add(sid)

    def _lock_group(self, tr: TrainRuntime, rs: Any) -> tuple[str, ...] | None:
        """Who requests: a coupled follower on the same leg rides on its leader's request."""
        f = self.formation_of_follower.get(tr.train_id)
        if f is not None and self.formations.state(f.id) in ("coupling", "coupled"):
            leader = self.trains[self.formations_leader_id(f)]
            if rs.switch_id in leader.locks and rs.switch_id not in leader.released:
                req = leader.locks[rs.switch_id]
                if tr.train_id in getattr(req, "holder_ids", ()):
                    return None  # already in the leader's group
        group = [tr.train_id]
        for f2 in self.formation_of_leader.get(tr.train_id, ()):  # include coupled followers on the same leg
            if self.formations.state(f2.id) not in ("coupling", "coupled"):
                continue
            fol = self._trip_ref(f2.follower, "formations")
            if fol.status not in ("inserting", "running") or rs.switch_id in fol.locks:
                continue
            if any(s.switch_id == rs.switch_id and s.leg == rs.leg for s in fol.trip.route.switches):
                group.append(fol.train_id)
        return tuple(group)

    def _release_all_locks(self, t: float, tr: TrainRuntime) -> None:
        for sid in list(tr.locks):
            if sid not in tr.released:
                self.interlocking.release(tr.train_id, sid)
                tr.released.add(sid)

    def _authority_end(self, tr: TrainRuntime) -> float:
        end = tr.view.length_m - 1.0
        for rs in tr.trip.route.switches:
            if rs.point_m <= tr.front_m - 1e-6 or rs.switch_id in tr.released:
                continue
            if not self.interlocking.is_locked_for(tr.train_id, rs.switch_id, rs.leg):
                return min(end, rs.point_m - self.settings.protection_margin_m)
        return end

    # ------------------------------------------------------------------ communication
    def _report(self, t: float, tr: TrainRuntime) -> tuple[Any, ...]:
        """A position report: (route id, front chainage, speed, applied acceleration, time)."""
        return (tr.trip.route.id, tr.front_m, tr.plant.speed_mps, tr.plant.applied_accel_mps2, t)

    def _communicate(self, t: float, active: list[TrainRuntime], reports: dict[str, tuple[Any, ...]]) -> None:
        """Send every train's report to the ground (t2g) and to its formation followers (t2t).

        A report is the state at ``t`` plus the plan its controller returned at the previous step
        (``Command.info["plan"]``: ``dt_s``, ``position_m``/``speed_mps``/``accel_mps2`` sequences and optionally
        ``t0_s``, the time entry 0 refers to) — the DMPC convention of broadcasting the last optimal plan.
        """
        t2g = self.channels.get("t2g")
        t2t = self.channels.get("t2t")
        for tr in active:
            report = reports[tr.train_id] + (tr.last_plan,)
            if t2g is not None:
                t2g.send(tr.train_id, "ground", report)
            if t2t is not None:
                for f in self.formation_of_leader.get(tr.train_id, ()):  # leaders talk to their followers
                    fol = self._trip_ref(f.follower, "formations")
                    if fol.status in ("inserting", "running"):
                        t2t.send(tr.train_id, fol.train_id, report)
                for other in self._coop_neighbours.get(tr.train_id, {}):  # graph neighbours, both ways
                    t2t.send(tr.train_id, other, report)

    def _known_state(self, observer: TrainRuntime, other: TrainRuntime, channel: str,
                     receiver: str) -> PredecessorState | None:
        """What ``observer`` knows of ``other`` via ``channel`` (mapped into the observer's frame)."""
        ch = self.channels.get(channel)
        msg = ch.latest(receiver, other.train_id) if ch is not None else None
        if msg is None:
            # no message yet: a registration report — a follower placed behind its leader knows where the leader
            # stood; the ground knows where each train was inserted (stale and behind the truth: conservative)
            reg = self._registration.get((observer.train_id, other.train_id))
            route_id, pos, v, acc, stamp = reg if reg is not None else (
                other.trip.route.id, other.depart_chainage_m, other.trip.start_speed_mps, 0.0,
                other.inserted_s or 0.0)
            plan = None
        else:
            route_id, pos, v, acc, stamp, plan = msg.payload
        veh = other.trip.vehicle
        mapped = observer.view.map_body(other.view, pos, veh.length_m)
        if mapped is None:
            return None
        front, rear = mapped  # only the part of its body on our track (see RouteView.map_body)
        planned: dict[str, Any] = {}
        if plan:  # the sender's last plan, moved into our frame and aligned so that entry 0 is at stamp_s
            shift = front - pos
            dt_plan = float(plan.get("dt_s", 0.0))
            drop = 0
            if "t0_s" in plan and dt_plan > 0.0:  # entry 0 refers to t0_s: skip entries before the stamp
                drop = max(0, int(round((stamp - float(plan["t0_s"])) / dt_plan)))
            planned = {"planned_position_m": tuple(float(x) + shift for x in plan.get("position_m", ())[drop:]),
                       "planned_speed_mps": tuple(float(x) for x in plan.get("speed_mps", ())[drop:]),
                       "planned_accel_mps2": tuple(float(x) for x in plan.get("accel_mps2", ())[drop:]),
                       "plan_dt_s": dt_plan}
        return PredecessorState(train_id=other.train_id, position_m=front, speed_mps=v, accel_mps2=acc,
                                length_m=front - rear, stamp_s=stamp, age_s=max(0.0, self.layer.now_s - stamp),
                                service_decel_mps2=veh.service_decel_mps2,
                                emergency_decel_mps2=veh.emergency_decel_mps2, source=channel, **planned)

    # ------------------------------------------------------------------ control
    def _control(self, t: float, tr: TrainRuntime, a: Ahead | None) -> float:
        veh = tr.trip.vehicle
        stop, offset = self._current_stop(tr)
        target = None
        if stop is not None:
            # halted inside the window: hold until SUMO registers the stop (~1 s) and through the dwell
            target = StopTarget(stop.station_id, stop.mark_m - offset, stop.window_start_m, stop.window_end_m,
                                dwelling=tr.sumo_stopped or tr.halted_s is not None)
        own_pos = tr.front_m
        own_v = tr.plant.speed_mps
        if self.noise_pos_sd > 0:
            own_pos += float(self.noise_rng.normal(0.0, self.noise_pos_sd))
        if self.noise_speed_sd > 0:
            own_v = max(0.0, own_v + float(self.noise_rng.normal(0.0, self.noise_speed_sd)))
        grad = tr.view.gradient_at(tr.front_m)
        tail_m = self._formation_tail_m(tr)
        limits = tr.view.limits_ahead(tr.front_m - veh.length_m - tail_m, tr.front_m + self.settings.lookahead_m)
        if tail_m > 0.0:
            # a coupled formation runs like one long train: a restriction holds until its last unit's rear clears
            limits = tuple(SpeedLimit(lim.start_m, lim.end_m + tail_m, lim.speed_mps) for lim in limits)
        base = dict(
            t_s=t, dt_s=self.dt,
            own=OwnState(tr.train_id, own_pos, own_v, tr.plant.applied_accel_mps2, veh.length_m, grad),
            vehicle=veh, route_length_m=tr.view.length_m,
            speed_limits=limits,
            line_speed_mps=tr.view.line_speed_mps, next_stop=target, authority_end_m=self._authority_end(tr),
        )
        commands: dict[str, Command] = {}
        f = self.formation_of_follower.get(tr.train_id)
        fstate = self.formations.state(f.id) if f is not None else "free"
        leader = self.trains[self.formations_leader_id(f)] if f is not None else None
        ato = tr.controllers["ato"]
        if fstate in ("coupling", "coupled") and tr.controllers.get("ato_closing") is not None and not tr.degraded:
            ato = tr.controllers["ato_closing"]
        ato_extras: dict[str, Any] = {}
        if tr.train_id in self.coop_members:
            edges = self._coop_neighbours.get(tr.train_id, {})
            states = []
            for j in edges:
                st = self._known_state(tr, self.trains[j], "t2t", tr.train_id)
                if st is not None:
                    states.append(st)
            ato_extras = {"edges": dict(edges), "neighbours": tuple(states), "k": int(round(t / self.dt))}
        if tr.mp_state is not None:  # the carriage model's relative state (couplers) for model-based ATOs
            ato_extras["multipoint_rel_state"] = tr.mp_state.relative()
        commands["ato"] = ato.command(Observation(**base, extras=ato_extras))

        if self.junction is not None and self.junction.in_plan_phase(tr.train_id):
            self._junction_commands(t, tr, a, base, commands, own_pos, own_v, fstate)
            return self._finish_control(t, tr, commands, grad)
        # following: coupled controller on t2t data, or separation on ground data
        used_vc = False
        if f is not None and fstate in ("coupling", "coupled") and leader is not None and \
                leader.status in ("inserting", "running") and tr.controllers.get("coupled") is not None:
            pred = self._known_state(tr, leader, "t2t", tr.train_id)
            # hysteresis: degrade when the leader's data is older than max_message_age_s, restore only once it is
            # at least one step fresher (a delay equal to the limit would otherwise flip the mode every step)
            age_limit = self.settings.max_message_age_s - (self.dt if tr.degraded else 0.0)
            if pred is not None and pred.age_s <= age_limit:
                extras = {}
                if stop is not None and offset > 0.0 and self._in_final_approach(tr, stop.mark_m - offset):
                    # both units stop at this platform: the ATO stops us exactly behind the leader's mark, the
                    # coupled controller keeps only its safety cap (its slow gap loop would halt us short)
                    extras["vc_tracking"] = False
                obs = Observation(**base, predecessor=pred, formation_state=fstate,
                                  target_gap_m=float(f.target_gap_m), extras=extras)
                vc_cmd = tr.controllers["coupled"].command(obs)
                commands["coupled"] = vc_cmd
                info = vc_cmd.info or {}
                tr.vc_solve_s = float(info["solve_time_s"]) if info.get("solve_time_s") is not None else None
                tr.vc_objective = float(info["J"]) if info.get("J") is not None else None
                tgt = vc_cmd.info.get("target_gap_m") if vc_cmd.info else None
                tr.vc_target_gap_m = float(tgt) if tgt is not None else None
                used_vc = True
                tr.stale_max_s = max(tr.stale_max_s, pred.age_s)
                if tr.degraded:
                    tr.degraded = False
                    self.events.record(t, "vc_restored", tr.train_id)
            elif not tr.degraded:
                tr.degraded = True
                self.events.record(t, "vc_degraded", tr.train_id,
                                   age_s=None if pred is None else round(pred.age_s, 3))
        if a is not None and not (used_vc and leader is not None and a.train_id == leader.train_id):
            other = self.trains[a.train_id]
            pred = self._known_state(tr, other, "t2g", "ground")
            if pred is not None:
                tr.stale_max_s = max(tr.stale_max_s, pred.age_s)
                obs = Observation(**base, predecessor=pred, formation_state=fstate)
                commands["separation"] = tr.controllers["separation"].command(obs)
        ca_ctl = tr.controllers.get("ca")
        if ca_ctl is not None:  # collision avoidance on the train's own sensor: works with the radio down
            ca_cmd = ca_ctl.command(Observation(**base, extras={"sensor": self._sensor(tr, a)},
                                                formation_state=fstate))
            commands["ca"] = ca_cmd
            event = ca_cmd.info.get("event") if ca_cmd.info else None
            if event in ("ca_on", "ca_off"):
                self.events.record(t, "ca_trigger" if event == "ca_on" else "ca_release", tr.train_id,
                                   gap_m=round(float(ca_cmd.info.get("gap_m", INF)), 3)
                                   if math.isfinite(float(ca_cmd.info.get("gap_m", INF))) else None,
                                   trigger_m=ca_cmd.info.get("trigger_m"))
        return self._finish_control(t, tr, commands, grad)

    def _junction_commands(self, t: float, tr: TrainRuntime, a: Ahead | None, base: dict[str, Any],
                           commands: dict[str, Command], own_pos: float, own_v: float, fstate: str) -> None:
        """A train under the junction plan: the plan's command, and only a relative-braking-distance safety cap
        against the train ahead (the coupled controller without gap tracking) — see railsim.engine.extensions.junction."""
        u = self.junction.command(t, tr, own_pos, own_v)
        if u is not None:
            commands["junction"] = Command(u)
        if a is None:
            return
        other = self.trains[a.train_id]
        f = self.formation_of_follower.get(tr.train_id)
        own_leader = f is not None and self.formations_leader_id(f) == other.train_id
        pred = self._known_state(tr, other, "t2t" if own_leader else "t2g", tr.train_id if own_leader else "ground")
        guard = tr.controllers.get("coupled")
        if pred is None:
            return
        if guard is None:
            commands["separation"] = tr.controllers["separation"].command(
                Observation(**base, predecessor=pred, formation_state=fstate))
            return
        target = self.junction.target_gap_m
        commands["guard"] = guard.command(Observation(**base, predecessor=pred, formation_state="coupling",
                                                      target_gap_m=target, extras={"vc_tracking": False}))

    def _finish_control(self, t: float, tr: TrainRuntime, commands: dict[str, Command], grad: float) -> float:
        """Arbitrate the roles' commands (minimum) and advance the plant; returns the speed handed to SUMO."""
        veh = tr.trip.vehicle
        role, cmd = arbitrate(commands)
        if cmd.emergency and tr.emergency_since_s is None:
            tr.emergency_since_s = t
            self.events.record(t, "emergency_brake_on", tr.train_id, role=role)
        elif not cmd.emergency and tr.emergency_since_s is not None:
            self.events.record(t, "emergency_brake_off", tr.train_id, role=role,
                               duration_s=round(t - tr.emergency_since_s, 3))
            tr.emergency_since_s = None
        if cmd.fallback:
            tr.fallbacks += 1
        if not math.isfinite(cmd.accel_mps2):
            self.events.record(t, "controller_nan", tr.train_id, role=role)
            log.error("%s: %s controller returned %r; braking", tr.train_id, role, cmd.accel_mps2)
            cmd = Command(-veh.service_decel_mps2, fallback=True)
            tr.fallbacks += 1
        if tr.mp_state is not None:
            return self._multipoint_step(t, tr, role, cmd)
        if tr.mono_state is not None:
            return self._monorail_step(t, tr, role, cmd, grad)
        u = cmd.accel_mps2
        noise_trains = self.scenario.faults.actuator_noise.trains
        if self.actuator_sd > 0.0 and (noise_trains is None or tr.train_id in noise_trains):
            u += float(self.actuator_rng.normal(0.0, self.actuator_sd))  # the papers' control disturbance
        for bias in self.scenario.faults.actuator_bias:  # a faulty actuator (injected fault, logged at start)
            if bias.train == tr.train_id and bias.from_s <= t < bias.until_s:
                u += bias.accel_mps2
        plan = cmd.info.get("plan") if cmd.info else None
        tr.last_plan = {"t0_s": t, **plan} if plan else None  # entry 0 = decision time unless the plan says so
        v_now = tr.plant.speed_mps
        res = dynamics.step(veh, tr.plant, u, self.dt, grad, cmd.emergency, self.step_method)
        jerk = abs(res.state.applied_accel_mps2 - tr.plant.applied_accel_mps2) / self.dt
        tr.max_jerk_mps3 = max(tr.max_jerk_mps3, jerk)
        tr.plant = res.state
        tr.energy_j += res.traction_energy_j
        for s in res.saturations:
            tr.saturations[s] = tr.saturations.get(s, 0) + 1
        tr.last_role = role
        tr.last_cmd_mps2 = cmd.accel_mps2
        # what SUMO moves the train by during the coming step: Euler/ballistic take the new speed; the papers'
        # explicit Euler x(k+1) = x(k) + T·v(k) ("forward") needs the speed *before* the update (spec 002 §7.3)
        tr.sent_speed_mps = v_now if self.step_method == "forward" else res.state.speed_mps
        return tr.sent_speed_mps


def _carriage_forces(cmd: Command, p: Any) -> np.ndarray:
    """Per-carriage forces [N]: the controller's own (``info["forces_n"]``) or its acceleration spread evenly."""
    forces = cmd.info.get("forces_n") if cmd.info else None
    if forces is not None and len(forces) == p.n_cars:
        return np.asarray(forces, dtype=float)
    return np.full(p.n_cars, float(cmd.accel_mps2) * p.car_mass_kg)


def _trig(trigger: Any, kind: str) -> bool:
    """True if a formation trigger (``couple``/``decouple``, possibly None) is of ``kind``."""
    return trigger is not None and trigger.kind == kind


_DELAY_KEYS = {"value": "value_s", "low": "low_s", "high": "high_s", "mean": "mean_s", "sd": "std_s"}


def _delay_mapping(delay: Any) -> dict[str, Any]:
    """Scenario delay spec (``dist`` + ``value|low,high|mean,sd`` in seconds) → the comms layer's field names."""
    out: dict[str, Any] = {"dist": delay.dist}
    for key, value in dict(delay.params).items():
        out[_DELAY_KEYS.get(key, key)] = value
    return out


def run(scenario: Any, out_dir: Path | str | None, seed: int | None = None, progress: bool | None = None,
        settings: EngineSettings | None = None) -> dict[str, Any]:
    """Run ``scenario`` (a :class:`railsim.scenario.Scenario`) and write its outputs to ``out_dir``.

    Returns the summary dictionary (also written as ``summary.json``).
    """
    sim = Simulation(scenario, Path(out_dir) if out_dir is not None else None, seed=seed, progress=progress,
                     settings=settings)
    summary = sim.run()
    if sim.out_dir is not None:
        sim.recorder.write(sim.out_dir)
        from railsim.analysis import registry as analyses
        from railsim.record import output

        results, tables = analyses.run(scenario, sim.out_dir)
        if results:  # the papers' own metrics, from the files just written
            summary["analyses"] = results
            summary["analysis_tables"] = tables
            output.write_json(sim.out_dir / "summary.json", {k: v for k, v in summary.items()
                                                             if k != "analysis_tables"})
    return summary
