"""The recorder: ground-truth traces, trip/stop/formation statistics and the run summary.

It only *observes* the simulation: the engine feeds it samples during the run (:meth:`Recorder.coupled_sample`,
:meth:`Recorder.trace_row`, :meth:`Recorder.stop_record`) and a :class:`RunSnapshot` at the end; it never sees
the engine (docs/architecture.md, "Layers"). Gaps, collisions and coupling quality are measured on truth;
what a train believed (message age) is recorded next to it so a user can see a follower acting on stale data.

Files written by :meth:`Recorder.write` (atomically, see :mod:`railsim.record.output`):

``trips.csv``       one row per trip: planned/actual departure and arrival, travel time, delay at arrival
                    (actual − planned free-run time), traction energy [kWh], minimum true gap [m], time coupled,
                    max jerk, stops served/scheduled, controller fallbacks, final status (``arrived``;
                    ``running``/``inserting``/``scheduled`` when the run ended first; ``removed`` when it left
                    the line by a ``leave`` event)
``stops.csv``       one row per trip and stop: planned/actual arrival, departure, dwell, stopping error [m]
                    (front − stopping mark at the halt), missed flag
``formations.csv``  one row per formation: coupling requests/successes/failures, time to couple, time coupled,
                    gap-error and speed-error percentiles while coupled
``events.csv``      the event log (exact times)
``trace.csv``       per-train samples every ``trace_stride_s``: chainage, speed, applied/commanded acceleration,
                    winning controller role, true gap, formation state, and the coupled controller's solve time
                    and objective (when it reports them: ``Command.info["solve_time_s"]``, ``info["J"]``)
``summary.json``    totals (see :meth:`summary`); ``status`` is ``completed``, ``failed`` (a desync, a stall:
                    ``failure`` says why) or ``interrupted`` (SIGINT/SIGTERM: ``interrupted_by``; every table
                    holds what happened up to ``sim_s``)
``delays.csv``      with ``disturbances:`` only (``RunSnapshot.extra_tables``): one row per trip and stop, arrival
                    delay split into primary (injected) and secondary (knock-on) (railsim.engine.primary_delays)
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np

from railsim.record import output
from railsim.record.snapshot import OUTPUT_FILES, RunSnapshot

TRIP_COLUMNS = [
    "trip_id",
    "service",
    "vehicle",
    "origin",
    "destination",
    "planned_departure_s",
    "departure_s",
    "planned_arrival_s",
    "arrival_s",
    "travel_time_s",
    "delay_s",
    "energy_kwh",
    "min_gap_m",
    "time_coupled_s",
    "max_jerk_mps3",
    "stops_served",
    "stops_scheduled",
    "fallbacks",
    "max_message_age_s",
    "status",
]
STOP_COLUMNS = [
    "trip_id",
    "service",
    "station",
    "planned_arrival_s",
    "arrival_s",
    "departure_s",
    "dwell_s",
    "stopping_error_m",
    "missed",
]
FORMATION_COLUMNS = [
    "formation",
    "leader",
    "follower",
    "couple_requests",
    "couple_successes",
    "couple_failures",
    "time_to_couple_s",
    "time_coupled_s",
    "gap_error_p50_m",
    "gap_error_p95_m",
    "gap_error_max_m",
    "speed_error_p50_mps",
    "speed_error_p95_mps",
    "min_gap_m",
    "final_state",
]
TRACE_COLUMNS = [
    "t_s",
    "train",
    "service",
    "chainage_m",
    "speed_mps",
    "applied_accel_mps2",
    "command_mps2",
    "role",
    "gap_m",
    "formation_state",
    "solve_time_s",
    "objective",
]
EVENT_COLUMNS = ["t_s", "kind", "subject", "detail"]


def _pct(values: list[float], q: float) -> float | None:
    return float(np.percentile(np.asarray(values), q)) if values else None


class Recorder:
    """Collects during the run; writes at the end."""

    def __init__(self, stride_s: float, dt_s: float) -> None:
        self.stride_s = max(float(stride_s), dt_s)
        self._next_trace_s = 0.0
        self.trace: list[dict[str, Any]] = []
        self.stops: list[dict[str, Any]] = []
        self.gap_err: dict[str, list[float]] = {}
        self.speed_err: dict[str, list[float]] = {}
        self.min_gap_pair: dict[str, float] = {}

    # ------------------------------------------------------------------ during the run
    def coupled_sample(self, formation_id: str, gap_error_m: float, speed_error_mps: float, gap_m: float) -> None:
        """One step of a coupled formation: gap error against the effective target, speed error, true gap."""
        self.gap_err.setdefault(formation_id, []).append(gap_error_m)
        self.speed_err.setdefault(formation_id, []).append(speed_error_mps)
        self.min_gap_pair[formation_id] = min(self.min_gap_pair.get(formation_id, math.inf), gap_m)

    def trace_due(self, t: float) -> bool:
        """True once every ``stride_s``: the caller then adds one :meth:`trace_row` per train on the line."""
        if t + 1e-9 < self._next_trace_s:
            return False
        self._next_trace_s = t + self.stride_s
        return True

    def trace_row(self, row: dict[str, Any]) -> None:
        """One sample (the columns of :data:`TRACE_COLUMNS`)."""
        self.trace.append(row)

    def stop_record(
        self,
        trip_id: str,
        service: str,
        station: str,
        planned_arrival_s: float | None,
        arrival_s: float | None,
        departure_s: float | None,
        error_m: float | None,
        missed: bool = False,
    ) -> None:
        self.stops.append(
            {
                "trip_id": trip_id,
                "service": service,
                "station": station,
                "planned_arrival_s": planned_arrival_s,
                "arrival_s": arrival_s,
                "departure_s": departure_s,
                "dwell_s": (departure_s - arrival_s) if (arrival_s is not None and departure_s is not None) else None,
                "stopping_error_m": error_m,
                "missed": missed,
            }
        )

    # ------------------------------------------------------------------ tables
    @staticmethod
    def trip_rows(run: RunSnapshot) -> list[dict[str, Any]]:
        rows = []
        for tr in run.trains:
            trip = tr.trip
            dest = trip.destination.station_id
            planned_arr = trip.planned_arrival_s.get(dest)
            travel = (
                (tr.arrived_s - tr.departed_s) if (tr.arrived_s is not None and tr.departed_s is not None) else None
            )
            rows.append(
                {
                    "trip_id": tr.train_id,
                    "service": trip.service_id,
                    "vehicle": trip.vehicle_name,
                    "origin": trip.origin.station_id,
                    "destination": dest,
                    "planned_departure_s": trip.depart_s,
                    "departure_s": tr.departed_s,
                    "planned_arrival_s": planned_arr,
                    "arrival_s": tr.arrived_s,
                    "travel_time_s": travel,
                    "delay_s": (tr.arrived_s - planned_arr)
                    if (tr.arrived_s is not None and planned_arr is not None)
                    else None,
                    "energy_kwh": tr.energy_j / 3.6e6,
                    "min_gap_m": tr.min_gap_m if math.isfinite(tr.min_gap_m) else None,
                    "time_coupled_s": tr.coupled_s,
                    "max_jerk_mps3": tr.max_jerk_mps3,
                    "stops_served": tr.stops_served,
                    "stops_scheduled": trip.n_stops_scheduled,
                    "fallbacks": tr.fallbacks,
                    "max_message_age_s": tr.stale_max_s,
                    "status": tr.status,
                }
            )
        return rows

    def formation_rows(self, run: RunSnapshot) -> list[dict[str, Any]]:
        rows = []
        for f in run.formations:  # the scenario's, then any formed at run time (junction)
            st = f.stats
            ge = self.gap_err.get(f.id, [])
            se = self.speed_err.get(f.id, [])
            rows.append(
                {
                    "formation": f.id,
                    "leader": f.leader_id,
                    "follower": f.follower_id,
                    "couple_requests": st.couple_requests,
                    "couple_successes": st.successes,
                    "couple_failures": st.failures + st.aborts,
                    "time_to_couple_s": st.time_to_couple_s[0] if st.time_to_couple_s else None,
                    "time_coupled_s": st.coupled_time_s,
                    "gap_error_p50_m": _pct(ge, 50),
                    "gap_error_p95_m": _pct(ge, 95),
                    "gap_error_max_m": max(ge) if ge else None,
                    "speed_error_p50_mps": _pct(se, 50),
                    "speed_error_p95_mps": _pct(se, 95),
                    "min_gap_m": self.min_gap_pair.get(f.id),
                    "final_state": f.state,
                }
            )
        return rows

    @staticmethod
    def event_rows(run: RunSnapshot) -> list[dict[str, Any]]:
        return [
            {"t_s": r["t_s"], "kind": r["kind"], "subject": r["subject"], "detail": r.get("detail", "")}
            for r in run.events
        ]

    # ------------------------------------------------------------------ summary
    def summary(self, run: RunSnapshot) -> dict[str, Any]:
        trains = list(run.trains)
        # service counts leave out a unit's empty depot runs (railsim.engine.depot); safety counts every train
        service = [tr for tr in trains if tr.trip.kind == "service"]
        min_gaps = [tr.min_gap_m for tr in trains if math.isfinite(tr.min_gap_m)]
        running_times: dict[str, list[float]] = {}
        for tr in service:
            if tr.arrived_s is not None and tr.departed_s is not None:
                running_times.setdefault(tr.trip.service_id, []).append(tr.arrived_s - tr.departed_s)
        formations = self.formation_rows(run)
        never_inserted = [tr.train_id for tr in trains if tr.inserted_s is None]
        return {
            "scenario": run.scenario_name,
            "seed": run.seed,
            "status": run.status,
            "interrupted_by": run.interrupted_by,
            "n_trains": len(service),
            "n_inserted": sum(1 for tr in service if tr.inserted_s is not None),
            "n_arrived": sum(1 for tr in service if tr.arrived_s is not None),
            "n_never_inserted": len(never_inserted),
            "never_inserted": never_inserted,
            "n_stops_served": sum(tr.stops_served for tr in service),
            "n_stops_scheduled": sum(tr.trip.n_stops_scheduled for tr in service),
            "n_stops_missed": sum(1 for s in self.stops if s["missed"]),
            # one collision truth: railsim's (on the chainage the desync check keeps equal to SUMO's) and SUMO's
            # own check count together; the detail keeps them apart
            "collisions": run.collisions + run.sumo_collisions,
            "collisions_railsim": run.collisions,
            "sumo_collisions": run.sumo_collisions,
            "switch_violations": sum(len(tr.violations) for tr in trains),
            "min_gap_m": min(min_gaps) if min_gaps else None,
            "fallbacks": sum(tr.fallbacks for tr in trains),
            "max_stopping_error_m": max(
                (abs(s["stopping_error_m"]) for s in self.stops if s["stopping_error_m"] is not None), default=None
            ),
            "mean_running_time_s": {k: float(np.mean(v)) for k, v in sorted(running_times.items())},
            "formations": {
                r["formation"]: {
                    k: r[k]
                    for k in ("final_state", "couple_successes", "time_to_couple_s", "gap_error_p95_m", "min_gap_m")
                }
                for r in formations
            },
            "comm": {name: dataclasses.asdict(stats) for name, stats in run.channel_stats.items()},
            "sim_s": run.sim_s,
            "wall_s": run.wall_s,
            "steps": run.steps,
            "step_s": run.step_s,
            "failure": run.failure,
            **run.extra_summary,
        }

    # ------------------------------------------------------------------ files
    def write(self, out_dir: Path, run: RunSnapshot) -> dict[str, Path]:
        """Write every file of :data:`railsim.record.snapshot.OUTPUT_FILES` (tables in the run's formats)."""
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        formats = tuple(run.formats) or ("csv",)
        files: dict[str, Path] = {}
        tables = {
            "trips": (self.trip_rows(run), TRIP_COLUMNS),
            "stops": (self.stops, STOP_COLUMNS),
            "formations": (self.formation_rows(run), FORMATION_COLUMNS),
            "events": (self.event_rows(run), EVENT_COLUMNS),
            "trace": (self.trace, TRACE_COLUMNS),
        }
        for spec in OUTPUT_FILES:
            if spec.kind == "sumo":  # the SUMO bridge writes these
                continue
            if spec.kind == "table":
                rows, cols = tables[spec.stem]
                for p in output.write_table(out_dir, spec.stem, rows, cols, formats):
                    files[p.name] = p
            elif spec.stem == "summary":
                output.write_json(out_dir / spec.file_name, self.summary(run))
            elif spec.stem == "scenario.resolved":
                output.write_yaml(out_dir / spec.file_name, run.resolved_scenario)
            elif spec.stem == "versions":
                output.write_json(out_dir / spec.file_name, dict(run.versions))
            if spec.kind != "table":
                files[spec.file_name] = out_dir / spec.file_name
        for stem, (rows, cols) in sorted(run.extra_tables.items()):  # only the runs that have them
            for p in output.write_table(out_dir, stem, rows, cols, formats):
                files[p.name] = p
        return files
