"""The ``railsim`` command: a thin layer over the Python API.

Subcommands, one module of :mod:`railsim.cli` per command group (each a function over the public API, so a
notebook can do the same)::

    railsim network build NAME|FILE --out DIR   build a world (net.xml, stops.add.xml, topology.json)   cli.network
    railsim network show NAME|FILE              readable summary of a world                              cli.network
    railsim network import OSM --out DIR        rail world from an OpenStreetMap extract                 cli.network
    railsim timetable import FEED --world DIR   scenario from a GTFS feed (or --from-lines)              cli.timetable
    railsim validate SCENARIO                   check a scenario file without running it                 cli.scenario
    railsim run SCENARIO --out DIR [--seed N]   run one simulation and write its outputs                 cli.run
    railsim reproduce EXPERIMENT --out DIR      re-run a paper experiment and draw its figures           cli.reproduce
    railsim plot RUN... [--kind K] [--out DIR]  figures of finished runs                                 cli.plot
    railsim sweep SWEEP --out DIR               many overridden runs of one scenario, one table          cli.sweep
    railsim robustness SCENARIO --runs N ...    Monte-Carlo primary delays: punctuality, knock-on         cli.robustness
    railsim min-headway SCENARIO --path P ...   minimum feasible headway of a service pattern            cli.headway
    railsim export DIR [--format F]             a run's (or sweep's) tables as CSV/Parquet/JSON          cli.export
    railsim report DIR [--format md|html]       one-page report of a run or a sweep                      cli.report
    railsim study vc-vs-mb --out DIR            line studies                                             cli.study

:data:`COMMAND_GROUPS` lists those modules explicitly, in the order ``railsim --help`` shows them: each has
``add_commands(subparsers)`` and sets ``func`` on its parsers. A missing or misspelt module fails at import.

Exit codes, and nothing else: 0 ok; 1 a run finished with a collision; 2 bad input (a
:class:`railsim.errors.ConfigError`, one line ``railsim: error: <file>: <field>: <message>``; argparse's usage
errors too); 3 a simulation that could not continue (:class:`railsim.errors.SimulationError`) or an environment
error — a full disk, a file-size limit, no permission, a run folder in use (:class:`railsim.errors.RunFolderError`,
any ``OSError``): one line with the path and the OS's reason; 130 Ctrl-C, at any moment, one line; 4 an internal
error — a bug in railsim, including ``RecursionError`` and ``MemoryError``: one line naming the exception and a
log file that holds the traceback (:func:`report_internal_error`), never a bare traceback on the terminal.
A reader that closes the output early (``railsim ... | head``) ends the command quietly, exit 0.
"""

from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import tempfile
import traceback
from collections.abc import Callable, Sequence
from types import ModuleType

from railsim.cli import (
    export,
    headway,
    network,
    plot,
    report,
    reproduce,
    robustness,
    run,
    scenario,
    study,
    sweep,
    timetable,
    values,
)
from railsim.errors import (
    EXIT_CONFIG_ERROR,
    EXIT_INTERNAL_ERROR,
    EXIT_SIMULATION_ERROR,
    ConfigError,
    RunFolderError,
    SimulationError,
)

# The command groups, in help order; each module has ``add_commands(subparsers)``.
COMMAND_GROUPS: tuple[ModuleType, ...] = (
    network,
    timetable,
    scenario,
    run,
    reproduce,
    plot,
    sweep,
    robustness,
    headway,
    export,
    report,
    study,
)


def build_parser() -> argparse.ArgumentParser:
    parser = values.OneLineParser(prog="railsim", description="Virtually coupled trains on SUMO rail networks.")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output (-vv for debug)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for group in COMMAND_GROUPS:
        group.add_commands(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    if hasattr(signal, "SIGXFSZ"):  # a file-size limit (ulimit -f) must be an error on write, not a killed process
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.WARNING - 10 * min(args.verbose, 2)
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    func: Callable[[argparse.Namespace], int] | None = getattr(args, "func", None)
    if func is None:
        parser.print_help()
        return 0
    return run_guarded(lambda: int(func(args) or 0), argv)


def run_guarded(body: Callable[[], int], argv: Sequence[str] | None = None) -> int:
    """Run ``body`` (a command) and turn what it raises into the exit codes of the module docstring, one line on
    stderr each; ``argv`` goes into an internal error's log file."""
    try:
        return body()
    except ConfigError as err:
        print(f"railsim: error: {err}", file=sys.stderr)
        return EXIT_CONFIG_ERROR
    except SimulationError as err:
        print(f"railsim: simulation error: {err}", file=sys.stderr)
        return EXIT_SIMULATION_ERROR
    except RunFolderError as err:
        print(f"railsim: error: {err}", file=sys.stderr)
        return EXIT_SIMULATION_ERROR
    except OSError as err:  # the machine refused: a path and the OS's words, not a bug
        print(f"railsim: error: {environment_message(err)}", file=sys.stderr)
        return EXIT_SIMULATION_ERROR
    except KeyboardInterrupt:
        print("railsim: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # whoever read our output stopped reading (`railsim ... | head`): not a failure
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # so the exit flush does not fail again
        return 0
    except Exception as exc:  # noqa: BLE001 - the last guard: a bug must not print a bare traceback
        return report_internal_error(exc, argv)


def environment_message(err: OSError) -> str:
    """``PATH: OS reason`` for an OS error (the path escaped and bounded, as every quoted user value)."""
    from railsim.inputs import excerpt

    reason = err.strerror or type(err).__name__
    path = err.filename if err.filename is not None else None
    return f"{excerpt(str(path), 200)[1:-1]}: {reason}" if path is not None else f"{reason}"


def report_internal_error(exc: BaseException, argv: Sequence[str] | None) -> int:
    """Write ``exc``'s traceback to a new log file (the temp folder, readable by the user only) and print one line
    naming the exception and the file; returns :data:`EXIT_INTERNAL_ERROR`."""
    lines = [f"railsim internal error; command line: {' '.join(sys.argv[:1] + list(argv or sys.argv[1:]))}\n"]
    lines += traceback.format_exception(type(exc), exc, exc.__traceback__)
    log_name = "(no log file)"
    try:
        fd, log_name = tempfile.mkstemp(prefix="railsim-error-", suffix=".log")
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.writelines(lines)
    except OSError:
        pass
    first = str(exc).splitlines()[0][:200] if str(exc) else ""
    print(
        f"railsim: internal error ({type(exc).__name__}: {first}); this is a bug in railsim, traceback in {log_name}",
        file=sys.stderr,
    )
    return EXIT_INTERNAL_ERROR


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
