"""The ``railsim`` command: a thin layer over the Python API.

Subcommands (each a function over the public API, so a notebook can do the same)::

    railsim network build NAME|FILE --out DIR   build a world (net.xml, stops.add.xml, topology.json)
    railsim network show NAME|FILE              readable summary of a world
    railsim validate SCENARIO                   check a scenario file without running it
    railsim run SCENARIO --out DIR [--seed N]   run one simulation and write its outputs

User mistakes (:class:`railsim.errors.ConfigError`) print one line ``railsim: error: <file>: <field>: <message>``
and exit with code 2; a simulation that cannot continue exits with code 3. Never a traceback for those.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from typing import Callable, Sequence

from railsim.errors import EXIT_CONFIG_ERROR, EXIT_SIMULATION_ERROR, ConfigError, SimulationError

# Modules that contribute subcommands: each has ``add_commands(subparsers)`` and sets ``func`` on its parsers.
_COMMAND_MODULES = ("railsim.cli.network", "railsim.cli.scenario", "railsim.cli.run", "railsim.studies.reproduce",
                    "railsim.cli.plot", "railsim.studies.sweep", "railsim.report.export", "railsim.report.document", "railsim.studies.vc_vs_mb")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="railsim", description="Virtually coupled trains on SUMO rail networks.")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output (-vv for debug)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for mod_name in _COMMAND_MODULES:
        try:
            mod = importlib.import_module(mod_name)
        except ModuleNotFoundError as exc:
            if exc.name == mod_name:
                continue  # that part of the product is not built yet
            raise
        mod.add_commands(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.WARNING - 10 * min(args.verbose, 2)
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    func: Callable[[argparse.Namespace], int] | None = getattr(args, "func", None)
    if func is None:
        parser.print_help()
        return 0
    try:
        return int(func(args) or 0)
    except ConfigError as err:
        print(f"railsim: error: {err}", file=sys.stderr)
        return EXIT_CONFIG_ERROR
    except SimulationError as err:
        print(f"railsim: simulation error: {err}", file=sys.stderr)
        return EXIT_SIMULATION_ERROR
    except KeyboardInterrupt:
        print("railsim: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
