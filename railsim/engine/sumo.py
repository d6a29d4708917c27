"""The SUMO bridge: the only module that imports libsumo (and traci, for ``railsim run --gui``).

SUMO is the world: it owns the track geometry, moves the trains by the speeds we give it, keeps station dwell
(``duration``/``until``) once a train halts with its whole length on the platform, writes its own outputs and
runs an independent collision check. Everything else (physics limits, interlocking, virtual coupling) is ours.

What this module does, and why (numbers in ``shared/notes/sumo_rail_findings.md``):

* **Start/close.** One simulation per process (a second ``libsumo.start`` silently restarts the first), so the
  bridge refuses to start twice and always closes. SUMO options: ``--railsignal.default-classes`` naming no
  class our trains have (:func:`rail_signal_classes`: no block-based insertion for them), collision checks on junctions with ``mingap-factor 0``,
  ``--time-to-teleport -1`` (a teleport would hide a deadlock), a seed, and the step method the scenario's
  discrete model needs (Euler: ``x += v_new·dt``; ballistic: ``x += (v_old+v_new)/2·dt``).
* **Insert.** Trains are added at run time with ``depart="now"``, ``departSpeed="0"`` and their station stops;
  controlled trains get ``speedMode 32`` immediately (SUMO then applies ``setSpeed`` exactly and enforces
  nothing — :mod:`railsim.physics.dynamics` does). A train added at step k appears after that step.
* **Read.** Direct getters (subscriptions are slower under libsumo) into numpy arrays. Positions come as the
  odometer ``getDistance`` (route chainage = depart chainage + odometer), never x/y, and never
  ``getDrivingDistance`` (it returns −2^30 for points behind). The edge is asked only where the odometer and the
  lane position cannot vouch for the last one (:class:`EdgeMemory`).
* **Speeds.** Every controlled train's speed is sent at every step: SUMO holds a ``setSpeed`` for later steps
  only while the vehicle has no stop pending, and ours always have one (docs/performance.md, "SUMO's side").
* **Stops on an edge passed twice.** SUMO makes a stop on the first pass of its edge; a stop meant for a later
  pass (``StopSpec.route_index``) waits, with the stops after it, until the train is past the earlier pass
  (:mod:`railsim.engine.stop_passes`), and is then handed over at the step that finds it so.
* **Guard.** ``--end`` is ignored when we drive the loop; the engine guards on simulated time.
* **Run folder.** With ``SumoConfig.run_dir`` the vTypes file is written there (not in a temp dir) and, on
  close, the trains SUMO got and ``.sumocfg`` files that open them (:mod:`railsim.engine.sumo_files`).
* **GUI.** ``SumoConfig.gui`` starts the eclipse-sumo wheel's ``sumo-gui`` through traci (a socket per call:
  slower, for looking) with the same command line; every call below goes to whichever API was started.
"""

from __future__ import annotations

import logging
import os
import tempfile
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

os.environ.setdefault("SUMO_HOME", "")  # silence "SUMO_HOME is not set" (we use the eclipse-sumo wheel)
if not os.environ["SUMO_HOME"]:
    try:  # the eclipse-sumo wheel knows its own home; never assume a system SUMO
        import sumo as _sumo_pkg

        os.environ["SUMO_HOME"] = _sumo_pkg.SUMO_HOME
    except ImportError:  # pragma: no cover - eclipse-sumo is a hard dependency
        del os.environ["SUMO_HOME"]

import libsumo  # noqa: E402  (after SUMO_HOME)

from railsim.engine import stop_passes, sumo_files  # noqa: E402
from railsim.errors import SimulationError  # noqa: E402
from railsim.record.output import write_bytes  # noqa: E402

log = logging.getLogger(__name__)

# The TraCI API the bridge talks to: libsumo in-process (every run), or traci driving a sumo-gui process
# (``railsim run --gui``); both have the same functions and a ``TraCIException``. Set by ``SumoBridge.start``.
_api: Any = libsumo

_STOP_BUS_STOP = 0x08  # trainStops are busStops to SUMO's stop logic


