"""Parameter sweeps: one base scenario, many overridden copies, every copy run in its own process, one tidy table.

A **sweep file** (YAML) names a base scenario and how to vary it::

    name: line3_headway_coupling            # optional, default: the file's stem
    description: ...                        # optional
    base: ../chongqing_line3_peak.yaml      # required, relative to this file
    grid:                                   # optional: dotted override path -> list of values (cartesian product)
      services[0].departures.headway_s: [120, 150, 180]
    link:                                   # optional: path -> the grid/case path whose value it copies
      services[1].departures.headway_s: services[0].departures.headway_s
    cases:                                  # optional: a list of override mappings, each with an optional label
      - {label: {coupling: "on"}}
      - {label: {coupling: "off"}, formations: []}     # a value may be a whole subtree
    seeds: [1, 2]                           # optional, default [the base scenario's simulation.seed]
    timeout_s: 600                          # optional per-case wall-clock limit (seconds), default none

Override paths are those of :func:`railsim.scenario.with_overrides` (``a.b[0].c``; mapping keys on the way are
created, list indices must exist).

**Expansion.** The cases are ``cases x grid x seeds``: every entry of ``cases`` (one empty case when the list is
absent) is combined with every grid point and every seed, in that nesting order (so the table reads case by case).
Inside one case the case's own overrides are applied first, then the grid values, then the links; a path may not be
both a grid axis and a case override. ``link`` ties parameters that must move together (the down headway equals
the up headway) without multiplying the grid. A case's ``label`` (a string, giving a column ``label``, or a mapping
column -> scalar) only names the case in the table: it changes nothing in the scenario and is not hashed.

**Case id.** ``case_id`` is the first 12 hex digits of the SHA-256 of the canonical JSON of ``{overrides, seed}``
(sorted keys; an integral float such as ``150.0`` hashes like ``150``). The same overrides and seed always give the
same id, whatever the order of the sweep file, so a re-run, or an extended sweep, finds the cases already done.

**Validation first.** Every case's scenario is loaded (overrides applied, schema checked) and its world ids checked
(:func:`railsim.studies.world.world_check`, the world is built once and cached) *before* anything runs; the first
bad case stops the sweep with one line naming the sweep file, the case and the field (exit code 2).

**Processes.** libsumo hosts one simulation per process, and a SUMO crash kills its interpreter, so each case runs
in a fresh child Python (:func:`run_case`, :mod:`.child`): locally ``workers`` threads each wait on one child at a
time; on a Dask cluster (``--dask ADDRESS``, the scheduler our users already run) each task is :func:`run_case`
too, i.e. the Dask worker also starts a fresh child per case (:mod:`.parallel`).

**Resumability.** The coordinating process (never a worker) persists each finished case atomically as
``DIR/rows/<case_id>.json`` the moment it completes (:mod:`railsim.record.output`: temp file + rename). ``cases.parquet``
and ``cases.csv`` are derived: rebuilt from ``rows/`` for the cases of the current definition, in expansion order,
at the end of every invocation (also after Ctrl-C). Re-running the same command skips every case that has a row,
so a sweep killed at any point (even ``kill -9``) loses at most the cases that were running and never duplicates a
row. A case that raises, crashes or times out is recorded with ``status: failed`` and its ``error``, and the sweep
goes on; ``--retry-failed`` runs those again (the failed row stays until its replacement is written).
``DIR/sweep.yaml`` holds the resolved definition and the SHA-256 of the base scenario file; resuming into a folder
made from a different base file is refused (the stored rows would not describe the new base).

**Columns.** ``case_id``, ``status`` (``ok`` | ``failed``), ``error`` (``""`` when ok), ``seed``, the label columns,
one column per override path (lists and mappings as compact JSON text), ``wall_s`` (the case's wall clock, child
start to end), then the scalar metrics of ``summary.json`` flattened with ``.`` (``formations.vc0.min_gap_m``,
``mean_running_time_s.airport_up``; the summary's own ``wall_s`` becomes ``engine_wall_s``; lists are dropped)
and four from ``trips.csv``: ``trips.arrival_delay_max_s``, ``trips.arrival_delay_p95_s``,
``trips.arrival_delay_mean_s`` (arrival delay against the free-run plan over the arrived trips) and
``trips.energy_kwh_total``. A collision is a result (``collisions`` > 0, status ok), not a failure.

**Determinism.** A case's metrics depend only on the base scenario, its overrides and its seed: the same sweep
run locally or on Dask gives identical metric columns; only the wall-clock columns (:data:`WALL_CLOCK_COLUMNS`)
differ.

``railsim sweep SWEEP.yaml --out DIR [--workers N | --dask ADDRESS] [--retry-failed] [--keep-runs] [--timeout S]``
(:mod:`railsim.cli.sweep`) exits 0 when every case is ok, 1 when some case failed, 2 on bad input, 130 when
interrupted.

The package, one concept per module, each importing only those before it:

* :mod:`.spec` — the sweep file, its expansion into :class:`Case` objects, :func:`case_id`, :func:`validate_cases`;
* :mod:`.metrics` — a run folder reduced to the row's metric columns (:func:`summary_metrics`, :func:`trip_metrics`);
* :mod:`.child` — one case in a fresh child process (:func:`run_case`);
* :mod:`.parallel` — many cases on local threads or a Dask cluster (:func:`execute`);
* :mod:`.tables` — the folder's ``rows/`` and the derived ``cases.parquet``/``cases.csv`` (:func:`write_tables`);
* :mod:`.runner` — a whole resumable sweep (:func:`run_sweep`).

Everything public is re-exported here: ``from railsim.studies import sweep; sweep.run_sweep(...)``.
"""

from railsim.studies.sweep.child import SweepInterrupted, run_case
from railsim.studies.sweep.metrics import summary_metrics, trip_metrics
from railsim.studies.sweep.parallel import CaseTask, execute
from railsim.studies.sweep.runner import SweepResult, run_sweep
from railsim.studies.sweep.spec import (
    CASE_ID_HEX,
    RESERVED_COLUMNS,
    SWEEP_KEYS,
    Case,
    SweepSpec,
    case_id,
    load_sweep,
    validate_cases,
)
from railsim.studies.sweep.tables import WALL_CLOCK_COLUMNS, load_table, read_rows, write_row, write_tables

__all__ = [
    "CASE_ID_HEX",
    "RESERVED_COLUMNS",
    "SWEEP_KEYS",
    "WALL_CLOCK_COLUMNS",
    "Case",
    "CaseTask",
    "SweepInterrupted",
    "SweepResult",
    "SweepSpec",
    "case_id",
    "execute",
    "load_sweep",
    "load_table",
    "read_rows",
    "run_case",
    "run_sweep",
    "summary_metrics",
    "trip_metrics",
    "validate_cases",
    "write_row",
    "write_tables",
]
