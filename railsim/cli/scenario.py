"""``railsim validate SCENARIO``: check a scenario file without running it.

Two levels, both on by default:

1. the schema (:func:`railsim.scenario.load`): keys, types, ranges, references, controller parameters;
2. the world (:func:`railsim.studies.world.world_check`): the world is built with ``network.build`` (cached
   by content hash, so only the first build runs netconvert) and every station and switch id the scenario
   names must exist in it. ``--no-world-check`` skips this level (fast, no netconvert).

Prints ``ok: <name>: N services, M trips, K formations`` and exits 0; a user mistake is one line on stderr and
exit code 2 (the error handling lives in :mod:`railsim.cli.main`).
"""

from __future__ import annotations

import argparse
import sys

from railsim import scenario as scenario_mod
from railsim.studies.world import world_check


def validate(args: argparse.Namespace) -> int:
    scn = scenario_mod.load(args.scenario)
    if args.world_check:
        skipped = world_check(scn)
        if skipped:
            print(f"railsim: warning: {skipped}", file=sys.stderr)
    print(f"ok: {scn.name}: {len(scn.services)} services, {scn.n_trips} trips, {len(scn.formations)} formations")
    return 0


def add_commands(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "validate",
        help="check a scenario file without running it",
        description="Validate a scenario file: schema, references, controller parameters and (by default) the "
        "station/switch ids against the built world.",
    )
    p.add_argument("scenario", metavar="SCENARIO", help="scenario YAML file")
    p.add_argument(
        "--world-check",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="build the world and check station/switch ids (default: on)",
    )
    p.set_defaults(func=validate)