class _RawVehicleCalls:
    """libsumo's per-vehicle getters and ``setSpeed`` as the compiled functions themselves.

    ``libsumo.vehicle.getSpeed(id)`` is a Python function that calls ``_libsumo.vehicle_getSpeed(id)``; the loop
    calls four getters and ``setSpeed`` for every train at every step (``getRoadID`` and ``getLaneID`` where the
    edge may have changed), so the bridge calls the compiled ones directly (``map`` over the ids: no Python frame
    per call). Same functions, same values.
    """

    def __init__(self, raw: Any) -> None:
        self.getDistance = raw.vehicle_getDistance
        self.getSpeed = raw.vehicle_getSpeed
        self.getLanePosition = raw.vehicle_getLanePosition
        self.getRoadID = raw.vehicle_getRoadID
        self.getLaneID = raw.vehicle_getLaneID
        self.getStopState = raw.vehicle_getStopState
        self.setSpeed = raw.vehicle_setSpeed


try:
    _RAW_LIBSUMO: Any = _RawVehicleCalls(libsumo.libsumo._libsumo)
except AttributeError:  # pragma: no cover - a libsumo without the SWIG module layout: its public functions
    _RAW_LIBSUMO = libsumo.vehicle


def _vehicle_calls() -> Any:
    """The per-vehicle calls of the API in use (libsumo's compiled ones, or traci's for the GUI)."""
    return _RAW_LIBSUMO if _api is libsumo else _api.vehicle


_ACTIVE = {"started": False}

EDGE_KEPT_TOL_M = 1e-6  # a lane position that moved on by the odometer's advance (SUMO adds one step to both)
LANE_END_MARGIN_M = 1e-3  # ... and stays this far short of its lane's end: the train is still on that lane
# Below this many trains the bridge asks every train's edge: the memory's array work (some tens of µs a step in
# the loop) costs more than the getters it saves (0.2-0.5 µs a train): SumoBridge.read with the memory ran at
# 0.83x the speed of asking every edge with 100 trains, 1.10x with 300, 1.33x with 1,000 (docs/performance.md).
EDGE_MEMORY_MIN_TRAINS = 200


def edge_kept(
    odometer_m: np.ndarray,
    lane_pos_m: np.ndarray,
    lane_length_m: np.ndarray,
    odometer_now_m: np.ndarray,
    lane_pos_now_m: np.ndarray,
) -> np.ndarray:
    """Which trains are surely on the lane they were on at the last reading (so on the same edge), from numbers
    read anyway: the odometer and the lane position then and now, and the length of that lane.

    SUMO moves a train along its lane by adding one step's advance to both its lane position and its odometer,
    and puts it on the next lane only once that position passes the lane's end (the position then restarts near
    0, less by the left lane's length). So a train that moved forward (advance > 0), whose lane position moved on
    by the odometer's advance (within ``EDGE_KEPT_TOL_M``) to a point short of the lane's end, never changed lane.
    Everything else reads its edge again: standing trains (a reversing unit is flipped onto its ``bidi`` edge at
    standstill), a train at or past its lane's end, and every jump (``moveTo``, a flip while starting off: the
    lane position leaves the odometer's advance). A train without a last reading (NaN) is never kept.
    """
    advance_m = odometer_now_m - odometer_m
    expected_m = lane_pos_m + advance_m
    return (
        (advance_m > 0.0)
        & (expected_m < lane_length_m - LANE_END_MARGIN_M)
        & (np.abs(lane_pos_now_m - expected_m) <= EDGE_KEPT_TOL_M)
    )


