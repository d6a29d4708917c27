"""A whole sweep: validate every case, run the unfinished ones, persist each row, rebuild the tables.

:func:`run_sweep` is the entry point (``railsim sweep`` is a thin layer over it, :mod:`railsim.cli.sweep`). It
refuses a folder made from a different version of the base scenario (``DIR/sweep.yaml`` keeps its SHA-256), skips
the cases that already have a row (``--retry-failed`` runs the failed ones again), writes each row the moment its
case finishes and rebuilds ``cases.parquet``/``cases.csv`` at the end of every invocation, also after Ctrl-C or
SIGTERM. Its :class:`SweepResult` counts the cases over the current definition.
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from railsim.errors import ConfigError
from railsim.record import output
from railsim.studies.sweep.parallel import CaseTask, execute
from railsim.studies.sweep.spec import Case, SweepSpec, load_sweep, validate_cases
from railsim.studies.sweep.tables import read_rows, write_row, write_tables


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
        return (
            f"sweep {name}: {state}{self.n_cases} cases, {self.n_ok} ok, {self.n_failed} failed "
            f"({self.n_run} run now, {self.n_skipped} already done) in {self.wall_s:.0f} s wall "
            f"({rate:.1f} cases/min) -> {self.out_dir}/cases.parquet, cases.csv"
        )


def _check_folder(spec: SweepSpec, out_dir: Path) -> None:
    stored = out_dir / "sweep.yaml"
    if stored.is_file():
        import yaml

        old = yaml.safe_load(stored.read_text(encoding="utf-8")) or {}
        if old.get("base_sha256") not in (None, spec.base_sha256):
            raise ConfigError(
                stored,
                "base_sha256",
                f"this folder holds a sweep of a different version of the base "
                f"scenario ({old.get('base')}); use a new --out folder (or delete this one)",
            )


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


def run_sweep(
    sweep: str | Path | SweepSpec,
    out_dir: str | Path,
    workers: int | None = None,
    dask_address: str | None = None,
    retry_failed: bool = False,
    keep_runs: bool = False,
    timeout_s: float | None = None,
    progress: bool | None = None,
    on_row: Callable[[Case, dict[str, Any]], None] | None = None,
) -> SweepResult:
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
    validate_cases(spec, full=True)  # every check railsim run makes, before the first case runs
    out.mkdir(parents=True, exist_ok=True)
    output.write_yaml(out / "sweep.yaml", {**spec.raw, "base_sha256": spec.base_sha256, "n_cases": len(spec.cases)})
    done = read_rows(out)
    todo = [c for c in spec.cases if c.case_id not in done or (retry_failed and done[c.case_id].get("status") != "ok")]
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
                    write_row(out, task.case.case_id, row)
                    n_run += 1
                    if on_row is not None:
                        on_row(task.case, row)
                    if bar is not None:
                        bar.update(1)
            finally:
                gen.close()  # type: ignore[attr-defined]
    except KeyboardInterrupt:
        interrupted = True
        raise
    finally:
        if bar is not None:
            bar.close()
        write_tables(spec, out)
        rows = read_rows(out)
        statuses = [rows[c.case_id].get("status") for c in spec.cases if c.case_id in rows]
        result = SweepResult(
            out_dir=out,
            n_cases=len(spec.cases),
            n_ok=statuses.count("ok"),
            n_failed=sum(1 for s in statuses if s != "ok"),
            n_run=n_run,
            n_skipped=len(spec.cases) - len(todo),
            wall_s=time.perf_counter() - t0,
            interrupted=interrupted,
        )
        if interrupted:
            print(result.summary_line(spec.name), file=sys.stderr)
    return result
