"""Safety on ground truth: collisions between trains and with obstacles, SUMO's own collisions, the sensor.

Collisions are detected on the true positions (the occupancy's gap to the train ahead < 0, or a front past an
obstacle) once per pair and logged as ``collision`` events; SUMO's own collision check runs too and each of its
reports is a ``sumo_collision`` event, kept apart in the detail (``collisions_railsim``, ``sumo_collisions``) and
counted together in ``collisions`` (docs/architecture.md, "Safety is never hidden"), so the summary's
``collisions`` is never lower than what SUMO saw. Trains on different tracks meet only inside a node: where two
movements cross at grade (``graph.graph["crossings"]``, :func:`network.topology.flat_crossings`: a diamond, the
track to a branch crossing the opposite main track at a double-track junction) two trains whose bodies span the
node at once on foe movements are a collision too (:meth:`SafetyMonitor.crossing_checks`; SUMO's own check calls
it a ``junction`` collision). On ``bidi`` track a train running or standing the other way is on the partner edge,
never "ahead" by edge: two such bodies overlapping on one track are a head-on collision
(:meth:`SafetyMonitor.head_on_checks`, :meth:`railsim.engine.occupancy.Occupancy.facing`; SUMO's ``frontal``).
Obstacles
(scenario ``events: obstacle``) are fixed to the track; a train's own ranging sensor (collision avoidance) reads
the nearest train or obstacle ahead within ``sensor_range_m``.

**Desync check.** Every chainage railsim uses (gaps, stopping errors, ``min_gap_m``) is SUMO's odometer plus the
insertion chainage. Each step the truth pass (:mod:`railsim.engine.truth`) compares it with where SUMO says the train is
(its edge and lane position, mapped to route chainage), and the step's advance with SUMO's speed (a train
moves at most ``max(v before, v now)·dt`` and never back; SUMO's ``moveTo`` shifts the odometer with the train,
so only this catches a jump). A difference above ``desync_tolerance_m`` means railsim believes something SUMO
does not (a train inserted elsewhere, moved behind our back). It is a ``desync`` event
(:meth:`SafetyMonitor.desync_found`) and a run failure (:attr:`SafetyMonitor.failure`; the run stops, writes its outputs and exits 3). Trains on an
internal junction lane are skipped for that step (their lane position is not on a route edge).

**Speed desync.** SUMO moves a controlled train at exactly the speed it is handed (speedMode 32) except at a
stop: it holds a dwelling train at 0 (the engine adopts that speed), and it halts a train that runs onto the end
of its stop at once, whatever its speed — an overrun the train's brakes could not have prevented, hidden by SUMO
(found by fuzzing: a vehicle with a 0.3 m/s³ jerk limit reached its stop's end at 4.5 m/s and stood one 0.2 s step
later). :meth:`SafetyMonitor.speed_imposed` checks every speed SUMO imposes on a train it was not holding: more
speed taken off in one step than the emergency brake can (``emergency_decel · dt``), hiding more run than the stop
tolerance (the least stopping distance, :func:`railsim.physics.dynamics.least_stop_distance_m`, from our speed
less that from SUMO's), is either a halt *inside* the window the train could still have stopped in — a
``sumo_forced_halt`` event (SUMO does this to trains much shorter than the platform, e.g. a 40 m unit on a 220 m
platform, from ~2 m/s some 5 m before the mark: the stopping error records where) — or a hidden overrun: a
``desync`` event (our speed, SUMO's, the next stop) and a run failure, like a position desync. The stop book
declares a stop missed before the train gets there (:func:`railsim.engine.stops.surely_overruns_m`), so the
failure is the backstop.
"""

from __future__ import annotations

import logging
import math
from bisect import bisect_right
from collections.abc import Callable
from typing import Any

from railsim.engine.events.clock import EventLayer
from railsim.engine.events.log import EventLog
from railsim.engine.occupancy import Ahead
from railsim.engine.settings import INF, EngineSettings
from railsim.engine.train import TrainRuntime
from railsim.physics import dynamics

log = logging.getLogger(__name__)

# -> (slots facing a train, the slot facing each, where it begins, the step's ids): Occupancy.facing_own_bodies
FacingBodies = Callable[[], tuple[list[int], list[int], list[float], list[str]]]