class EdgeMemory:
    """Each train's edge id (and its lane's length) from the last reading, so that :meth:`SumoBridge.read` asks
    SUMO for an edge only where :func:`edge_kept` cannot vouch for the old one (a few trains a step: a train at
    line speed changes edge every few hundred steps, a standing one is asked every step).

    The readings are arrays aligned with the last step's ids; a step with other ids (a train came or left) carries
    over those it had. :meth:`forget` drops one train's reading (the bridge calls it whenever it adds, removes or
    reroutes a train: a new vehicle with an old id starts a new odometer). ``lane_length_m`` gives a lane's length
    by its id (asked once per lane).
    """

    def __init__(self, lane_length_m: Callable[[str], float]) -> None:
        self._lane_length_of = lane_length_m
        self.ids: list[str] = []
        self.odometer_m = np.empty(0)  # the last reading's arrays themselves (only read, never written)
        self.lane_pos_m = np.empty(0)
        self.lane_length_m = np.empty(0)  # this memory's own
        self.edges: list[str] = []
        self._forgotten: set[str] = set()
        self._lane_lengths_m: dict[str, float] = {}

    def clear(self) -> None:
        """Forget every reading (the next :meth:`edges_now` asks for every edge)."""
        self.ids = []

    def forget(self, train_id: str) -> None:
        self._forgotten.add(train_id)

    def edges_now(self, ids: list[str], odometer_m: np.ndarray, lane_pos_m: np.ndarray, calls: Any) -> list[str]:
        """The edge id of every train of ``ids`` (read or vouched for), given this step's odometers and lane
        positions; remembers this step's readings."""
        n = len(ids)
        if ids == self.ids:
            odo0, pos0, length_m, edges = self.odometer_m, self.lane_pos_m, self.lane_length_m, self.edges
        else:  # trains came or left: carry over the readings of those that were there
            where = {vid: i for i, vid in enumerate(self.ids)}
            old = np.array([where.get(vid, -1) for vid in ids], dtype=np.intp)
            had = old >= 0
            odo0 = np.full(n, np.nan)
            odo0[had] = self.odometer_m[old[had]]
            pos0, length_m = np.zeros(n), np.zeros(n)
            pos0[had], length_m[had] = self.lane_pos_m[old[had]], self.lane_length_m[old[had]]
            edges = [self.edges[i] if i >= 0 else "" for i in old.tolist()]
        kept = edge_kept(odo0, pos0, length_m, odometer_m, lane_pos_m)
        if self._forgotten:  # added, removed or rerouted since: a new odometer, maybe a new vehicle
            index = {vid: i for i, vid in enumerate(ids)}
            for vid in self._forgotten:
                if vid in index:
                    kept[index[vid]] = False
            self._forgotten.clear()
        for i in np.flatnonzero(~kept).tolist():
            vid = ids[i]
            edges[i] = calls.getRoadID(vid)
            length_m[i] = self._lane_length_m(calls.getLaneID(vid))
        self.ids, self.edges, self.lane_length_m = ids, edges, length_m
        self.odometer_m, self.lane_pos_m = odometer_m, lane_pos_m
        return list(edges)

    def _lane_length_m(self, lane_id: str) -> float:
        length_m = self._lane_lengths_m.get(lane_id)
        if length_m is None:
            length_m = self._lane_lengths_m[lane_id] = float(self._lane_length_of(lane_id))
        return length_m


@dataclass(frozen=True)
class VTypeSpec:
    """A SUMO vehicle type for one of our vehicle presets (kinematics only; physics stays in railsim)."""

    type_id: str
    length_m: float
    max_speed_mps: float
    accel_mps2: float = 1.0
    decel_mps2: float = 1.0
    emergency_decel_mps2: float = 1.3
    vclass: str = "rail_urban"
    tau_s: float = 1.0  # Krauss reaction time; tiny for controlled trains so insertion checks never bind


@dataclass(frozen=True)
class StopSpec:
    """A station stop handed to SUMO: trainStop id plus dwell (``duration_s``) and/or departure (``until_s``)."""

    stop_id: str
    duration_s: float | None = None
    until_s: float | None = None
    # (start, end) lane positions [m]: stop on the trainStop's lane in this window instead of at the trainStop
    # (a platform shorter than the train: SUMO registers a trainStop only with the whole train on it)
    lane_stop_m: tuple[float, float] | None = None
    # the pass of the stop's edge it is made on: its index in the route as handed to SUMO (None: the first pass
    # SUMO finds); counted from the edge the train stands on for a new route (``reroute``)
    route_index: int | None = None


@dataclass
class SumoConfig:
    """How to start SUMO for one run."""

    net_file: Path
    additional_files: Sequence[Path] = ()
    step_s: float = 0.5
    seed: int = 42
    step_method: str = "euler"  # "euler", "ballistic", or "forward" (SUMO runs Euler; the engine hands it v_k)
    begin_s: float = 0.0
    vtypes: Sequence[VTypeSpec] = ()
    output_dir: Path | None = None
    sumo_outputs: Sequence[str] = ()  # any of: tripinfo, stops, fcd, collisions
    extra_args: Sequence[str] = ()
    run_dir: Path | None = None  # the run folder: vTypes, inserted trains and .sumocfg files go there
    gui: bool = False  # sumo-gui through traci instead of libsumo (for looking; slower)


