"""One simulation: the step loop that owns time and the order of the phases (docs/architecture.md).

Per step ``k`` at time ``t_k``::

    layer.advance_to(t_k)        departures due, message deliveries, switch throws, formation commands
    truth   = sumo.read()        odometer → route chainage and edge of every train (ground truth), desync and
                                 imposed-speed checks, in one compiled pass (railsim.engine.truth)
    safety                       occupancy → train ahead; collisions on truth; SUMO's own; stall watchdog
    extensions.before_bookkeeping   e.g. the junction planner plans, re-plans and hands over
    bookkeeping per train        stops (halt, registration, dwell, arrival), formations, route locks
    extensions.before_comms      e.g. Paper C's cooperative graph
    comms                        every train reports to the ground (t2g); leaders to followers (t2t)
    control                      every train's situation at t; roles; line trains in one compiled call, the
                                 others' roles one by one → arbitration → plant → speed for SUMO
    sumo.set_speeds; record; trains that arrived leave SUMO; sumo.step()

The loop only orders phases; each concern is a port with a narrow interface, built in :meth:`Simulation.__init__`:
``Fleet`` (trips), ``FormationBook``, ``RouteLocks``, ``StopBook``, ``Dispatcher``, ``Knowledge`` (comms),
``SafetyMonitor``, ``StallWatch``, ``ControlStage`` and ``RecordingPort`` (one module each in this package).
Paper-specific behaviour plugs in as extensions chosen by the scenario (:mod:`railsim.engine.extensions`).
"""

from __future__ import annotations

import logging
import sys
import time as _time
from pathlib import Path
from typing import Any

import numpy as np
from mypy_extensions import mypyc_attr

from railsim.engine import primary_delays, timed
from railsim.engine.control import ControlStage
from railsim.engine.coupling import FormationBook
from railsim.engine.depot import Depots
from railsim.engine.disturbances import Disturbances
from railsim.engine.events import EventLayer, FormationManager, Interlocking, Switch
from railsim.engine.extensions import ExtensionContext, ExtensionSet
from railsim.engine.extensions.registry import install_all
from railsim.engine.fleet import Fleet
from railsim.engine.heap import setup_frozen
from railsim.engine.insertion import Dispatcher
from railsim.engine.interrupt import StopRequest
from railsim.engine.knowledge import Knowledge, comm_channels
from railsim.engine.locking import RouteLocks
from railsim.engine.occupancy import Ahead, Occupancy
from railsim.engine.progress import RunProgress
from railsim.engine.recording import RecordingPort
from railsim.engine.safety import SafetyMonitor
from railsim.engine.settings import PERMISSIVE_DECEL_MPS2, PERMISSIVE_SPEED_FACTOR, PERMISSIVE_TAU_S, EngineSettings
from railsim.engine.slots import SlotStore
from railsim.engine.stops import StopBook
from railsim.engine.train import TrainRuntime
from railsim.engine.truth import TruthPass
from railsim.engine.turnback import Turnbacks
from railsim.engine.watchdog import StallWatch
from railsim.errors import SimulationError
from railsim.record.recorder import Recorder
from railsim.record.snapshot import RunSnapshot

__all__ = ["EngineSettings", "Simulation", "TrainRuntime", "run"]
log = logging.getLogger(__name__)


