"""The recorder: ground-truth traces, trip/stop/formation statistics and the run summary.

It only *observes* the simulation (DESIGN.md §5). Gaps, collisions and coupling quality are measured on truth;
what a train believed (message age) is recorded next to it so a user can see a follower acting on stale data.

Files written by :meth:`Recorder.write` (atomically, see :mod:`railsim.record.output`):

``trips.csv``       one row per trip: planned/actual departure and arrival, travel time, delay at arrival
                    (actual − planned free-run time), traction energy [kWh], minimum true gap [m], time coupled,
                    max jerk, stops served/scheduled, controller fallbacks, final status
``stops.csv``       one row per trip and stop: planned/actual arrival, departure, dwell, stopping error [m]
                    (front − stopping mark at the halt), missed flag
``formations.csv``  one row per formation: coupling requests/successes/failures, time to couple, time coupled,
                    gap-error and speed-error percentiles while coupled
``events.csv``      the event log (exact times)
``trace.csv``       per-train samples every ``trace_stride_s``: chainage, speed, applied/commanded acceleration,
                    winning controller role, true gap, formation state, and the coupled controller's solve time
                    and objective (when it reports them: ``Command.info["solve_time_s"]``, ``info["J"]``)
``summary.json``    totals (see :meth:`summary`)
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np

from railsim.record import output

TRIP_COLUMNS = ["trip_id", "service", "vehicle", "origin", "destination", "planned_departure_s", "departure_s",
                "planned_arrival_s", "arrival_s", "travel_time_s", "delay_s", "energy_kwh", "min_gap_m",
                "time_coupled_s", "max_jerk_mps3", "stops_served", "stops_scheduled", "fallbacks",
                "max_message_age_s", "status"]
STOP_COLUMNS = ["trip_id", "service", "station", "planned_arrival_s", "arrival_s", "departure_s", "dwell_s",
                "stopping_error_m", "missed"]
FORMATION_COLUMNS = ["formation", "leader", "follower", "couple_requests", "couple_successes", "couple_failures",
                     "time_to_couple_s", "time_coupled_s", "gap_error_p50_m", "gap_error_p95_m", "gap_error_max_m",
                     "speed_error_p50_mps", "speed_error_p95_mps", "min_gap_m", "final_state"]
TRACE_COLUMNS = ["t_s", "train", "service", "chainage_m", "speed_mps", "applied_accel_mps2", "command_mps2", "role",
                 "gap_m", "formation_state", "solve_time_s", "objective"]
EVENT_COLUMNS = ["t_s", "kind", "subject", "detail"]


def _pct(values: list[float], q: float) -> float | None:
    return float(np.percentile(np.asarray(values), q)) if values else None


class Recorder:
    """Collects during the run; writes at the end."""

    def __init__(self, sim: Any, stride_s: float) -> None:
        self.sim = sim
        self.stride_s = max(float(stride_s), sim.dt)
        self._next_trace_s = 0.0
        self.trace: list[dict[str, Any]] = []
        self.stops: list[dict[str, Any]] = []
        self.gap_err: dict[str, list[float]] = {}
        self.speed_err: dict[str, list[float]] = {}
        self.min_gap_pair: dict[str, float] = {}

    # ------------------------------------------------------------------ during the run
    def step(self, t: float, active: list[Any], ahead: dict[str, Any],
             reports: dict[str, tuple[Any, ...]] | None = None) -> None:
        """One step: coupled-gap statistics every step; a trace sample every ``stride_s`` of the state *at* t
        (``reports``: route, chainage, speed, applied acceleration, time — taken before the plant step) and the
        command decided at t."""
        sim = self.sim
        for fid, f in ((f.id, f) for f in sim.formation_of_follower.values()):
            if sim.formations.state(fid) != "coupled":
                continue
            fol = sim._trip_ref(f.follower, "formations")
            lead = sim._trip_ref(f.leader, "formations")
            a = ahead.get(fol.train_id)
            if a is None or a.train_id != lead.train_id:
                continue
            self.gap_err.setdefault(fid, []).append(abs(a.gap_m - sim._effective_target(fol, f)))
            self.speed_err.setdefault(fid, []).append(abs(fol.plant.speed_mps - lead.plant.speed_mps))
            self.min_gap_pair[fid] = min(self.min_gap_pair.get(fid, math.inf), a.gap_m)
        if t + 1e-9 < self._next_trace_s:
            return
        self._next_trace_s = t + self.stride_s
        for tr in active:
            f = sim.formation_of_follower.get(tr.train_id)
            rep = reports.get(tr.train_id) if reports else None
            speed, accel = (rep[2], rep[3]) if rep is not None else (tr.plant.speed_mps, tr.plant.applied_accel_mps2)
            self.trace.append({
                "t_s": t, "train": tr.train_id, "service": tr.trip.service_id, "chainage_m": tr.front_m,
                "speed_mps": speed, "applied_accel_mps2": accel,
                "command_mps2": tr.last_cmd_mps2, "role": tr.last_role,
                "gap_m": tr.last_gap_m if math.isfinite(tr.last_gap_m) else None,
                "formation_state": str(sim.formations.state(f.id)) if f is not None else "",
                "solve_time_s": tr.vc_solve_s, "objective": tr.vc_objective,
            })

    def stop_record(self, tr: Any, stop: Any, arrival_s: float | None, departure_s: float | None,
                    error_m: float | None, missed: bool = False) -> None:
        planned = tr.trip.planned_arrival_s.get(stop.station_id)
        self.stops.append({
            "trip_id": tr.train_id, "service": tr.trip.service_id, "station": stop.station_id,
            "planned_arrival_s": planned, "arrival_s": arrival_s, "departure_s": departure_s,
            "dwell_s": (departure_s - arrival_s) if (arrival_s is not None and departure_s is not None) else None,
            "stopping_error_m": error_m, "missed": missed,
        })

    # ------------------------------------------------------------------ tables
    def trip_rows(self) -> list[dict[str, Any]]:
        rows = []
        for tr in self.sim.trains.values():
            trip = tr.trip
            dest = trip.destination.station_id
            planned_arr = trip.planned_arrival_s.get(dest)
            travel = (tr.arrived_s - tr.departed_s) if (tr.arrived_s is not None and tr.departed_s is not None) \
                else None
            rows.append({
                "trip_id": tr.train_id, "service": trip.service_id, "vehicle": trip.vehicle_name,
                "origin": trip.origin.station_id, "destination": dest,
                "planned_departure_s": trip.depart_s, "departure_s": tr.departed_s,
                "planned_arrival_s": planned_arr, "arrival_s": tr.arrived_s, "travel_time_s": travel,
                "delay_s": (tr.arrived_s - planned_arr) if (tr.arrived_s is not None and planned_arr is not None)
                else None,
                "energy_kwh": tr.energy_j / 3.6e6, "min_gap_m": tr.min_gap_m if math.isfinite(tr.min_gap_m) else None,
                "time_coupled_s": tr.coupled_s, "max_jerk_mps3": tr.max_jerk_mps3,
                "stops_served": tr.stops_served, "stops_scheduled": len(trip.stops) - 1, "fallbacks": tr.fallbacks,
                "max_message_age_s": tr.stale_max_s, "status": tr.status,
            })
        return rows

    def formation_rows(self) -> list[dict[str, Any]]:
        sim = self.sim
        rows = []
        for f in sim.formation_of_follower.values():  # the scenario's, then any formed at run time (junction)
            st = sim.formations.stats(f.id)
            fol = sim._trip_ref(f.follower, "formations")
            lead = sim._trip_ref(f.leader, "formations")
            ge = self.gap_err.get(f.id, [])
            se = self.speed_err.get(f.id, [])
            rows.append({
                "formation": f.id, "leader": lead.train_id, "follower": fol.train_id,
                "couple_requests": st.couple_requests, "couple_successes": st.successes,
                "couple_failures": st.failures + st.aborts,
                "time_to_couple_s": st.time_to_couple_s[0] if st.time_to_couple_s else None,
                "time_coupled_s": st.coupled_time_s,
                "gap_error_p50_m": _pct(ge, 50), "gap_error_p95_m": _pct(ge, 95),
                "gap_error_max_m": max(ge) if ge else None,
                "speed_error_p50_mps": _pct(se, 50), "speed_error_p95_mps": _pct(se, 95),
                "min_gap_m": self.min_gap_pair.get(f.id), "final_state": sim.formations.state(f.id),
            })
        return rows

    def event_rows(self) -> list[dict[str, Any]]:
        return [{"t_s": r["t_s"], "kind": r["kind"], "subject": r["subject"], "detail": r.get("detail", "")}
                for r in self.sim.events.rows()]

    # ------------------------------------------------------------------ summary
    def summary(self) -> dict[str, Any]:
        sim = self.sim
        trains = list(sim.trains.values())
        min_gaps = [tr.min_gap_m for tr in trains if math.isfinite(tr.min_gap_m)]
        running_times: dict[str, list[float]] = {}
        for tr in trains:
            if tr.arrived_s is not None and tr.departed_s is not None:
                running_times.setdefault(tr.trip.service_id, []).append(tr.arrived_s - tr.departed_s)
        comm = {}
        for name, ch in sim.channels.items():
            comm[name] = dataclasses.asdict(ch.stats())
        formations = self.formation_rows()
        return {
            "scenario": sim.scenario.name,
            "seed": sim.seed,
            "n_trains": len(trains),
            "n_inserted": sum(1 for tr in trains if tr.inserted_s is not None),
            "n_arrived": sum(1 for tr in trains if tr.arrived_s is not None),
            "n_stops_served": sum(tr.stops_served for tr in trains),
            "n_stops_scheduled": sum(len(tr.trip.stops) - 1 for tr in trains),
            "n_stops_missed": sum(1 for s in self.stops if s["missed"]),
            "collisions": len(sim.collisions),
            "sumo_collisions": len(sim.sumo_collisions),
            "switch_violations": sum(len(tr.violations) for tr in trains),
            "min_gap_m": min(min_gaps) if min_gaps else None,
            "fallbacks": sum(tr.fallbacks for tr in trains),
            "max_stopping_error_m": max((abs(s["stopping_error_m"]) for s in self.stops
                                         if s["stopping_error_m"] is not None), default=None),
            "mean_running_time_s": {k: float(np.mean(v)) for k, v in sorted(running_times.items())},
            "formations": {r["formation"]: {k: r[k] for k in ("final_state", "couple_successes", "time_to_couple_s",
                                                               "gap_error_p95_m", "min_gap_m")} for r in formations},
            "comm": comm,
            "sim_s": getattr(sim, "end_s", 0.0),
            "wall_s": sim.wall_s,
            "steps": sim.steps,
            "step_s": sim.dt,
            **({"junction": sim.junction.summary()} if getattr(sim, "junction", None) is not None else {}),
        }

    # ------------------------------------------------------------------ files
    def write(self, out_dir: Path) -> dict[str, Path]:
        out_dir = Path(out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        formats = tuple(self.sim.scenario.outputs.formats) or ("csv",)
        files: dict[str, Path] = {}
        for stem, rows, cols in (("trips", self.trip_rows(), TRIP_COLUMNS), ("stops", self.stops, STOP_COLUMNS),
                                 ("formations", self.formation_rows(), FORMATION_COLUMNS),
                                 ("events", self.event_rows(), EVENT_COLUMNS), ("trace", self.trace, TRACE_COLUMNS)):
            for p in output.write_table(out_dir, stem, rows, cols, formats):
                files[p.name] = p
        summary = self.summary()
        output.write_json(out_dir / "summary.json", summary)
        files["summary.json"] = out_dir / "summary.json"
        output.write_yaml(out_dir / "scenario.resolved.yaml", self.sim.scenario.raw)
        files["scenario.resolved.yaml"] = out_dir / "scenario.resolved.yaml"
        from railsim import __version__
        from railsim.engine.sumo import version as sumo_version

        output.write_json(out_dir / "versions.json", {"railsim": __version__, "sumo": sumo_version(),
                                                      "numpy": np.__version__})
        return files