@dataclass
class TrainStates:
    """A snapshot of the trains present in SUMO (ground truth), aligned arrays indexed like ``ids``."""

    t_s: float
    ids: list[str]
    odometer_m: np.ndarray
    speed_mps: np.ndarray
    lane_pos_m: np.ndarray
    edge_ids: list[str]
    stopped: np.ndarray  # SUMO has registered a stop (dwelling)


def rail_signal_classes(vtypes: Sequence[VTypeSpec]) -> str:
    """The value of ``--railsignal.default-classes``: no vehicle class of ours. SUMO puts a train of a listed
    class on only once its block up to the next rail signal is free; on a signal-free net with bidi track that is
    the rest of its route, so a tram handed to SUMO at a single-track terminus stayed in SUMO's queue until the
    opposing tram had cleared the line (SUMO's default lists every rail class but tram). ``tram`` while no train
    is a tram, else none."""
    return "tram" if all(v.vclass != "tram" for v in vtypes) else ""


class SumoBridge:
    """Owns one libsumo simulation. Use as a context manager so SUMO is always closed."""

    edge_memory_min_trains = EDGE_MEMORY_MIN_TRAINS  # fewer trains present: every edge asked (:class:`EdgeMemory`)

    def __init__(self, config: SumoConfig) -> None:
        self.config = config
        self._tmp: tempfile.TemporaryDirectory[str] | None = None
        self._routes: set[str] = set()
        self._controlled: set[str] = set()
        self._vtype_file: Path | None = None
        self.inserted: list[sumo_files.InsertedTrain] = []  # every train as SUMO got it (for the run folder)
        self._edges = EdgeMemory(lambda lane_id: float(_api.lane.getLength(lane_id)))
        # stops SUMO would make on an earlier pass of their edge: train -> (route index the train must be past,
        # route index of the route's start, the stops in order) (:mod:`railsim.engine.stop_passes`)
        self._later: dict[str, tuple[int, int, list[StopSpec]]] = {}
        self.started = False

    # ---------------------------------------------------------------- lifecycle
    def command_line(self, vtype_file: Path | None) -> list[str]:
        cfg = self.config
        args = [
            "sumo",
            "-n",
            str(cfg.net_file),
            "--step-length",
            f"{cfg.step_s:g}",
            "--begin",
            f"{cfg.begin_s:g}",
            "--seed",
            str(int(cfg.seed)),
            "--railsignal.default-classes",
            rail_signal_classes(cfg.vtypes),
            "--collision.action",
            "warn",
            "--collision.check-junctions",
            "true",
            "--collision.mingap-factor",
            "0",
            "--time-to-teleport",
            "-1",
            "--emergencydecel.warning-threshold",
            "100",
            "--no-step-log",
            "true",
            "--duration-log.disable",
            "true",
            "--no-warnings",
            "true",
        ]
        if cfg.step_method == "ballistic":
            args += ["--step-method.ballistic", "true"]
        elif cfg.step_method not in ("euler", "forward"):  # forward = SUMO Euler fed the *old* speed (engine)
            raise ValueError(f"step_method must be 'euler', 'ballistic' or 'forward', got {cfg.step_method!r}")
        additional = [str(p) for p in cfg.additional_files]
        if vtype_file is not None:
            additional.append(str(vtype_file))
        if additional:
            args += ["-a", ",".join(additional)]
        if cfg.output_dir is not None and cfg.sumo_outputs:
            out = Path(cfg.output_dir)
            out.mkdir(parents=True, exist_ok=True)
            names = {
                "tripinfo": "--tripinfo-output",
                "stops": "--stop-output",
                "fcd": "--fcd-output",
                "collisions": "--collision-output",
            }
            for key in cfg.sumo_outputs:
                if key not in names:
                    raise ValueError(f"unknown SUMO output {key!r}; expected one of {sorted(names)}")
                args += [names[key], str(out / f"sumo_{key}.xml")]
            if "fcd" in cfg.sumo_outputs:
                args += ["--fcd-output.distance", "true"]
        args += list(cfg.extra_args)
        return args

    def start(self) -> SumoBridge:
        global _api
        if _ACTIVE["started"]:
            raise SimulationError("a SUMO simulation is already running in this process (libsumo hosts one)")
        run_dir = self.config.run_dir
        if run_dir is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="railsim-sumo-")
        vtype_file = None
        if self.config.vtypes:
            vtype_file = Path(run_dir or self._tmp.name) / sumo_files.VTYPES_FILE  # type: ignore[union-attr]
            write_bytes(vtype_file, sumo_files.vtypes_xml(self.config.vtypes).encode("utf-8"))
        self._vtype_file = vtype_file
        args = self.command_line(vtype_file)
        log.debug("starting SUMO: %s", " ".join(args))
        _api = libsumo
        try:
            if self.config.gui:
                _api = _start_gui(args)
            else:
                libsumo.start(args)
        except _api.TraCIException as exc:  # SUMO refused the inputs: show its message
            self._cleanup()
            raise SimulationError(f"SUMO could not start: {exc}") from None
        except Exception as exc:  # libsumo raises FatalTraCIError for unreadable nets
            self._cleanup()
            raise SimulationError(f"SUMO could not start: {exc}") from None
        _ACTIVE["started"] = True
        self.started = True
        return self

    def close(self) -> None:
        if self.started:
            try:
                _api.close()
            finally:
                self.started = False
                _ACTIVE["started"] = False
        self._write_run_files()
        self._cleanup()

    def _write_run_files(self) -> None:
        """The trains SUMO got and the ``.sumocfg`` files, in the run folder (:mod:`railsim.engine.sumo_files`)."""
        cfg = self.config
        if cfg.run_dir is None or self._vtype_file is None:
            return
        sumo_files.write_run_files(
            cfg.run_dir, self.command_line(self._vtype_file), self._vtype_file, self.inserted, "fcd" in cfg.sumo_outputs
        )

    def _cleanup(self) -> None:
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None

    def __enter__(self) -> SumoBridge:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---------------------------------------------------------------- world
    @property
    def time_s(self) -> float:
        return float(_api.simulation.getTime())

    def step(self) -> None:
        _api.simulationStep()
        if self._later:
            self._hand_later()

    def add_route(self, route_id: str, edges: Sequence[str]) -> None:
        if route_id in self._routes:
            return
        try:
            _api.route.add(route_id, list(edges))
        except _api.TraCIException as exc:
            raise SimulationError(f"SUMO rejected route {route_id!r}: {exc}") from None
        self._routes.add(route_id)

    def add_train(
        self,
        train_id: str,
        route_id: str,
        type_id: str,
        depart_pos_m: float,
        stops: Sequence[StopSpec] = (),
        controlled: bool = True,
        depart_speed_mps: float = 0.0,
    ) -> None:
        """Insert a train now (it appears after the next step) with its stops; controlled → speedMode 32."""
        self._edges.forget(train_id)
        try:
            _api.vehicle.add(
                train_id,
                route_id,
                type_id,
                depart="now",
                departPos=f"{depart_pos_m:.3f}",
                departSpeed=f"{depart_speed_mps:.6f}",
            )
            self._hand_stops(train_id, stops, 0)
            if controlled:
                _api.vehicle.setSpeedMode(train_id, 32)
                self._controlled.add(train_id)
        except _api.TraCIException as exc:
            raise SimulationError(f"SUMO rejected train {train_id!r}: {exc}") from None
        self.inserted.append(
            sumo_files.InsertedTrain(
                train_id,
                type_id,
                self.time_s,
                float(depart_pos_m),
                float(depart_speed_mps),
                tuple(_api.route.getEdges(route_id)),
                tuple((s.stop_id, s.duration_s, s.until_s) for s in stops),
            )
        )

    def reroute(self, train_id: str, edges: Sequence[str], stops: Sequence[StopSpec]) -> None:
        """Give a standing train a new route from the edge it is on (a unit's next trip) and its stops."""
        self._edges.forget(train_id)
        try:
            _api.vehicle.setRoute(train_id, list(edges))
            # SUMO keeps the edges already passed in front of the new route: it starts at the train's route index
            self._hand_stops(train_id, stops, max(0, int(_api.vehicle.getRouteIndex(train_id))))
        except _api.TraCIException as exc:
            raise SimulationError(f"SUMO rejected the next route of {train_id!r}: {exc}") from None

    def _hand_stops(self, train_id: str, stops: Sequence[StopSpec], base: int) -> None:
        """Hand SUMO the stops it makes on the pass they are meant for now; keep the rest for later (module
        docstring). ``base``: the route index where the route the stops' ``route_index`` count in begins."""
        self._later.pop(train_id, None)
        if not stops:
            return
        route = _api.vehicle.getRoute(train_id)
        edges = [_api.lane.getEdgeID(_api.busstop.getLaneID(s.stop_id)) for s in stops]
        want = [None if s.route_index is None else base + s.route_index for s in stops]
        now, past = stop_passes.stops_now(route, edges, want, int(_api.vehicle.getRouteIndex(train_id)))
        _set_stops(train_id, stops[:now])
        if past is not None:
            self._later[train_id] = (past, base, list(stops[now:]))

    def _hand_later(self) -> None:
        """Hand over the waiting stops of every train that has left the earlier pass of their edge behind."""
        for train_id, (past, base, stops) in list(self._later.items()):
            try:
                if int(_api.vehicle.getRouteIndex(train_id)) > past:
                    self._hand_stops(train_id, stops, base)
            except _api.TraCIException as exc:
                if train_id not in _api.vehicle.getIDList():  # it left the simulation: nothing to stop
                    self._later.pop(train_id, None)
                    continue
                raise SimulationError(f"SUMO rejected the stops of {train_id!r}: {exc}") from None

    def remove(self, train_id: str) -> None:
        self._edges.forget(train_id)
        self._later.pop(train_id, None)
        try:
            _api.vehicle.remove(train_id)
        except _api.TraCIException:
            pass
        self._controlled.discard(train_id)

    def set_length(self, train_id: str, length_m: float) -> None:
        _api.vehicle.setLength(train_id, float(length_m))

    def drop_stop(self, train_id: str, stop_id: str, lane_stop_m: tuple[float, float] | None = None) -> None:
        """Drop the pending stop ``stop_id`` (or its ``lane_stop_m`` window) if it is still the train's next one (a train overran the platform: logged by
        the engine). SUMO itself drops a stop a train has run past, so the next stop is compared first: dropping
        blindly would remove the stop after it (the destination — the train would then never arrive)."""
        try:
            pending = _api.vehicle.getStops(train_id, 1)
            if not pending:
                self._drop_later(train_id, stop_id)
                return
            nxt = pending[0]
            if lane_stop_m is None:
                same = nxt.stoppingPlaceID == stop_id
            else:
                same = not nxt.stoppingPlaceID and nxt.lane == _api.busstop.getLaneID(stop_id)
                same = same and abs(nxt.endPos - lane_stop_m[1]) < 1e-3
            if same:
                _api.vehicle.replaceStop(train_id, 0, "")
        except _api.TraCIException as exc:
            log.warning("could not drop stop %s of %s: %s", stop_id, train_id, exc)

    # ---------------------------------------------------------------- state
    def present_ids(self) -> list[str]:
        return list(_api.vehicle.getIDList())

    def departed_ids(self) -> list[str]:
        return list(_api.simulation.getDepartedIDList())

    def arrived_ids(self) -> list[str]:
        return list(_api.simulation.getArrivedIDList())

    def pending_ids(self) -> list[str]:
        return list(_api.simulation.getPendingVehicles())

    def read(self, ids: Sequence[str] | None = None) -> TrainStates:
        """Ground truth for ``ids`` (default: every train present) via direct getters: the odometer, speed, lane
        position and stop state of every train; with ``edge_memory_min_trains`` or more, its edge only where
        :class:`EdgeMemory` cannot vouch for the last one read."""
        ids = list(_api.vehicle.getIDList()) if ids is None else list(ids)
        v = _vehicle_calls()
        odo = np.array(list(map(v.getDistance, ids)), dtype=float)  # one getter over all trains at a time
        spd = np.array(list(map(v.getSpeed, ids)), dtype=float)
        lpos = np.array(list(map(v.getLanePosition, ids)), dtype=float)
        stopped = (np.array(list(map(v.getStopState, ids)), dtype=np.int64) & 1).astype(bool)  # isStopped: bit 0
        if len(ids) >= self.edge_memory_min_trains:
            edges = self._edges.edges_now(ids, odo, lpos, v)
        else:  # few trains: asking is cheaper than the memory's array work
            self._edges.clear()
            edges = list(map(v.getRoadID, ids))
        return TrainStates(self.time_s, ids, odo, spd, lpos, edges, stopped)

    def set_speeds(self, ids: Sequence[str], speeds_mps: Sequence[float] | np.ndarray) -> None:
        """Hand SUMO each train's speed for the coming step (libsumo's compiled setter mapped over the ids: no
        Python frame per train)."""
        deque(map(_vehicle_calls().setSpeed, ids, map(float, speeds_mps)), maxlen=0)  # consumed in C

    def release_speed(self, train_id: str) -> None:
        """Hand a train back to SUMO's car-following model (``setSpeed(-1)``, default speed mode)."""
        _api.vehicle.setSpeed(train_id, -1)
        _api.vehicle.setSpeedMode(train_id, 31)
        self._controlled.discard(train_id)

    def collisions(self) -> list[dict[str, object]]:
        """SUMO's own collision reports of the last step (an independent check of our ground truth)."""
        out = []
        for c in _api.simulation.getCollisions():
            out.append({"collider": c.collider, "victim": c.victim, "type": c.type, "lane": c.lane, "pos_m": c.pos})
        return out

    def _drop_later(self, train_id: str, stop_id: str) -> None:
        """Drop ``stop_id`` if it is the first of the stops still waiting to be handed to SUMO."""
        waiting = self._later.get(train_id)
        if waiting is not None and waiting[2][0].stop_id == stop_id:
            rest = waiting[2][1:]
            if rest:
                self._later[train_id] = (waiting[0], waiting[1], rest)
            else:
                del self._later[train_id]

    def stop_states(self, train_id: str) -> list[tuple[str, float, float]]:
        """Remaining stops of a train as ``(stop_id, duration_s, until_s)`` (for checks and debugging): SUMO's,
        then those still waiting for the train to pass an earlier pass of their edge (``until``/``duration``
        -1073741824.0 where none)."""
        held = [(s.stoppingPlaceID, s.duration, s.until) for s in _api.vehicle.getStops(train_id)]
        unset = -1073741824.0
        later = self._later.get(train_id, (0, 0, []))[2]
        return held + [
            (s.stop_id, unset if s.duration_s is None else s.duration_s, unset if s.until_s is None else s.until_s)
            for s in later
        ]