@mypyc_attr(allow_interpreted_subclasses=True)  # benchmarks and tests time its steps in a subclass
class Simulation:
    """Builds the world, the trains and the ports for a scenario, and runs the step loop. Use :func:`run`."""

    def __init__(
        self,
        scenario: Any,
        out_dir: Path | None,
        seed: int | None = None,
        progress: bool | None = None,
        settings: EngineSettings | None = None,
        stop: StopRequest | None = None,
        gui: bool = False,
    ) -> None:
        from network.world import load_world, sumo_args
        from railsim import scenario as scn_mod

        self.scenario = scenario
        self.out_dir = Path(out_dir) if out_dir is not None else None
        sim = scenario.simulation
        self.seed = int(sim.seed if seed is None else seed)
        self.dt = float(sim.step_s)
        self.duration_s = float(sim.duration_s)
        self.step_method = sim.step_method
        self.settings = (settings or EngineSettings()).with_interlocking(scenario.interlocking)
        self.progress = sys.stderr.isatty() if progress is None else progress
        self.stop, self.gui = stop or StopRequest(), gui  # a signal noted ends the run between steps; sumo-gui
        self.interrupted_by: str | None = None  # the signal that ended the step loop ("SIGINT"), once it has
        self.rng = np.random.default_rng(self.seed)

        self.bundle = load_world(scenario.world, scenario.source)  # a shipped/line world is built, a net is read
        self.sumo_extra_args = sumo_args(self.bundle)  # () for generated worlds
        scn_mod.check_against_world(
            scenario, self.bundle.stations.keys(), self.bundle.switches.keys(), self.bundle.station_aliases
        )
        if self.bundle.station_aliases:  # an external net: stations named by name or stop id -> station ids
            scenario = self.scenario = scn_mod.with_station_ids(scenario, self.bundle)

        # ---- event layer: clock, log, formation state machine, interlocking, radio channels
        self.layer = EventLayer(t0_s=0.0, rng=np.random.default_rng(self.rng.integers(2**63)))
        self.events = self.layer.log
        self.interlocking = Interlocking(self.layer)
        for sw in self.bundle.switches.values():
            self.interlocking.add_switch(Switch(sw.id, throw_time_s=float(sw.throw_time_s)))
        self.channels = comm_channels(self.layer, scenario)
        disturbances = Disturbances.from_faults(scenario.faults, self.rng)  # its two streams, in this order

        # ---- the ports, given their collaborators when built, in dependency order. True cycles are closed once:
        # FormationBook.wire, the ExtensionSet install() fills; the SUMO bridge is connected in run().
        self.extensions = ExtensionSet()
        self.fleet = Fleet(scenario.source)
        self.fleet.build(scenario, self.bundle, self.dt, self.step_method)
        self.trains = self.fleet.trains
        self.primary = primary_delays.draw(scenario, self.fleet, self.seed, self.dt, self.bundle.station_aliases)
        # rotations: trips chained into units, each next trip given its turnback (before any port reads routes)
        self.turnbacks = Turnbacks(self.fleet, self.bundle.graph, scenario.rotations, self.events, scenario.source)
        # depot runs: each unit's day starts with a run out of a depot and ends with one into a depot
        self.depots = Depots(self.fleet, self.turnbacks, self.bundle, scenario, self.dt, self.step_method)
        self.formations = FormationBook(
            self.fleet, FormationManager(self.layer), self.settings, self.dt, self.turnbacks.chained, self.extensions
        )
        for k, f in enumerate(scenario.formations):
            self.formations.add(f, f"formations[{k}]")
        self.formations.across_turnbacks(self.turnbacks)
        self.locks = RouteLocks(
            self.fleet, self.interlocking, self.formations, self.events, self.settings, self.extensions, self.layer
        )
        self.locks.protect_merges(self.bundle.graph)
        self.recorder = Recorder(stride_s=float(scenario.outputs.trace_stride_s), dt_s=self.dt)
        pax = primary_delays.passenger_demand(self.primary)
        euler_dt_s = self.dt if self.step_method == "euler" else 0.0  # how SUMO moves trains (surely_overruns_m)
        self.stops = StopBook(
            self.formations, self.locks, self.events, self.settings, self.recorder.stop_record, pax, euler_dt_s
        )
        self.knowledge = Knowledge(self.layer, self.channels, self.formations, self.extensions)
        self.dispatcher = Dispatcher(
            self.fleet,
            self.layer,
            self.events,
            self.settings,
            self.formations,
            self.knowledge.handshake,
            self.locks.release_all,
            self.turnbacks.chained,
            (self.locks.admit,),
            self.extensions,
        )
        self.formations.wire(self.dispatcher, self.stops)
        primary_delays.apply(self.primary, self.fleet, self.formations.couples_on_departure)
        self.locks.set_up_shared_track(self.bundle.graph, self.turnbacks.next_of.get)
        self.safety = SafetyMonitor(self.trains, self.layer, self.events, self.settings)
        self.safety.set_up_crossings(self.bundle.graph)
        self.control = ControlStage(
            self.trains,
            self.formations,
            self.knowledge,
            self.safety,
            self.locks,
            self.stops,
            self.events,
            self.settings,
            self.dt,
            self.step_method,
            disturbances,
            self.extensions,
        )
        self.watchdog = StallWatch(
            self.events, self.settings, self.locks, self.control.berths, self.knowledge.radio_out
        )
        self.recording = RecordingPort(self.recorder, self.formations)
        self.occupancy = Occupancy()
        self.occupancy.set_bidi(self.bundle.graph)
        self.slots = SlotStore(self.occupancy)  # per-train state resident in arrays (railsim.engine.slots)
        self.truth = TruthPass(self.occupancy, self.safety, self.settings.desync_tolerance_m, self.dt, self.slots)
        self.dispatcher.schedule_departures()
        ports = timed.TimedPorts(self.layer, self.events, self.fleet, self.formations, self.dispatcher, self.safety)
        timed.schedule(ports, scenario)
        ctx = ExtensionContext(
            scenario=scenario,
            trains=self.trains,
            formations=self.formations,
            knowledge=self.knowledge,
            events=self.events,
            interlocking=self.interlocking,
            channels=self.channels,
            settings=self.settings,
            actuator_bias=disturbances.biased,
            switch_throw_s={sid: float(sw.throw_time_s) for sid, sw in self.bundle.switches.items()},
            dt_s=self.dt,
            step_method=self.step_method,
            draw_seed=lambda: int(self.rng.integers(2**63)),
        )
        self.extensions.install(install_all(ctx))
        self.steps = 0
        self.wall_s = 0.0
        self.end_s = 0.0
        self.bridge: Any = None

    # ------------------------------------------------------------------ main loop
    def run(self) -> dict[str, Any]:
        """Run until every trip has finished or the horizon; return the summary."""
        from railsim.engine.sumo import SumoBridge

        t_wall = _time.perf_counter()
        bar = RunProgress(self.scenario.name, len(self.trains), self.duration_s, self.progress)
        with SumoBridge(self._sumo_config()) as bridge, setup_frozen():  # (railsim.engine.heap)
            self.bridge = bridge
            self.dispatcher.connect(bridge)
            self.turnbacks.connect(bridge)
            self.stops.connect(bridge.drop_stop)
            t = bridge.time_s
            log.info("simulating %s: %d trips, horizon %g s", self.scenario.name, len(self.trains), self.duration_s)
            while t <= self.duration_s + 1e-9 and self.stop.signum is None:
                self._step(t)
                bridge.step()
                self.steps += 1
                t = bridge.time_s
                bar.update(t, n_finished := self.fleet.n_finished())
                if n_finished == len(self.fleet.trains) or self.failure() is not None:  # all done, or a failure
                    break
            self.end_s = t
            # read once: a signal noted after this point (the run already over) stops nothing and is not recorded
            self.interrupted_by = self.stop.reason
            if self.interrupted_by is not None:  # a signal: write what the run has (railsim.engine.interrupt)
                log.warning("%s: stopping at t = %g s; writing what the run has", self.interrupted_by, t)
            else:
                self.dispatcher.report_never_inserted(t)
                self.watchdog.at_end(t)  # a failure (desync, stall) stops the run; outputs written, then exit 3
        bar.close(self.end_s, self.fleet.n_finished())
        self.wall_s = _time.perf_counter() - t_wall
        return self.recorder.summary(self.snapshot())

    def failure(self) -> str | None:
        """Why the run had to stop (a desync, a stall), one line; None while all is well."""
        return self.safety.failure or self.watchdog.failure

    def _sumo_config(self) -> Any:
        from railsim.engine.sumo import SumoConfig, VTypeSpec

        # permissive vTypes: SUMO inserts exactly where and when we say (railsim.engine.settings explains why)
        vtypes = [
            VTypeSpec(
                name,
                v.length_m,
                max(v.max_speed_mps * PERMISSIVE_SPEED_FACTOR, 1.0),
                accel_mps2=1.0,
                decel_mps2=PERMISSIVE_DECEL_MPS2,
                emergency_decel_mps2=PERMISSIVE_DECEL_MPS2,
                tau_s=PERMISSIVE_TAU_S,
                vclass=self.bundle.vclass,
            )
            for name, v in self.scenario.vehicles.items()
        ]
        outs = tuple(self.scenario.outputs.sumo)
        additional = list(self.bundle.additional_files) or [self.bundle.stops_file]  # an external net: the user's
        return SumoConfig(
            net_file=self.bundle.net_file,
            additional_files=additional,
            step_s=self.dt,
            seed=self.seed,
            step_method=self.step_method,
            vtypes=vtypes,
            output_dir=self.out_dir if outs else None,
            sumo_outputs=outs,
            extra_args=self.sumo_extra_args,
            run_dir=self.out_dir,
            gui=self.gui,
        )

    def _step(self, t: float) -> None:
        self.layer.advance_to(t)
        bridge = self.bridge
        present = set(bridge.present_ids())
        on_line = self.fleet.active()  # handed to SUMO: present, or still waiting in its queue (guarded)
        pending = [tr for tr in on_line if tr.status == "inserting" and tr.sumo_id not in present]
        self.dispatcher.guard_pending(pending)  # it may withdraw some: the watchdog sees those still inserting
        self.watchdog.pending(t, [tr for tr in pending if tr.status == "inserting"], self.dispatcher.blocker_at_front)
        active = [tr for tr in on_line if tr.sumo_id in present]
        for tr in active:
            if tr.status == "inserting":
                tr.status = "running"
                tr.departed_s = t
                self.events.record(t, "train_departed", tr.train_id, station=tr.trip.origin.station_id)
        if not active:
            return
        ids = [tr.sumo_id for tr in active]
        # SUMO's truth: chainages, pointers, the desync and imposed-speed checks, the occupancy index placed
        self.truth.read(t, active, bridge.read(ids))
        tids = self.occupancy.ids
        ahead: dict[str, Ahead | None] = dict(zip(tids, self.occupancy.ahead_all(self.settings.lookahead_m)))
        for tr in active:
            self.safety.truth_checks(t, tr, ahead[tr.train_id])
        self.safety.crossing_checks(t, active)
        if self.occupancy.has_bidi:  # trains facing each other on one track (partner edges): contacts, authorities
            self.safety.head_on_checks(t, active, self.occupancy.facing_own_bodies)
            speeds = [tr.plant.speed_mps for tr in active]
            self.locks.facing_m = self.occupancy.facing_within_braking(speeds, self.settings.sensor_range_m)
        self.safety.sumo_reported(t, bridge.collisions())
        self.watchdog.check(t, active, ahead)

        self.extensions.before_bookkeeping(t)
        for tr in active:
            self.stops.bookkeeping(t, tr)
            self.formations.bookkeeping(t, tr, ahead[tr.train_id])
            self.locks.bookkeeping(t, tr, ahead[tr.train_id])
        self.extensions.before_comms(t, active)
        reports = {tr.train_id: Knowledge.report(t, tr) for tr in active}  # the state at t, before the plant step
        # broadcast the state at t (with the plan decided last step) and deliver what is due now: a zero-delay
        # channel gives the neighbours' state at t in the same step (the papers' "perfect communication")
        self.knowledge.communicate(active, reports)
        self.layer.advance_to(t)
        rears = self.knowledge.ground_rears(t, tids, self.occupancy.reported_rears)  # of the trains ahead
        speeds = self.control.control_all(t, active, ahead, rears)
        bridge.set_speeds(ids, speeds)
        self.slots.sent(speeds)  # what SUMO was handed, for the next check of the speeds it applied
        self.recording.step(t, active, ahead, reports)
        for tr in active:  # trains that finished this step leave SUMO now, or their unit runs its next trip
            if tr.status == "arrived":
                succ = self.turnbacks.handover(t, tr)
                self.locks.hand_over(t, tr, succ)  # the sections it stands in pass to its unit's next trip
                if succ is None:  # no next trip for its unit
                    bridge.remove(tr.sumo_id)
                self.formations.on_off_line(t, tr)

    # ------------------------------------------------------------------ results
    def snapshot(self) -> RunSnapshot:
        """The run as plain data for the recorder."""
        from railsim import __version__
        from railsim.engine.sumo import version as sumo_version

        extra: dict[str, Any] = self.extensions.summaries()
        if self.turnbacks.units:
            extra["fleet"] = self.turnbacks.summary()
            if self.depots.runs or self.depots.unreached:
                extra["fleet"].update(self.depots.summary())
        extra.update(primary_delays.summary(self.primary))
        extra.update(self.formations.why_not_coupled(self.end_s))  # never a silent drop; may log events
        return RunSnapshot(
            scenario_name=self.scenario.name,
            seed=self.seed,
            trains=list(self.trains.values()),
            formations=self.recording.formation_outcomes(),
            events=list(self.events.rows()),
            channel_stats={name: ch.stats() for name, ch in self.channels.items()},
            collisions=len(self.safety.collisions),
            sumo_collisions=len(self.safety.sumo_collisions),
            sim_s=self.end_s,
            wall_s=self.wall_s,
            steps=self.steps,
            step_s=self.dt,
            formats=tuple(self.scenario.outputs.formats),
            resolved_scenario=self.scenario.raw,
            versions={"railsim": __version__, "sumo": sumo_version(), "numpy": np.__version__},
            extra_summary=extra,
            failure=self.failure(),
            extra_tables=primary_delays.tables(self.primary, self.recorder.stops, self.trains),
            interrupted_by=self.interrupted_by,
        )

    def write(self, out_dir: Path) -> dict[str, Path]:
        return self.recorder.write(out_dir, self.snapshot())


def run(
    scenario: Any,
    out_dir: Path | str | None,
    seed: int | None = None,
    progress: bool | None = None,
    settings: EngineSettings | None = None,
    stop: StopRequest | None = None,
    gui: bool = False,
) -> dict[str, Any]:
    """Run ``scenario`` (a :class:`railsim.scenario.Scenario`) and write its outputs to ``out_dir``.

    Returns the summary dictionary (also written as ``summary.json``). :func:`railsim.api.run` adds the paper
    families' analyses of the files written; use that one unless you want the bare engine. ``stop``: a signal
    noted on it ends the run between two steps (:mod:`railsim.engine.interrupt`); ``gui``: sumo-gui via traci.
    """
    out = Path(out_dir) if out_dir is not None else None
    sim = Simulation(scenario, out, seed=seed, progress=progress, settings=settings, stop=stop, gui=gui)
    summary = sim.run()
    if sim.out_dir is not None:
        sim.write(sim.out_dir)
    if sim.failure() is not None:  # the outputs are on disk; the run still failed
        raise SimulationError(sim.failure())
    return summary