class SafetyMonitor:
    """Truth checks every step; obstacles; the sensor reading a controller may use."""

    def __init__(
        self, trains: dict[str, TrainRuntime], layer: EventLayer, events: EventLog, settings: EngineSettings
    ) -> None:
        self.trains = trains
        self.layer = layer
        self.events = events
        self.settings = settings
        self.obstacles: dict[str, tuple[str, float]] = {}  # obstacle id -> (SUMO edge, position on it [m])
        self.collisions: list[dict[str, Any]] = []
        self.sumo_collisions: list[dict[str, Any]] = []
        self._colliding_pairs: set[tuple[str, str]] = set()
        self.failure: str | None = None  # why the run must stop (a desync), one line
        # train -> [(crossing node, its movement, route chainage where the front enters / the rear has left)]
        self._crossings: dict[str, list[tuple[str, tuple[str, str], float, float]]] = {}
        # per train: its spans, and their ends if both starts and ends ascend along its route (else None)
        self._crossing_of: dict[str, tuple[list[tuple[str, tuple[str, str], float, float]], list[float] | None]] = {}
        self._foes: dict[str, dict[tuple[str, str], list[tuple[str, str]]]] = {}

    def set_up_crossings(self, graph: Any) -> None:
        """Where each train's route passes a flat crossing of ``graph`` (the truth check needs no interlocking)."""
        self._foes = graph.graph.get("crossings", {})
        if not self._foes:
            return
        for tid, tr in self.trains.items():
            route = tr.trip.route
            spans = []
            for k in range(len(route.edges) - 1):
                move = (route.edges[k], route.edges[k + 1])
                link = graph.get_edge_data(*move)  # None at a reversal (a turnaround is no graph edge)
                node = None if link is None else link["node"]
                if node is not None and move in self._foes.get(node, {}):
                    start_m = float(route.edge_start_m[k]) + float(graph.nodes[move[0]]["length_m"])
                    spans.append((node, move, start_m, float(route.edge_start_m[k + 1])))
            if spans:
                self._crossings[tid] = spans
                starts, ends = [span[2] for span in spans], [span[3] for span in spans]
                ordered = starts == sorted(starts) and ends == sorted(ends)  # (else every span is looked at)
                self._crossing_of[tid] = (spans, ends if ordered else None)

    # ------------------------------------------------------------------ obstacles
    def place_obstacle(self, oid: str, ev: Any) -> None:
        """A static obstacle appears ``ahead_m`` ahead of a train's front (on that train's route, fixed to the track)."""
        tr = self.trains[ev.train]
        ch = tr.front_m + float(ev.ahead_m)
        i = tr.view.edge_at(ch)
        self.obstacles[oid] = (tr.view.edges[i], ch - tr.view.edge_start_m[i])
        self.events.record(self.layer.now_s, "obstacle_appeared", oid, ahead_of=tr.train_id, chainage_m=round(ch, 3))
        if ev.duration_s is not None:

            def clear(_t: float, oid: str = oid) -> None:
                self.obstacles.pop(oid, None)
                self.events.record(self.layer.now_s, "obstacle_cleared", oid)

            self.layer.at(self.layer.now_s + float(ev.duration_s), clear, "obstacle_clear_due", oid)

    def obstacle_ahead(self, tr: TrainRuntime) -> tuple[str, float] | None:
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

    def sensor(self, tr: TrainRuntime, a: Ahead | None) -> dict[str, Any]:
        """What the train's own ranging sensor reads: nearest train or obstacle ahead within range (truth-based)."""
        reading: dict[str, Any] = {"distance_m": INF, "closing_speed_mps": 0.0, "object": "vehicle"}
        if a is not None and a.gap_m <= self.settings.sensor_range_m:
            other = self.trains[a.train_id]
            reading = {
                "distance_m": a.gap_m,
                "closing_speed_mps": tr.plant.speed_mps - other.plant.speed_mps,
                "object": "vehicle",
            }
        obs = self.obstacle_ahead(tr)
        if obs is not None and obs[1] <= self.settings.sensor_range_m and obs[1] < reading["distance_m"]:
            reading = {"distance_m": obs[1], "closing_speed_mps": tr.plant.speed_mps, "object": "obstacle"}
        return reading

    # ------------------------------------------------------------------ every step
    def truth_checks(self, t: float, tr: TrainRuntime, a: Ahead | None) -> None:
        """Gap to the train ahead (min gap, last gap) and collisions with it or with an obstacle."""
        if self.obstacles:
            hit = self.obstacle_ahead(tr)
            if hit is not None and hit[1] < 0.0:
                self._collision(t, tr, hit[0], -hit[1], "%s hit %s")
        if a is None:
            tr.last_gap_m = INF
            return
        tr.last_gap_m = a.gap_m
        if a.gap_m < tr.min_gap_m:
            tr.min_gap_m = a.gap_m
        if a.gap_m < 0.0:
            self._collision(t, tr, a.train_id, -a.gap_m, "%s ran into %s")

    def _collision(self, t: float, tr: TrainRuntime, other: str, overlap_m: float, what: str) -> None:
        pair = (tr.train_id, other)
        if pair in self._colliding_pairs:
            return
        self._colliding_pairs.add(pair)
        self.collisions.append(
            {"t_s": t, "follower": tr.train_id, "leader": other, "overlap_m": overlap_m, "chainage_m": tr.front_m}
        )
        self.events.record(t, "collision", tr.train_id, leader=other, overlap_m=round(overlap_m, 3))
        log.error("collision at t=%.1f s: " + what + " (overlap %.2f m)", t, tr.train_id, other, overlap_m)

    def crossing_checks(self, t: float, active: list[TrainRuntime]) -> None:
        """Two trains whose bodies span one flat crossing at once on foe movements collide (module docstring)."""
        if not self._crossings:
            return
        inside: dict[str, list[tuple[TrainRuntime, tuple[str, str]]]] = {}
        crossing_of = self._crossing_of
        for tr in active:
            mine = crossing_of.get(tr.train_id)
            if mine is None:
                continue
            spans, ends = mine
            front_m = tr.front_m
            rear_m = front_m - tr.trip.vehicle.length_m
            if ends is None:  # spans out of order along the route: every one is looked at
                for node, move, start_m, end_m in spans:
                    if front_m > start_m and rear_m < end_m:
                        inside.setdefault(node, []).append((tr, move))
                continue
            # one after the other along the route: from the first that ends beyond the rear (ends ascend: so do all
            # after it), up to the front
            for k in range(bisect_right(ends, rear_m), len(spans)):
                node, move, start_m, _ = spans[k]
                if start_m >= front_m:
                    break
                inside.setdefault(node, []).append((tr, move))
        for node, here in inside.items():
            for i, (tr, move) in enumerate(here):
                for other, move2 in here[i + 1 :]:
                    if move2 not in self._foes[node][move]:
                        continue
                    pair = (min(tr.train_id, other.train_id), max(tr.train_id, other.train_id))
                    if pair in self._colliding_pairs:
                        continue
                    self._colliding_pairs.add(pair)
                    self.collisions.append(
                        {
                            "t_s": t,
                            "follower": tr.train_id,
                            "leader": other.train_id,
                            "overlap_m": 0.0,
                            "chainage_m": tr.front_m,
                            "crossing": node,
                        }
                    )
                    self.events.record(t, "collision", tr.train_id, leader=other.train_id, crossing=node)
                    log.error("collision at t=%.1f s: %s and %s on crossing %s", t, tr.train_id, other.train_id, node)

    def head_on_checks(self, t: float, active: list[TrainRuntime], own_bodies: FacingBodies) -> None:
        """Two trains on one track facing each other whose bodies overlap collide head-on (module docstring);
        ``own_bodies()``: :meth:`railsim.engine.occupancy.Occupancy.facing_own_bodies` (for every train of
        ``active``, in its order, the train facing it on the track under its own body, in one call)."""
        mine, other, near, ids = own_bodies()
        for k, o, near_m in zip(mine, other, near, strict=True):  # (only the trains something faces)
            tr = active[k]
            if near_m > tr.front_m:
                continue
            other_id = ids[o]
            pair = (min(tr.train_id, other_id), max(tr.train_id, other_id))
            if pair in self._colliding_pairs:
                continue
            self._colliding_pairs.add(pair)
            overlap_m = tr.front_m - near_m
            self.collisions.append(
                {
                    "t_s": t,
                    "follower": tr.train_id,
                    "leader": other_id,
                    "overlap_m": overlap_m,
                    "chainage_m": tr.front_m,
                    "head_on": True,
                }
            )
            self.events.record(
                t, "collision", tr.train_id, leader=other_id, overlap_m=round(overlap_m, 3), head_on=True
            )
            log.error("collision at t=%.1f s: %s and %s head-on (overlap %.2f m)", t, tr.train_id, other_id, overlap_m)

    def sumo_reported(self, t: float, reports: list[dict[str, Any]]) -> None:
        """SUMO's own collision reports of this step (kept apart from ours)."""
        for c in reports:
            c["t_s"] = t
            self.sumo_collisions.append(c)
            self.events.record(t, "sumo_collision", str(c["collider"]), victim=str(c["victim"]), type=str(c["type"]))

    def desync_found(
        self,
        t: float,
        active: list[TrainRuntime],
        out_of_step: list[int],
        railsim_m: Any,
        sumo_m: Any,
        edges: list[str],
    ) -> None:
        """The trains the truth pass found out of step with SUMO (indices into ``active``; module docstring): a
        ``desync`` event each, with the chainage railsim expected and SUMO's (NaN: its edge is not on the route),
        and the run's failure."""
        tol = self.settings.desync_tolerance_m
        bad = []
        for k in out_of_step:
            tr = active[k]
            expected_m, sumo_here = float(railsim_m[k]), float(sumo_m[k])
            sumo_at = None if math.isnan(sumo_here) else sumo_here
            bad.append(tr.train_id)
            self.events.record(
                t,
                "desync",
                tr.train_id,
                railsim_m=round(expected_m, 3),
                sumo_m=None if sumo_at is None else round(sumo_at, 3),
                edge=edges[k],
            )
            log.error(
                "desync at t=%.1f s: %s railsim %.3f m, SUMO %s m (%s)", t, tr.train_id, expected_m, sumo_at, edges[k]
            )
        if bad and self.failure is None:
            self.failure = (
                f"railsim and SUMO disagree on where {', '.join(bad)} stand(s) at t={t:.1f} s "
                f"(more than {tol:g} m; see the desync events)"
            )

    def speed_imposed(self, t: float, tr: TrainRuntime, sumo_v_mps: float, railsim_v_mps: float, dt_s: float) -> None:
        """SUMO's speed for ``tr`` is not the one it was handed (module docstring, "Speed desync")."""
        veh = tr.trip.vehicle
        if tr.sumo_stopped or railsim_v_mps - sumo_v_mps <= veh.emergency_decel_mps2 * dt_s + 1e-6:
            return  # held at its stop (the dwell), or a speed the train's own brakes could have reached
        grade = tr.view.gradient_at(tr.front_m)
        least_m = dynamics.least_stop_distance_m(veh, railsim_v_mps, grade)
        if least_m - dynamics.least_stop_distance_m(veh, sumo_v_mps, grade) <= self.settings.missed_stop_tolerance_m:
            return  # the train would have stood within the stop tolerance of where SUMO halted it
        stop = tr.trip.stops[tr.next_stop] if tr.next_stop < len(tr.trip.stops) else None
        station = None if stop is None else stop.station_id
        detail = dict(railsim_mps=round(railsim_v_mps, 3), sumo_mps=round(sumo_v_mps, 3), next_stop=station)
        if stop is not None and tr.front_m + least_m <= stop.served_end_m + self.settings.missed_stop_tolerance_m:
            # halted early inside the window it could still have stopped in: its stopping error shows where
            self.events.record(t, "sumo_forced_halt", tr.train_id, front_m=round(tr.front_m, 3), **detail)
            log.warning("SUMO halted %s at %s from %.2f m/s in one step", tr.train_id, station, railsim_v_mps)
            return
        self.events.record(t, "desync", tr.train_id, edge=tr.sumo_edge, **detail)
        log.error("desync at t=%.1f s: SUMO set %s from %.3f to %.3f m/s", t, tr.train_id, railsim_v_mps, sumo_v_mps)
        if self.failure is None:
            self.failure = (
                f"SUMO stopped {tr.train_id} harder than its emergency brake can at t={t:.1f} s "
                f"({railsim_v_mps:.2f} -> {sumo_v_mps:.2f} m/s in one step, next stop {station}: an overrun SUMO hid; "
                "see the desync events)"
            )