def _start_gui(args: list[str]) -> Any:
    """Start sumo-gui (the eclipse-sumo wheel's) through traci with ``args``; it starts running at once."""
    import traci
    from sumolib import checkBinary

    traci.start([checkBinary("sumo-gui"), *args[1:], "--start", "true", "--quit-on-end", "true"])
    return traci


def _set_stops(train_id: str, stops: Sequence[StopSpec]) -> None:
    """Hand SUMO a train's station stops (trainStops are busStops to SUMO's stop logic; a platform shorter than
    the train is a stop on its lane, ``lane_stop_m``, which SUMO registers where a trainStop would not)."""
    for stop in stops:
        duration = -1073741824.0 if stop.duration_s is None else float(stop.duration_s)
        until = -1073741824.0 if stop.until_s is None else float(stop.until_s)
        if stop.lane_stop_m is None:
            _api.vehicle.setBusStop(train_id, stop.stop_id, duration, until, flags=_STOP_BUS_STOP)
            continue
        lane = _api.busstop.getLaneID(stop.stop_id)
        # SUMO rejects a stop that ends past its lane ("invalid position"), even by a rounding error of the route
        # chainage the window was computed in (a platform ending at its edge's end, an overrun reaching it)
        lane_m = float(_api.lane.getLength(lane))
        end_m = min(stop.lane_stop_m[1], lane_m)
        start_m = max(0.0, min(stop.lane_stop_m[0], end_m))
        _api.vehicle.setStop(
            train_id,
            _api.lane.getEdgeID(lane),
            pos=end_m,
            laneIndex=int(lane.rsplit("_", 1)[1]),
            duration=duration,
            until=until,
            startPos=start_m,
        )


def version() -> str:
    """SUMO version string of the loaded _api."""
    try:
        return str(libsumo.simulation.getVersion()[1])
    except Exception:  # not started
        return getattr(libsumo, "__version__", "unknown")
