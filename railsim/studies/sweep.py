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
(:func:`railsim.cli.scenario.world_check`, the world is built once and cached) *before* anything runs; the first
bad case stops the sweep with one line naming the sweep file, the case and the field (exit code 2).

**Processes.** libsumo hosts one simulation per process, and a SUMO crash kills its interpreter, so each case runs
in a fresh child Python (:func:`run_case`): locally ``workers`` threads each wait on one child at a time; on a Dask
cluster each task is :func:`run_case` too, i.e. the Dask worker (which runs tasks on threads, several at once) also
starts a fresh child per case. Children live in their own process group (a terminal Ctrl-C reaches only the
coordinator, which then kills them) and exit by themselves if their parent dies.

**Why Dask.** The users who run large sweeps already have a cluster with a Dask scheduler (an HPC allocation through
dask-jobqueue, a lab server, a cloud deployment); ``--dask ADDRESS`` submits to it with ``distributed.Client``
and needs nothing else to be installed or started. Dask's workers must see the same filesystem paths (the base
scenario, its world files and, with ``--keep-runs``, the sweep folder): true for a ``LocalCluster`` and for a
cluster on a shared filesystem. A Dask task that is already running when the sweep is interrupted finishes in the
background (Dask cannot stop a running thread); its result is discarded.

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
exits 0 when every case is ok, 1 when some case failed, 2 on bad input, 130 when interrupted.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import csv
import hashlib
import itertools
import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping, Sequence

from railsim.record import output
from railsim.errors import ConfigError
from railsim.scenario import _PATH_RE, _parse_yaml, _read_text

SWEEP_KEYS = ("name", "description", "base", "grid", "link", "cases", "seeds", "timeout_s")
RESERVED_COLUMNS = ("case_id", "status", "error", "seed", "wall_s")
# Columns that measure wall-clock time: they differ between runs of the same case; every other column may not.
WALL_CLOCK_COLUMNS = ("wall_s", "engine_wall_s")
CASE_ID_HEX = 12
_TAIL_CHARS = 600  # how much of a crashed child's stderr goes into the error column
_PARENT_POLL_S = 1.0  # how often a child checks that its parent is still alive
DASK_CONNECT_TIMEOUT_S = 10.0  # how long to try reaching a Dask scheduler before giving up


