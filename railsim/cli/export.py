"""``railsim export``: write a run's tables (or a sweep's cases) as CSV, Parquet or JSON.

    railsim export DIR [--format csv|parquet|json] [--out OUT] [--trace]

A thin layer over :func:`railsim.report.export.export` (tables and formats are described in
:mod:`railsim.report.export`); prints every file written and the pandas call that reads them back.
"""

from __future__ import annotations

import argparse
from typing import Any

from railsim.cli import values
from railsim.report.export import FORMATS, READERS, export


def add_commands(sub: Any) -> None:
    p = sub.add_parser(
        "export",
        help="write a run's trip/stop/formation/event/section tables (or a sweep's cases) as CSV, Parquet or JSON",
    )
    p.add_argument("folder", type=values.path, help="run folder (railsim run) or sweep folder (railsim sweep)")
    p.add_argument(
        "--format",
        choices=FORMATS,
        default="csv",
        dest="fmt",
        help='read back with pd.read_csv, pd.read_parquet or pd.read_json(path, orient="records")',
    )
    p.add_argument("--out", default=None, type=values.path, help="output folder (default: FOLDER/export)")
    p.add_argument("--trace", action="store_true", help="also export the per-train trace (large)")
    p.set_defaults(func=cmd_export)


def cmd_export(args: argparse.Namespace) -> int:
    paths = export(args.folder, args.fmt, args.out, include_trace=args.trace)
    for path in paths:
        print(path)
    print(f"read each with: {READERS[args.fmt].format(path=paths[0].parent / ('<table>.' + args.fmt))}")
    return 0
