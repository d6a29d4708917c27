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

A **sweep file** (``base:`` + ``grid``/``cases``/``link``/``seeds``, :mod:`railsim.studies.sweep`) is recognised and
checked as a whole: its structure, then the base scenario with every case's overrides at both levels; no case runs
(``ok: sweep <name>: base <file>, N cases``).

Prints ``ok: <name>: N services, M trips, K formations`` and exits 0; a user mistake is one line on stderr and
exit code 2 (the error handling lives in :mod:`railsim.cli.main`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from railsim import scenario as scenario_mod
from railsim.cli import values
from railsim.studies.world import run_checks


def validate(args: argparse.Namespace) -> int:
    path = Path(args.scenario)
    data = scenario_mod.parse_yaml(scenario_mod.read_text(path, args.scenario), args.scenario)
    if is_sweep(data):
        return validate_sweep(args.scenario, args.world_check)
    scn = scenario_mod.from_mapping(data, source=path, base_dir=path.resolve().parent)  # = scenario.load(path)
    if args.world_check:
        skipped = run_checks(scn)
        if skipped:
            print(f"railsim: warning: {skipped}", file=sys.stderr)
    print(f"ok: {scn.name}: {len(scn.services)} services, {scn.n_trips} trips, {len(scn.formations)} formations")
    return 0


def is_sweep(data: Any) -> bool:
    """True if a parsed file is a sweep definition (a mapping with ``base:`` and no ``world:``), not a scenario."""
    return isinstance(data, dict) and "base" in data and "world" not in data


def validate_sweep(path: str, world_check: bool) -> int:
    """The sweep file's structure, then the base scenario with every case's overrides (and, with the world check,
    every check ``railsim run`` makes before its first step), without running any case."""
    from railsim.studies.sweep import load_sweep, validate_cases

    spec = load_sweep(path)
    validate_cases(spec, world_check=world_check, full=True)
    print(f"ok: sweep {spec.name}: base {spec.base.name}, {len(spec.cases)} cases")
    return 0


def add_commands(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "validate",
        help="check a scenario file without running it",
        description="Validate a scenario file: schema, references, controller parameters and (by default) every "
        "check railsim run makes before its first step (world, routes, formations, insertion, interlocking), "
        "without starting SUMO.",
    )
    p.add_argument(
        "scenario",
        metavar="SCENARIO",
        type=values.path,
        help="scenario YAML file (or a sweep file: every case is checked)",
    )
    p.add_argument(
        "--world-check",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="build the world and make run's checks before the first step (default: on)",
    )
    p.set_defaults(func=validate)