# --------------------------------------------------------------------------------------------------------------
# Sweep definition
# --------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Case:
    """One case of a sweep: the overrides applied to the base scenario, the seed, and display labels."""

    case_id: str
    overrides: dict[str, Any]
    seed: int
    labels: dict[str, Any] = field(default_factory=dict)

    def describe(self) -> str:
        parts = [f"{k}={_compact(v)}" for k, v in self.labels.items()]
        parts += [f"{k}={_compact(v)}" for k, v in self.overrides.items()]
        parts.append(f"seed {self.seed}")
        return ", ".join(parts)


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep definition (see the module docstring)."""

    name: str
    source: Path
    base: Path  # absolute path of the base scenario
    base_sha256: str
    cases: tuple[Case, ...]
    override_columns: tuple[str, ...]
    label_columns: tuple[str, ...]
    timeout_s: float | None
    raw: dict[str, Any]  # the resolved definition, written to DIR/sweep.yaml


def _compact(value: Any) -> str:
    text = value if isinstance(value, str) else json.dumps(value, separators=(",", ":"), default=str)
    return text if len(text) <= 40 else text[:37] + "..."


def _canonical(value: Any) -> Any:
    """Value as hashed: integral floats as ints (``150.0`` and ``150`` are the same headway)."""
    if isinstance(value, float) and math.isfinite(value) and value == int(value):
        return int(value)
    if isinstance(value, Mapping):
        return {str(k): _canonical(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    return value


def case_id(overrides: Mapping[str, Any], seed: int) -> str:
    """Stable id of a case: SHA-256 of the canonical JSON of ``{overrides, seed}``, first 12 hex digits."""
    text = json.dumps({"overrides": _canonical(dict(overrides)), "seed": int(seed)}, sort_keys=True,
                      separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:CASE_ID_HEX]


def _is_scalar(value: Any) -> bool:
    return value is None or isinstance(value, (str, int, float, bool))


class _SweepValidator:
    def __init__(self, source: Path) -> None:
        self.source = str(source)

    def fail(self, where: str | None, message: str) -> ConfigError:
        return ConfigError(self.source, where, message)

    def path(self, value: Any, where: str) -> str:
        if not isinstance(value, str) or not _PATH_RE.match(value):
            raise self.fail(where, f'expected an override path like "services[0].departures.headway_s", got {value!r}')
        return value

    def labels(self, value: Any, where: str) -> dict[str, Any]:
        if isinstance(value, str):
            return {"label": value}
        if not isinstance(value, Mapping) or not value:
            raise self.fail(where, f"expected a string or a non-empty mapping column -> value, got {value!r}")
        out: dict[str, Any] = {}
        for k, v in value.items():
            if not isinstance(k, str) or not k or k in RESERVED_COLUMNS:
                raise self.fail(f"{where}.{k}", f"expected a column name other than {', '.join(RESERVED_COLUMNS)}")
            if not _is_scalar(v):
                raise self.fail(f"{where}.{k}", f"expected a scalar label value, got {_compact(v)}")
            out[k] = v
        return out


def load_sweep(path: str | Path) -> SweepSpec:
    """Read and validate a sweep file (its structure only; :func:`validate_cases` checks every case's scenario)."""
    src = Path(path)
    v = _SweepValidator(src)
    data = _parse_yaml(_read_text(src, str(src)), str(src))
    if not isinstance(data, Mapping):
        raise v.fail(None, f"expected a mapping with keys {', '.join(SWEEP_KEYS)}, got {_compact(data)}")
    for key in data:
        if key not in SWEEP_KEYS:
            raise v.fail(str(key), f"unknown key; expected one of {', '.join(SWEEP_KEYS)}")
    name = data.get("name", src.stem)
    if not isinstance(name, str) or not name:
        raise v.fail("name", f"expected a non-empty string, got {name!r}")
    base_text = data.get("base")
    if not isinstance(base_text, str) or not base_text:
        raise v.fail("base", "expected the path of a scenario file (relative to the sweep file)")
    base = (src.resolve().parent / base_text).resolve()
    if not base.is_file():
        raise v.fail("base", f"scenario file not found: {base}")

    grid_raw = data.get("grid") or {}
    if not isinstance(grid_raw, Mapping):
        raise v.fail("grid", "expected a mapping override path -> list of values")
    grid: dict[str, list[Any]] = {}
    for key, values in grid_raw.items():
        p = v.path(key, f"grid.{key}")
        if not isinstance(values, list) or not values:
            raise v.fail(f"grid.{p}", f"expected a non-empty list of values, got {_compact(values)}")
        grid[p] = values

    cases_raw = data.get("cases")
    if cases_raw is None:
        cases_raw = [{}]
    if not isinstance(cases_raw, list) or not cases_raw:
        raise v.fail("cases", "expected a non-empty list of override mappings")
    case_defs: list[tuple[dict[str, Any], dict[str, Any]]] = []
    for i, entry in enumerate(cases_raw):
        where = f"cases[{i}]"
        if entry is None:
            entry = {}
        if not isinstance(entry, Mapping):
            raise v.fail(where, f"expected a mapping of override path -> value, got {_compact(entry)}")
        labels: dict[str, Any] = {}
        overrides: dict[str, Any] = {}
        for key, value in entry.items():
            if key == "label":
                labels = v.labels(value, f"{where}.label")
                continue
            p = v.path(key, f"{where}.{key}")
            if p in grid:
                raise v.fail(f"{where}.{p}", "also a grid axis: vary a path either in the grid or in the cases")
            overrides[p] = value
        case_defs.append((overrides, labels))

    link_raw = data.get("link") or {}
    if not isinstance(link_raw, Mapping):
        raise v.fail("link", "expected a mapping override path -> the grid or case path it copies")
    case_paths = {p for o, _ in case_defs for p in o}
    link: dict[str, str] = {}
    for key, src_path in link_raw.items():
        p = v.path(key, f"link.{key}")
        s = v.path(src_path, f"link.{p}")
        if p in grid or p in case_paths:
            raise v.fail(f"link.{p}", "is varied itself (grid or cases); a linked path copies another one")
        if s not in grid and s not in case_paths:
            raise v.fail(f"link.{p}", f"expected a grid or case path to copy, got {s!r}")
        link[p] = s

    seeds_raw = data.get("seeds")
    if seeds_raw is None:
        seeds = [_base_seed(base)]
    else:
        if not isinstance(seeds_raw, list) or not seeds_raw:
            raise v.fail("seeds", "expected a non-empty list of integers >= 0")
        seeds = []
        for j, s in enumerate(seeds_raw):
            if isinstance(s, bool) or not isinstance(s, int) or s < 0:
                raise v.fail(f"seeds[{j}]", f"expected an integer >= 0, got {s!r}")
            if s in seeds:
                raise v.fail(f"seeds[{j}]", f"seed {s} is listed twice")
            seeds.append(s)

    timeout = data.get("timeout_s")
    if timeout is not None and (isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or timeout <= 0):
        raise v.fail("timeout_s", f"expected a number of seconds > 0, got {timeout!r}")

    cases: list[Case] = []
    seen: dict[str, int] = {}
    grid_points = list(itertools.product(*grid.values())) if grid else [()]
    for ci, (case_over, labels) in enumerate(case_defs):
        for point in grid_points:
            over = dict(case_over)
            over.update(zip(grid.keys(), point))
            for target, copied in link.items():
                if copied in over:
                    over[target] = over[copied]
            for seed in seeds:
                cid = case_id(over, seed)
                if cid in seen:
                    raise v.fail(f"cases[{ci}]", f"case ({Case(cid, over, seed, labels).describe()}) duplicates "
                                                 f"case {seen[cid]}: same overrides and seed")
                seen[cid] = len(cases)
                cases.append(Case(cid, over, seed, labels))

    override_columns = list(dict.fromkeys([p for o, _ in case_defs for p in o] + list(grid) + list(link)))
    label_columns = list(dict.fromkeys(k for _, lab in case_defs for k in lab))
    for col in label_columns:
        if col in override_columns:
            raise v.fail("cases", f"label column {col!r} has the name of an override path")
    raw = {"name": name, "description": str(data.get("description", "")), "base": str(base),
           "grid": grid, "link": link,
           "cases": [dict(({"label": lab} if lab else {}), **o) for o, lab in case_defs],
           "seeds": seeds, "timeout_s": timeout}
    return SweepSpec(name=name, source=src, base=base, base_sha256=_sha256(base), cases=tuple(cases),
                     override_columns=tuple(override_columns), label_columns=tuple(label_columns),
                     timeout_s=float(timeout) if timeout is not None else None, raw=raw)


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _base_seed(base: Path) -> int:
    from railsim import scenario

    return int(scenario.load(base).simulation.seed)


def validate_cases(spec: SweepSpec, world_check: bool = True) -> None:
    """Load every case's scenario (overrides applied) and check its world ids; ConfigError on the first bad case.

    The error names the sweep file, the case (number and overrides) and the scenario field."""
    from railsim import scenario
    from railsim.cli.scenario import world_check as check_world

    for k, case in enumerate(spec.cases):
        try:
            scn = scenario.load(spec.base, case.overrides)
            if world_check:  # station/switch ids depend on the overridden services: every case (builds are cached)
                check_world(scn)
        except ConfigError as err:
            inner = str(err).replace("<overrides>", "override")
            raise ConfigError(spec.source, f"case {k} ({case.describe()})", inner) from None


# --------------------------------------------------------------------------------------------------------------
# One case in a child process
# --------------------------------------------------------------------------------------------------------------


class SweepInterrupted(Exception):
    """The sweep is stopping (Ctrl-C): the case's child was killed and its result must not be recorded."""


class _ChildControl:
    """Live child processes of one coordinator, so that an interrupt can kill them all."""

    def __init__(self) -> None:
        self.stopping = threading.Event()
        self._lock = threading.Lock()
        self._live: set[subprocess.Popen[bytes]] = set()

    def add(self, proc: subprocess.Popen[bytes]) -> None:
        with self._lock:
            self._live.add(proc)
        if self.stopping.is_set():
            _kill(proc)

    def remove(self, proc: subprocess.Popen[bytes]) -> None:
        with self._lock:
            self._live.discard(proc)

    def stop(self) -> None:
        self.stopping.set()
        with self._lock:
            live = list(self._live)
        for proc in live:
            _kill(proc)


_DEFAULT_CONTROL = _ChildControl()


def _kill(proc: subprocess.Popen[bytes]) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)  # the child leads its own process group
    except (ProcessLookupError, PermissionError):
        pass


