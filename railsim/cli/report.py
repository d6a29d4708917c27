"""``railsim report``: a one-page Markdown or HTML report of a run or a sweep folder.

    railsim report DIR [--format md|html]

A thin layer over :func:`railsim.report.document.write_report` (what the page shows is described in
:mod:`railsim.report.document`); prints the path of the page it wrote.
"""

from __future__ import annotations

import argparse
from typing import Any

from railsim.cli import values
from railsim.report.document import FORMATS, write_report


def add_commands(sub: Any) -> None:
    p = sub.add_parser("report", help="write a one-page Markdown or HTML report of a run or a sweep folder")
    p.add_argument("folder", type=values.path, help="run folder (railsim run) or sweep folder (railsim sweep)")
    p.add_argument(
        "--format",
        choices=FORMATS,
        default="md",
        dest="fmt",
        help="md: report.md with figures linked from report_figures/; html: one self-contained file",
    )
    p.set_defaults(func=cmd_report)


def cmd_report(args: argparse.Namespace) -> int:
    print(write_report(args.folder, args.fmt))
    return 0
