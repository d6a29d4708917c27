"""``railsim timetable import``: a scenario from a GTFS feed, or from an imported world's lines.

    railsim timetable import FEED.zip --world DIR --date YYYY-MM-DD --from HH:MM --to HH:MM --out SCENARIO.yaml
        [--routes R1,R2] [--vclass CLASS] [--turnback-min-s S] [--rotations explicit|auto] [--radius-m M]
    railsim timetable import --from-lines --headway-s H --world DIR --from HH:MM --to HH:MM --out SCENARIO.yaml
        [--lines L1,L2] [--vclass CLASS]

``DIR`` is a folder written by ``railsim network import``. The work is :mod:`railsim.timetable`; bad input is a
ConfigError (one line, exit 2).
"""

from __future__ import annotations

import argparse
import datetime
from typing import Any

from railsim.errors import ConfigError
from railsim.scenario.clock import CLOCK_WHAT, parse_clock


def _clock_arg(value: str, flag: str) -> float:
    try:
        return parse_clock(value)
    except ValueError:
        raise ConfigError("<command line>", flag, f"expected {CLOCK_WHAT}, got {value!r}") from None


def _list(text: str | None) -> list[str] | None:
    return [x.strip() for x in text.split(",") if x.strip()] if text else None


def cmd_import(args: argparse.Namespace) -> int:
    from railsim.timetable import import_timetable, timetable_from_lines

    from_s = _clock_arg(args.from_time, "--from")
    to_s = _clock_arg(args.to_time, "--to")
    if args.from_lines:
        if args.feed is not None:
            raise ConfigError("<command line>", "--from-lines", "expected either a FEED or --from-lines, not both")
        if args.headway_s is None:
            raise ConfigError("<command line>", "--headway-s", "expected a headway in seconds with --from-lines")
        report = timetable_from_lines(
            args.world,
            from_s,
            to_s,
            args.headway_s,
            args.out,
            vclass=args.vclass,
            lines=_list(args.lines),
            turnback_min_s=args.turnback_min_s,
        )
    else:
        if args.feed is None:
            raise ConfigError("<command line>", "FEED", "expected a GTFS feed (.zip), or --from-lines --headway-s H")
        if args.date is None:
            raise ConfigError("<command line>", "--date", "expected the service date YYYY-MM-DD")
        try:
            day = datetime.date.fromisoformat(args.date)
        except ValueError:
            raise ConfigError("<command line>", "--date", f"expected a date YYYY-MM-DD, got {args.date!r}") from None
        report = import_timetable(
            args.feed,
            args.world,
            day,
            from_s,
            to_s,
            args.out,
            routes=_list(args.routes),
            vclass=args.vclass,
            turnback_min_s=args.turnback_min_s,
            rotations=args.rotations,
            radius_m=args.radius_m,
        )
    print(report.text())
    return 0


def add_commands(subparsers: Any) -> None:
    tt = subparsers.add_parser("timetable", help="import a timetable (GTFS, or an imported world's lines)")
    sub = tt.add_subparsers(dest="timetable_command", metavar="ACTION", required=True)
    i = sub.add_parser("import", help="write a scenario from a GTFS feed or from the world's OSM lines")
    i.add_argument("feed", nargs="?", metavar="FEED.zip", help="GTFS feed (omit with --from-lines)")
    i.add_argument("--world", required=True, metavar="DIR", help="folder written by `railsim network import`")
    i.add_argument("--date", metavar="YYYY-MM-DD", help="service date (GTFS)")
    i.add_argument("--from", dest="from_time", required=True, metavar="HH:MM", help="first departure of the window")
    i.add_argument("--to", dest="to_time", required=True, metavar="HH:MM", help="end of the window (exclusive)")
    i.add_argument("--out", required=True, metavar="SCENARIO.yaml", help="scenario file to write")
    i.add_argument(
        "--routes", metavar="R1,R2", help="GTFS route ids or short names to keep (default: every rail route)"
    )
    i.add_argument("--vclass", default=None, help="rail class of the scenario (default: the one most trips match)")
    i.add_argument("--turnback-min-s", type=float, default=180.0, help="minimum turnback between two trips [s]")
    i.add_argument(
        "--rotations",
        choices=("explicit", "auto"),
        default="explicit",
        help="explicit units (block_id, else built) or auto (railsim chains at run time)",
    )
    i.add_argument("--radius-m", type=float, default=300.0, help="position match radius [m]")
    i.add_argument("--from-lines", action="store_true", help="services from the world's imported OSM lines")
    i.add_argument("--headway-s", type=float, default=None, help="headway of --from-lines services [s]")
    i.add_argument("--lines", metavar="L1,L2", help="--from-lines: only these line refs")
    i.set_defaults(func=cmd_import)
