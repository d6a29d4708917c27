"""What the engine hands the recorder at the end of a run, and the table of files a run writes.

:class:`RunSnapshot` is plain data: the recorder turns it into ``trips.csv``, ``formations.csv``,
``events.csv``, ``summary.json`` … without ever importing the engine. ``trains`` are the engine's train
records, read through the attributes :class:`TripOutcome` lists.

:data:`OUTPUT_FILES` is the one table of what a run folder holds: the recorder writes it in this order, the CLI
prints it, and a new output is one row here plus its writer in :meth:`railsim.record.recorder.Recorder.write`.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol


class TripOutcome(Protocol):
    """The attributes of a train record the recorder reads (``railsim.engine.train.TrainRuntime`` has them)."""

    train_id: str
    trip: Any
    status: str
    inserted_s: float | None
    departed_s: float | None
    arrived_s: float | None
    energy_j: float
    min_gap_m: float
    coupled_s: float
    max_jerk_mps3: float
    stops_served: int
    fallbacks: int
    stale_max_s: float
    violations: set[str]


@dataclass(frozen=True)
class FormationOutcome:
    """One formation at the end of the run: ids, the state machine's statistics and its final state."""

    id: str
    leader_id: str
    follower_id: str
    stats: Any  # railsim.engine.events.formations.FormationStats
    state: str


@dataclass
class RunSnapshot:
    """Everything the recorder needs from a finished (or interrupted) run."""

    scenario_name: str
    seed: int
    trains: Iterable[TripOutcome]
    formations: list[FormationOutcome]
    events: list[dict[str, Any]]
    channel_stats: Mapping[str, Any]  # channel name -> ChannelStats (a dataclass)
    collisions: int
    sumo_collisions: int
    sim_s: float
    wall_s: float
    steps: int
    step_s: float
    formats: tuple[str, ...]
    resolved_scenario: Any
    versions: Mapping[str, str]
    extra_summary: dict[str, Any] = field(default_factory=dict)  # extensions' summaries (e.g. "junction")
    failure: str | None = None  # why the run stopped early (a desync, a stall), or None
    # tables only some runs write (``delays.csv`` with ``disturbances:``): stem -> (rows, columns)
    extra_tables: dict[str, tuple[list[dict[str, Any]], list[str]]] = field(default_factory=dict)
    interrupted_by: str | None = None  # the signal that stopped the run ("SIGINT", "SIGTERM"), or None

    @property
    def status(self) -> str:
        """``interrupted`` (a signal), ``failed`` (a desync, a stall) or ``completed`` (all trips or the horizon)."""
        if self.interrupted_by is not None:
            return "interrupted"
        return "failed" if self.failure is not None else "completed"


@dataclass(frozen=True)
class OutputFile:
    """One file of a run folder: ``kind`` is ``table`` (CSV, + Parquet if asked), ``document`` or ``sumo``."""

    stem: str
    kind: str
    file_name: str
    what: str


OUTPUT_FILES: tuple[OutputFile, ...] = (
    OutputFile("trips", "table", "trips.csv", "one row per trip"),
    OutputFile("stops", "table", "stops.csv", "one row per trip and stop"),
    OutputFile("formations", "table", "formations.csv", "one row per formation"),
    OutputFile("events", "table", "events.csv", "the event log"),
    OutputFile("trace", "table", "trace.csv", "per-train samples"),
    OutputFile("summary", "document", "summary.json", "totals of the run"),
    OutputFile("scenario.resolved", "document", "scenario.resolved.yaml", "the scenario with every default"),
    OutputFile("versions", "document", "versions.json", "railsim, SUMO and numpy versions"),
    # kind "sumo": written by the SUMO bridge, not the recorder (railsim.engine.sumo_files)
    OutputFile("sumo_vtypes", "sumo", "sumo_vtypes.rou.xml", "the run's SUMO vehicle types"),
    OutputFile("sumo_routes", "sumo", "sumo_routes.rou.xml", "every train as SUMO got it: route, stops"),
    OutputFile("sumo_run", "sumo", "sumo_run.sumocfg", "opens the run's net, stops and trains in sumo/sumo-gui"),
    OutputFile("sumo_replay", "sumo", "sumo_replay.sumocfg", "net and stops to replay sumo_fcd.xml on (fcd only)"),
)


def output_file_name(stem: str) -> str:
    """The file name of the :data:`OUTPUT_FILES` row ``stem``."""
    return next(f.file_name for f in OUTPUT_FILES if f.stem == stem)