def _flatten(prefix: str, value: Any, out: dict[str, Any]) -> None:
    if isinstance(value, Mapping):
        for k, v in value.items():
            _flatten(f"{prefix}.{k}" if prefix else str(k), v, out)
    elif _is_scalar(value):
        out[prefix] = value
    # lists (e.g. printable tables) are not metrics: dropped


def summary_metrics(summary: Mapping[str, Any]) -> dict[str, Any]:
    """The scalar metrics of a run's summary, nested keys joined with ``.``; ``wall_s`` renamed ``engine_wall_s``."""
    flat: dict[str, Any] = {}
    _flatten("", {k: v for k, v in summary.items() if k != "analysis_tables"}, flat)
    if "wall_s" in flat:
        flat["engine_wall_s"] = flat.pop("wall_s")
    flat.pop("seed", None)  # the row's own seed column
    return flat


def trip_metrics(run_dir: Path) -> dict[str, Any]:
    """Arrival-delay statistics [s] over the arrived trips and total traction energy [kWh] of a finished run."""
    import numpy as np

    path = Path(run_dir) / "trips.csv"
    if path.is_file():
        with open(path, newline="", encoding="utf-8") as fh:
            rows: list[Mapping[str, Any]] = list(csv.DictReader(fh))
    else:
        import pandas as pd

        rows = pd.read_parquet(Path(run_dir) / "trips.parquet").to_dict("records")

    def numbers(key: str) -> list[float]:
        vals = []
        for r in rows:
            x = r.get(key)
            if x is not None and x != "" and math.isfinite(float(x)):
                vals.append(float(x))
        return vals

    delays, energy = numbers("delay_s"), numbers("energy_kwh")
    return {
        "trips.arrival_delay_max_s": max(delays) if delays else None,
        "trips.arrival_delay_p95_s": float(np.percentile(delays, 95)) if delays else None,
        "trips.arrival_delay_mean_s": float(np.mean(delays)) if delays else None,
        "trips.energy_kwh_total": float(sum(energy)) if energy else None,
    }


