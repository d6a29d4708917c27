"""Safety on ground truth: collisions between trains and with obstacles, SUMO's own collisions, the sensor.

Collisions are detected on the true positions (the occupancy's gap to the train ahead < 0, or a front past an
obstacle) once per pair and logged as ``collision`` events; SUMO's own collision check runs too and each of its
reports is a ``sumo_collision`` event, kept apart (docs/architecture.md, "Safety is never hidden"). Obstacles
(scenario ``events: obstacle``) are fixed to the track; a train's own ranging sensor (collision avoidance) reads
the nearest train or obstacle ahead within ``sensor_range_m``.
"""

from __future__ import annotations

import logging
from typing import Any

from railsim.engine.events.clock import EventLayer
from railsim.engine.events.log import EventLog
from railsim.engine.occupancy import Ahead
from railsim.engine.settings import INF, EngineSettings
from railsim.engine.train import TrainRuntime

log = logging.getLogger(__name__)


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

    def sumo_reported(self, t: float, reports: list[dict[str, Any]]) -> None:
        """SUMO's own collision reports of this step (kept apart from ours)."""
        for c in reports:
            c["t_s"] = t
            self.sumo_collisions.append(c)
            self.events.record(t, "sumo_collision", str(c["collider"]), victim=str(c["victim"]), type=str(c["type"]))
