"""``railsim run``: run one scenario and write its outputs (a thin layer over :func:`railsim.api.run`).

Exit codes: 0 the run went through; 1 a collision (railsim's or SUMO's); 2 bad input; 3 the run could not
continue (a desync, a stall: one line from :class:`railsim.errors.SimulationError`) or a train was never
inserted (the summary names it), or its outputs could not be written (a full disk, a file-size limit: the
folder is left as it was) or the folder is in use by another run; 130/143 Ctrl-C (SIGINT)/SIGTERM stopped it —
the outputs up to the simulated time reached are written and ``summary.json`` says ``status: interrupted``
(:mod:`railsim.engine.interrupt`); one that comes after the last step stops nothing, and the run exits with its
own code. The folder holds this run's files only (docs/guide/run-folders.md).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from railsim.cli import values
from railsim.errors import ConfigError, SimulationError
from railsim.record.snapshot import OUTPUT_FILES, output_file_name


def add_commands(sub: Any) -> None:
    p = sub.add_parser("run", help="run a scenario and write trips/stops/formations/events/summary")
    p.add_argument("scenario", type=values.path, help="scenario YAML file")
    p.add_argument(
        "--out",
        required=True,
        type=values.path,
        help="output folder: holds this run only, written as a whole (docs/guide/run-folders.md)",
    )
    p.add_argument("--seed", type=values.seed, default=None, help="override the scenario's seed")
    p.add_argument("--no-progress", action="store_true", help="no progress bar even on a terminal")
    p.add_argument("--gui", action="store_true", help="run it in sumo-gui (through traci: slower, for looking)")
    p.set_defaults(func=cmd_run)


def format_summary(summary: dict[str, Any], out_dir: Path) -> str:
    lines = [
        f"scenario {summary['scenario']} (seed {summary['seed']}): simulated {summary['sim_s']:.0f} s in "
        f"{summary['wall_s']:.1f} s wall ({summary['steps']} steps of {summary['step_s']:g} s)",
        f"  trains: {summary['n_arrived']}/{summary['n_trains']} arrived; stops served "
        f"{summary['n_stops_served']}/{summary['n_stops_scheduled']} (missed {summary['n_stops_missed']}); "
        f"max stopping error {summary['max_stopping_error_m'] if summary['max_stopping_error_m'] is None else round(summary['max_stopping_error_m'], 3)} m",
        f"  safety: {summary['collisions']} collisions (railsim: {summary['collisions_railsim']}, "
        f"SUMO: {summary['sumo_collisions']}), "
        f"{summary['switch_violations']} switch violations, min gap "
        f"{'n/a' if summary['min_gap_m'] is None else format(summary['min_gap_m'], '.1f')} m, "
        f"{summary['fallbacks']} controller fallbacks",
    ]
    if summary.get("status") == "interrupted":
        lines.append(
            f"  interrupted ({summary['interrupted_by']}): {summary['n_never_inserted']} train(s) not inserted yet"
        )
    elif summary["n_never_inserted"]:
        lines.append(
            f"  never inserted: {summary['n_never_inserted']} train(s): {', '.join(summary['never_inserted'])} "
            "(see the never_inserted events for why)"
        )
    for svc, rt in summary["mean_running_time_s"].items():
        lines.append(f"  mean running time {svc}: {rt / 60:.1f} min")
    if summary["formations"]:
        ok = sum(1 for f in summary["formations"].values() if (f["couple_successes"] or 0) > 0)
        lines.append(f"  formations: {ok}/{len(summary['formations'])} coupled at least once")
        for fid, because in (summary.get("formations_not_coupling") or {}).items():
            lines.append(f"  formation {fid} cannot couple on departure: {because}")
    asked = summary.get("formations_asked")
    if asked:
        ok = sum(1 for f in asked if f["coupled"])
        why: dict[str, int] = {}
        for f in asked:
            if not f["coupled"]:
                why[str(f["reason"])] = why.get(str(f["reason"]), 0) + 1
        reasons = "".join(f", {n} {r}" for r, n in sorted(why.items()))
        lines.append(f"  formations coupled where asked: {ok}/{len(asked)}{reasons}")
        for f in asked:
            on_run = f.get("on_run")
            if on_run:
                gap = on_run["least_gap_m"]
                where = "not past the merge yet" if gap is None else f"at best {gap:g} m behind it"
                lines.append(
                    f"  formation {f['id']} cannot couple on the run after its merge: its follower may pass "
                    f"{on_run['switch_interval_s']:g} s after its leader, which stands {on_run['leader_to_halt_s']:g} s "
                    f"after the merge; {on_run['hold_s']:g} s before that (the coupled state's hold) the follower is {where} "
                    f"(target {on_run['target_gap_m']:g} m): it couples standing"
                )
    shown = [f for f in OUTPUT_FILES if f.kind != "sumo" and f.stem not in ("scenario.resolved", "versions")]
    files = ", ".join([*(f.file_name for f in shown), output_file_name("sumo_run")])
    lines.append(f"  outputs: {out_dir}/ ({files})")
    for table in summary.get("analysis_tables", ()):
        lines.append(table)
    return "\n".join(lines)


def cmd_run(args: argparse.Namespace) -> int:
    from railsim import api, scenario
    from railsim.engine.interrupt import stop_on_signals

    out = Path(args.out)
    progress = False if args.no_progress else None
    with stop_on_signals() as stop:
        try:
            scn = scenario.load(args.scenario)
            summary = api.run(scn, out, seed=args.seed, progress=progress, stop=stop, gui=args.gui)
        except (ConfigError, SimulationError):
            if stop.signum is None:
                raise
            # the signal reached a child first (netconvert building the world): nothing ran, nothing to write
            print(f"railsim: interrupted ({stop.reason}) before the first step; no outputs", file=sys.stderr)
            return stop.exit_code
    print(format_summary(summary, out))
    if summary["status"] == "interrupted":  # a signal noted once the steps were over stopped nothing: exit as run
        print(f"railsim: interrupted ({stop.reason}) at t = {summary['sim_s']:g} s; outputs so far in {out}/")
        return stop.exit_code
    return exit_code(summary)


def exit_code(summary: dict[str, Any]) -> int:
    """1 on any collision (railsim's or SUMO's), else 3 if a train was never inserted, else 0."""
    from railsim.errors import EXIT_SIMULATION_ERROR

    if summary["collisions"] > 0:
        return 1
    return EXIT_SIMULATION_ERROR if summary["n_never_inserted"] else 0