def _watch_parent(parent_pid: int) -> None:
    while True:
        time.sleep(_PARENT_POLL_S)
        if os.getppid() != parent_pid:
            os._exit(3)  # the coordinator is gone: nobody will read our result


def _child_main(spec_path: str) -> None:
    """Entry point of the case child process (see :func:`run_case`): run, then write the result file."""
    spec = json.loads(Path(spec_path).read_text(encoding="utf-8"))
    threading.Thread(target=_watch_parent, args=(int(spec["parent_pid"]),), daemon=True).start()
    result_path = Path(spec["result"])
    try:
        from railsim import api as engine
        from railsim import scenario

        scn = scenario.load(spec["scenario"], spec["overrides"])
        with tempfile.TemporaryDirectory(prefix="railsim_case_") as tmp:
            run_dir = Path(spec["out_dir"]) if spec.get("out_dir") else Path(tmp)
            engine.run(scn, run_dir, seed=int(spec["seed"]), progress=False)
            summary = json.loads((run_dir / "summary.json").read_text(encoding="utf-8"))
            metrics = summary_metrics(summary)
            metrics.update(trip_metrics(run_dir))
        output.write_json(result_path, {"ok": True, "metrics": metrics})
    except BaseException as exc:  # noqa: BLE001 - every failure of a case becomes its error text
        output.write_json(result_path, {"ok": False, "error": f"{type(exc).__name__}: {exc}"})
        raise SystemExit(1) from None


