"""``railsim robustness``: Monte-Carlo primary delays on one scenario, punctuality with 95 % intervals.

    railsim robustness SCENARIO --runs N --out DIR [--headways 110,130,150] [--services a,b]
                       [--intensities 0.5,1,2] [--disturbances FILE] [--first-seed S] [--baseline-runs K]
                       [--workers K | --dask ADDRESS]

A thin layer over :func:`railsim.studies.robustness.run_robustness` (what is run, the knock-on definition and
the verdict are described there). Resumable: the same command again skips finished runs. Prints one line per
(headway, intensity) and the report's path; exits 0 when every run finished, 1 when some failed, 2 on bad input.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from railsim.cli import values
from railsim.cli.sweep import require_one_backend
from railsim.errors import ConfigError


def float_list(text: str | None, option: str) -> tuple[float, ...]:
    """``"110,130,150"`` → (110.0, 130.0, 150.0); ConfigError naming the option otherwise."""
    if not text:
        return ()
    try:
        return tuple(float(x) for x in text.split(",") if x.strip())
    except ValueError:
        raise ConfigError("<command line>", option, f"expected comma-separated numbers, got {text!r}") from None


def cmd_robustness(args: argparse.Namespace) -> int:
    from railsim.studies.robustness import RobustnessPlan, headway_paths, load_disturbances, run_robustness

    require_one_backend(args)
    scenario = Path(args.scenario)
    if not scenario.is_file():
        raise ConfigError(args.scenario, None, "expected a scenario file, found none")
    headways = float_list(args.headways, "--headways")
    services = [s.strip() for s in (args.services or "").split(",") if s.strip()] or None
    plan = RobustnessPlan(
        scenario=scenario,
        runs=args.runs,
        first_seed=args.first_seed,
        headway_paths=headway_paths(scenario, services) if headways else (),
        headways_s=headways,
        intensities=float_list(args.intensities, "--intensities"),
        disturbances=load_disturbances(Path(args.disturbances)) if args.disturbances else None,
        disturbances_source=Path(args.disturbances) if args.disturbances else None,
        baseline_runs=args.baseline_runs,
        label=args.label or scenario.stem,
    )
    result = run_robustness(
        plan, args.out, workers=args.workers, dask_address=args.dask, progress=False if args.no_progress else None
    )
    for g in result["groups"]:
        k = g["kpis"]
        pf = k["excess_propagation_factor"]
        w3 = k["robustness.within_3min"]
        print(
            f"headway {g['headway_s']} s, intensity {g['intensity']:g}: {g['n_ok']}/{g['n_runs']} runs; "
            f"≤3 min {100 * (w3['mean'] or 0):.1f} ± {100 * (w3['ci95'] or 0):.1f} %; "
            f"excess propagation {pf['mean'] if pf['mean'] is not None else float('nan'):.2f}"
            f" ± {pf['ci95'] or 0:.2f}"
        )
    print(f"report: {Path(args.out) / 'robustness.md'}")
    return 0 if all(g["n_failed"] == 0 for g in result["groups"]) else 1


def add_robustness_options(p: Any) -> None:
    """Options shared with ``railsim study vc-vs-mb --disturbances``."""
    p.add_argument("--runs", type=values.count, default=20, help="Monte-Carlo runs (seeds) per point (default 20)")
    p.add_argument("--first-seed", type=values.seed, default=1, help="seeds first-seed … first-seed + runs − 1")
    p.add_argument("--intensities", default=None, help="comma-separated disturbances.intensity values to sweep")
    p.add_argument("--baseline-runs", type=values.count, default=1, help="undisturbed runs per headway (default 1)")


def add_commands(sub: Any) -> None:
    p = sub.add_parser(
        "robustness",
        help="Monte-Carlo primary delays: punctuality, knock-on and propagation with 95 %% intervals",
        description="Run a disturbed scenario many times (seeds) at one or more headways, resumably, and report "
        "punctuality, knock-on delay and the stability curve (DIR/robustness.md).",
    )
    p.add_argument(
        "scenario",
        metavar="SCENARIO",
        type=values.path,
        help="scenario file (with a disturbances: section, or --disturbances)",
    )
    p.add_argument(
        "--out", required=True, type=values.path, help="output folder (runs/, baseline/, robustness.md/.json, plots)"
    )
    add_robustness_options(p)
    p.add_argument("--headways", default=None, help="comma-separated headways [s] of the headway services")
    p.add_argument("--services", default=None, help="services whose headway moves (default: all timetabled by headway)")
    p.add_argument(
        "--disturbances",
        default=None,
        metavar="FILE",
        type=values.path,
        help="replace the scenario's disturbances: section",
    )
    p.add_argument("--label", default=None, help="name in the report (default: the scenario's file name)")
    p.add_argument(
        "--workers", type=values.count, default=None, help="local worker processes (default: number of cores)"
    )
    p.add_argument("--dask", default=None, metavar="ADDRESS", help="run on this Dask scheduler (tcp://host:8786)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar even on a terminal")
    p.set_defaults(func=cmd_robustness)
