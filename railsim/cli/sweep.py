"""``railsim sweep``: run a base scenario over a grid/list of overrides, resumably, into one table.

    railsim sweep SWEEP.yaml --out DIR [--workers N | --dask ADDRESS] [--retry-failed] [--keep-runs] [--timeout S]

A thin layer over :func:`railsim.studies.sweep.run_sweep` (the sweep file, the folder layout and the columns are
described in :mod:`railsim.studies.sweep`). Prints the one-line :meth:`~railsim.studies.sweep.SweepResult.summary_line`;
exits 0 when every case is ok, 1 when some case failed, 2 on bad input (:mod:`railsim.cli.main`).
"""

from __future__ import annotations

import argparse
from typing import Any

from railsim.cli import values
from railsim.errors import ConfigError
from railsim.studies.sweep import load_sweep, run_sweep


def require_one_backend(args: argparse.Namespace) -> None:
    """``--workers`` (local processes) and ``--dask`` (a cluster) exclude each other (also for ``min-headway``)."""
    if args.workers is not None and args.dask is not None:
        raise ConfigError(None, "--workers", "give either --workers (local processes) or --dask (a cluster)")


def cmd_sweep(args: argparse.Namespace) -> int:
    require_one_backend(args)
    spec = load_sweep(args.sweep)
    result = run_sweep(
        spec,
        args.out,
        workers=args.workers,
        dask_address=args.dask,
        retry_failed=args.retry_failed,
        keep_runs=args.keep_runs,
        timeout_s=args.timeout,
        progress=False if args.no_progress else None,
    )
    print(result.summary_line(spec.name))
    return 0 if result.n_failed == 0 else 1


def add_commands(sub: Any) -> None:
    p = sub.add_parser(
        "sweep",
        help="run a base scenario over a grid/list of overrides (resumable), one table",
        description="Run every case of a sweep file in its own process, locally or on a Dask "
        "cluster; re-running the same command resumes (finished cases are skipped).",
    )
    p.add_argument(
        "sweep", metavar="SWEEP", type=values.path, help="sweep YAML file (base scenario, grid, cases, seeds)"
    )
    p.add_argument(
        "--out", required=True, type=values.path, help="sweep folder: rows/, cases.parquet, cases.csv, sweep.yaml"
    )
    p.add_argument(
        "--workers", type=values.count, default=None, help="local worker processes (default: number of cores)"
    )
    p.add_argument("--dask", default=None, metavar="ADDRESS", help="run on this Dask scheduler (tcp://host:8786)")
    p.add_argument("--retry-failed", action="store_true", help="run failed cases again")
    p.add_argument("--keep-runs", action="store_true", help="keep every case's run outputs under DIR/runs/<case_id>")
    p.add_argument("--timeout", type=values.seconds, default=None, metavar="S", help="wall-clock limit per case [s]")
    p.add_argument("--no-progress", action="store_true", help="no progress bar even on a terminal")
    p.set_defaults(func=cmd_sweep)