def run_case(scenario_path: str | Path, overrides: Mapping[str, Any], seed: int, out_dir: Path | None = None,
             timeout_s: float | None = None, *, control: _ChildControl | None = None) -> dict[str, Any]:
    """Run one case of ``scenario_path`` in a fresh child process and return its flat row.

    Never raises for a failing case: an exception in the child, a crash (signal) or a timeout gives
    ``status: failed`` with the reason in ``error``. With ``out_dir`` the run's full outputs are kept there.
    Raises :class:`SweepInterrupted` only when ``control`` is stopping (the sweep was interrupted).
    """
    ctl = control or _DEFAULT_CONTROL
    overrides = dict(overrides)
    row: dict[str, Any] = {"case_id": case_id(overrides, seed), "status": "failed", "error": "", "seed": int(seed)}
    for path, value in overrides.items():
        row[path] = value if _is_scalar(value) else json.dumps(value, separators=(",", ":"), sort_keys=True)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="railsim_case_io_") as io_dir:
        spec_file = Path(io_dir) / "spec.json"
        result_file = Path(io_dir) / "result.json"
        output.write_json(spec_file, {"scenario": str(Path(scenario_path).resolve()), "overrides": overrides,
                                      "seed": int(seed), "out_dir": str(Path(out_dir).resolve()) if out_dir else None,
                                      "result": str(result_file), "parent_pid": os.getpid()})
        code = f"from railsim.studies.sweep import _child_main; _child_main({str(spec_file)!r})"
        if ctl.stopping.is_set():
            raise SweepInterrupted(row["case_id"])
        proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                start_new_session=True)
        ctl.add(proc)
        timed_out = False
        try:
            try:
                _, err = proc.communicate(timeout=timeout_s)
            except subprocess.TimeoutExpired:
                timed_out = True
                _kill(proc)
                _, err = proc.communicate()
        finally:
            ctl.remove(proc)
        row["wall_s"] = time.perf_counter() - t0
        if ctl.stopping.is_set():
            raise SweepInterrupted(row["case_id"])
        result = None
        if result_file.is_file():
            result = json.loads(result_file.read_text(encoding="utf-8"))
        if timed_out:
            row["error"] = f"timed out after {timeout_s:g} s"
        elif result is None:
            tail = err.decode("utf-8", "replace").strip()[-_TAIL_CHARS:]
            how = (f"killed by signal {signal.Signals(-proc.returncode).name}" if proc.returncode < 0
                   else f"exited with code {proc.returncode}")
            row["error"] = f"child process {how} without a result" + (f": {tail}" if tail else "")
        elif not result["ok"]:
            row["error"] = result["error"]
        else:
            row["status"] = "ok"
            row.update(result["metrics"])
    return row


# --------------------------------------------------------------------------------------------------------------
# Running many cases (local threads or a Dask cluster)
# --------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class CaseTask:
    """What :func:`execute` runs: a case of a scenario file, with where to keep its outputs (or None)."""

    scenario: Path
    case: Case
    out_dir: Path | None = None
    timeout_s: float | None = None


