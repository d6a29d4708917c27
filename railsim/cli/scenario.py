"""``railsim validate SCENARIO``: check a scenario file without running it.

Two levels, both on by default:

1. the schema (:func:`railsim.scenario.load`): keys, types, ranges, references, controller parameters;
2. everything ``railsim run`` checks before its first step: the engine's :class:`railsim.engine.Simulation` is
   built with no output folder and never run, so validate and run share one set of checks and one message for
   each mistake (:func:`railsim.studies.world.run_checks`) — the world (built with ``network.build``, cached by content hash, or a user's ``.net.xml``
   read as it is) and every station and switch id the scenario names; a route between each service's stations
   (none, or one that needs a reversal); formation trip references and coupling stations (``couple:
   on_departure`` needs the leader to stop at the follower's origin, ``at_station`` a station on both routes);
   insertion positions on the first edge; the interlocking and the free-run timetables. SUMO is not started.
   ``--no-world-check`` skips this level (fast, no netconvert).

Prints ``ok: <name>: N services, M trips, K formations`` and exits 0; a user mistake is one line on stderr and
exit code 2 (the error handling lives in :mod:`railsim.cli.main`).
"""

from __future__ import annotations

import argparse
import sys

from railsim import scenario as scenario_mod
from railsim.studies.world import run_checks


def validate(args: argparse.Namespace) -> int:
    scn = scenario_mod.load(args.scenario)
    if args.world_check:
        skipped = run_checks(scn)
        if skipped:
            print(f"railsim: warning: {skipped}", file=sys.stderr)
    print(f"ok: {scn.name}: {len(scn.services)} services, {scn.n_trips} trips, {len(scn.formations)} formations")
    return 0


def add_commands(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "validate",
        help="check a scenario file without running it",
        description="Validate a scenario file: schema, references, controller parameters and (by default) every "
        "check railsim run makes before its first step (world, routes, formations, insertion, interlocking), "
        "without starting SUMO.",
    )
    p.add_argument("scenario", metavar="SCENARIO", help="scenario YAML file")
    p.add_argument(
        "--world-check",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="build the world and make run's checks before the first step (default: on)",
    )
    p.set_defaults(func=validate)