def _connect(dask_address: str) -> Any:
    try:
        from distributed import Client
    except ImportError:  # pragma: no cover - a declared dependency
        raise ConfigError(None, "--dask", "the 'distributed' package is not installed") from None
    try:
        return Client(dask_address, timeout=f"{DASK_CONNECT_TIMEOUT_S}s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise ConfigError(None, "--dask", f"cannot connect to the Dask scheduler at {dask_address!r}: {exc}") from None


def execute(tasks: Sequence[CaseTask], workers: int | None = None, dask_address: str | None = None,
            ) -> Iterator[tuple[CaseTask, dict[str, Any]]]:
    """Run ``tasks`` in parallel and yield ``(task, row)`` as each finishes (completion order).

    Locally ``workers`` threads (default: the number of cores) each wait on one child process; with
    ``dask_address`` every task is submitted to that Dask cluster. Closing the generator early, or an exception in
    the consumer (Ctrl-C), kills the local children and cancels the pending Dask tasks: no result arrives after.
    """
    if not tasks:
        return
    if dask_address is not None:
        yield from _execute_dask(tasks, dask_address)
        return
    n = max(1, int(workers or os.cpu_count() or 1))
    ctl = _ChildControl()
    pool = cf.ThreadPoolExecutor(max_workers=min(n, len(tasks)), thread_name_prefix="railsim-case")
    try:
        futures = {pool.submit(run_case, t.scenario, t.case.overrides, t.case.seed, t.out_dir, t.timeout_s,
                               control=ctl): t for t in tasks}
        for fut in cf.as_completed(futures):
            yield futures[fut], fut.result()
    finally:
        ctl.stop()
        pool.shutdown(wait=True, cancel_futures=True)


def _execute_dask(tasks: Sequence[CaseTask], dask_address: str) -> Iterator[tuple[CaseTask, dict[str, Any]]]:
    from distributed import as_completed

    client = _connect(dask_address)
    futures: dict[Any, CaseTask] = {}
    try:
        for t in tasks:
            fut = client.submit(run_case, str(t.scenario), t.case.overrides, t.case.seed,
                                str(t.out_dir) if t.out_dir else None, t.timeout_s, pure=False,
                                key=f"railsim-case-{t.case.case_id}-{os.urandom(4).hex()}")
            futures[fut] = t
        for fut in as_completed(list(futures)):
            task = futures[fut]
            if fut.status == "error":  # the task itself died (a lost worker): a failed case, like a crash
                row = {"case_id": task.case.case_id, "status": "failed", "seed": task.case.seed,
                       "error": f"Dask task failed: {type(fut.exception()).__name__}: {fut.exception()}"}
                row.update({k: v if _is_scalar(v) else json.dumps(v, separators=(",", ":"), sort_keys=True)
                            for k, v in task.case.overrides.items()})
            else:
                row = fut.result()
            yield task, row
    finally:
        pending = [f for f in futures if not f.done()]
        if pending:
            client.cancel(pending)
        client.close()


# --------------------------------------------------------------------------------------------------------------
# A whole sweep
# --------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SweepResult:
    """What :func:`run_sweep` did: counts over the current definition and where the table is."""

    out_dir: Path
    n_cases: int
    n_ok: int
    n_failed: int
    n_run: int  # cases run by this invocation
    n_skipped: int  # cases already finished before it
    wall_s: float
    interrupted: bool = False

    @property
    def table(self) -> Path:
        return self.out_dir / "cases.parquet"

    def summary_line(self, name: str) -> str:
        rate = self.n_run / self.wall_s * 60.0 if self.wall_s > 0 and self.n_run else 0.0
        state = "interrupted: " if self.interrupted else ""
        return (f"sweep {name}: {state}{self.n_cases} cases, {self.n_ok} ok, {self.n_failed} failed "
                f"({self.n_run} run now, {self.n_skipped} already done) in {self.wall_s:.0f} s wall "
                f"({rate:.1f} cases/min) -> {self.out_dir}/cases.parquet, cases.csv")


def _rows_dir(out_dir: Path) -> Path:
    return Path(out_dir) / "rows"


def read_rows(out_dir: Path) -> dict[str, dict[str, Any]]:
    """The persisted rows of a sweep folder, by case id (unreadable half-files cannot exist: writes are atomic)."""
    rows: dict[str, dict[str, Any]] = {}
    folder = _rows_dir(out_dir)
    if folder.is_dir():
        for path in sorted(folder.glob("*.json")):
            rows[path.stem] = json.loads(path.read_text(encoding="utf-8"))
    return rows


def _check_folder(spec: SweepSpec, out_dir: Path) -> None:
    stored = out_dir / "sweep.yaml"
    if stored.is_file():
        import yaml

        old = yaml.safe_load(stored.read_text(encoding="utf-8")) or {}
        if old.get("base_sha256") not in (None, spec.base_sha256):
            raise ConfigError(stored, "base_sha256", f"this folder holds a sweep of a different version of the base "
                              f"scenario ({old.get('base')}); use a new --out folder (or delete this one)")


def _table_rows(spec: SweepSpec, rows: Mapping[str, dict[str, Any]]) -> tuple[list[dict[str, Any]], list[str]]:
    table: list[dict[str, Any]] = []
    metric_cols: set[str] = set()
    for case in spec.cases:
        row = rows.get(case.case_id)
        if row is None:
            continue
        row = dict(row)
        row.update(case.labels)  # labels come from the current definition (they are not hashed)
        for col in spec.label_columns:
            row.setdefault(col, None)
        table.append(row)
        metric_cols.update(row)
    head = ["case_id", "status", "error", "seed", *spec.label_columns, *spec.override_columns, "wall_s"]
    columns = head + sorted(metric_cols - set(head))
    return table, columns


def _uniform_types(rows: list[dict[str, Any]], columns: Sequence[str]) -> list[dict[str, Any]]:
    """Parquet needs one type per column: a column mixing text and numbers becomes text."""
    out = [dict(r) for r in rows]
    for col in columns:
        kinds = {("num" if isinstance(r.get(col), (int, float)) and not isinstance(r.get(col), bool)
                  else type(r.get(col)).__name__) for r in out if r.get(col) is not None}
        if len(kinds) > 1:
            for r in out:
                if r.get(col) is not None:
                    r[col] = str(r[col])
    return out


def write_tables(spec: SweepSpec, out_dir: Path) -> int:
    """Rebuild ``cases.parquet`` and ``cases.csv`` from ``rows/`` (current cases, expansion order); row count."""
    rows, columns = _table_rows(spec, read_rows(out_dir))
    rows = _uniform_types(rows, columns)
    output.write_csv(Path(out_dir) / "cases.csv", rows, columns)
    output.write_parquet(Path(out_dir) / "cases.parquet", rows, columns)
    return len(rows)


def load_table(out_dir: str | Path) -> Any:
    """The cases table of a sweep folder as a pandas DataFrame."""
    import pandas as pd

    return pd.read_parquet(Path(out_dir) / "cases.parquet")


class _TermAsInterrupt:
    """SIGTERM behaves like Ctrl-C while a sweep runs (so ``kill PID`` also stops it cleanly)."""

    def __enter__(self) -> None:
        self.previous = None
        if threading.current_thread() is threading.main_thread():
            def handler(signum: int, frame: Any) -> None:
                raise KeyboardInterrupt

            self.previous = signal.signal(signal.SIGTERM, handler)

    def __exit__(self, *exc: Any) -> None:
        if self.previous is not None:
            signal.signal(signal.SIGTERM, self.previous)


def run_sweep(sweep: str | Path | SweepSpec, out_dir: str | Path, workers: int | None = None,
              dask_address: str | None = None, retry_failed: bool = False, keep_runs: bool = False,
              timeout_s: float | None = None, progress: bool | None = None,
              on_row: Callable[[Case, dict[str, Any]], None] | None = None) -> SweepResult:
    """Validate every case, run those not finished yet in ``out_dir``, and rebuild its tables (module docstring).

    ``timeout_s`` (or the file's ``timeout_s``) limits each case's wall clock. ``progress``: tqdm bar, default
    only on a terminal. Ctrl-C (KeyboardInterrupt) or SIGTERM kills the running children, keeps every finished row,
    rebuilds the tables and re-raises.
    """
    spec = sweep if isinstance(sweep, SweepSpec) else load_sweep(sweep)
    if workers is not None and workers < 1:
        raise ConfigError(None, "--workers", f"expected an integer >= 1, got {workers}")
    if timeout_s is not None and timeout_s <= 0:
        raise ConfigError(None, "--timeout", f"expected seconds > 0, got {timeout_s}")
    out = Path(out_dir)
    _check_folder(spec, out)
    validate_cases(spec)
    out.mkdir(parents=True, exist_ok=True)
    output.write_yaml(out / "sweep.yaml", {**spec.raw, "base_sha256": spec.base_sha256,
                                           "n_cases": len(spec.cases)})
    done = read_rows(out)
    todo = [c for c in spec.cases if c.case_id not in done
            or (retry_failed and done[c.case_id].get("status") != "ok")]
    limit = timeout_s if timeout_s is not None else spec.timeout_s
    tasks = [CaseTask(spec.base, c, out / "runs" / c.case_id if keep_runs else None, limit) for c in todo]
    show = sys.stderr.isatty() if progress is None else progress
    bar = None
    if show:
        from tqdm import tqdm

        bar = tqdm(total=len(spec.cases), initial=len(spec.cases) - len(todo), unit="case", desc=spec.name)
    t0 = time.perf_counter()
    n_run = 0
    interrupted = False
    try:
        with _TermAsInterrupt():
            gen = execute(tasks, workers=workers, dask_address=dask_address)
            try:
                for task, row in gen:
                    output.write_json(_rows_dir(out) / f"{task.case.case_id}.json", row)
                    n_run += 1
                    if on_row is not None:
                        on_row(task.case, row)
                    if bar is not None:
                        bar.update(1)
            finally:
                gen.close()
    except KeyboardInterrupt:
        interrupted = True
        raise
    finally:
        if bar is not None:
            bar.close()
        write_tables(spec, out)
        rows = read_rows(out)
        statuses = [rows[c.case_id].get("status") for c in spec.cases if c.case_id in rows]
        result = SweepResult(out_dir=out, n_cases=len(spec.cases), n_ok=statuses.count("ok"),
                             n_failed=sum(1 for s in statuses if s != "ok"), n_run=n_run,
                             n_skipped=len(spec.cases) - len(todo), wall_s=time.perf_counter() - t0,
                             interrupted=interrupted)
        if interrupted:
            print(result.summary_line(spec.name), file=sys.stderr)
    return result


# --------------------------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------------------------


def cmd_sweep(args: argparse.Namespace) -> int:
    if args.workers is not None and args.dask is not None:
        raise ConfigError(None, "--workers", "give either --workers (local processes) or --dask (a cluster)")
    spec = load_sweep(args.sweep)
    result = run_sweep(spec, args.out, workers=args.workers, dask_address=args.dask, retry_failed=args.retry_failed,
                       keep_runs=args.keep_runs, timeout_s=args.timeout, progress=False if args.no_progress else None)
    print(result.summary_line(spec.name))
    return 0 if result.n_failed == 0 else 1


def add_commands(sub: Any) -> None:
    p = sub.add_parser("sweep", help="run a base scenario over a grid/list of overrides (resumable), one table",
                       description="Run every case of a sweep file in its own process, locally or on a Dask "
                       "cluster; re-running the same command resumes (finished cases are skipped).")
    p.add_argument("sweep", metavar="SWEEP", help="sweep YAML file (base scenario, grid, cases, seeds)")
    p.add_argument("--out", required=True, help="sweep folder: rows/, cases.parquet, cases.csv, sweep.yaml")
    p.add_argument("--workers", type=int, default=None, help="local worker processes (default: number of cores)")
    p.add_argument("--dask", default=None, metavar="ADDRESS", help="run on this Dask scheduler (tcp://host:8786)")
    p.add_argument("--retry-failed", action="store_true", help="run failed cases again")
    p.add_argument("--keep-runs", action="store_true", help="keep every case's run outputs under DIR/runs/<case_id>")
    p.add_argument("--timeout", type=float, default=None, metavar="S", help="wall-clock limit per case [s]")
    p.add_argument("--no-progress", action="store_true", help="no progress bar even on a terminal")
    p.set_defaults(func=cmd_sweep)
    from railsim.studies import headway

    headway.add_commands(sub)
