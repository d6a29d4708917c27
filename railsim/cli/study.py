"""``railsim study``: line studies, one subcommand each (today ``vc-vs-mb``).

    railsim study vc-vs-mb --out DIR [--mb SCENARIO] [--vc SCENARIO] [--services a,b] [--lo S --hi S --tol S]
                           [--headway S] [--workers N | --dask ADDRESS] [--sensitivity] [--no-control] [--bisect]
                           [--disturbances FILE [--runs N] [--robust-headways 110,130,150] [--robustness-only]]

``vc-vs-mb`` is a thin layer over :func:`railsim.studies.vc_vs_mb.vc_vs_mb` (moving block vs virtual coupling on
one line; the regimes, the search and the report are described in :mod:`railsim.studies.vc_vs_mb`). It prints one
line per regime and the report's path; exits 0 when every regime has a feasible headway, 1 otherwise, 2 on bad
input. With ``--disturbances FILE`` it adds the robustness comparison
(:mod:`railsim.studies.vc_robustness`: the same seeds in both regimes) as a section of ``vc_vs_mb.md``;
``--robustness-only`` runs only that. ``railsim study`` alone prints the list of studies.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from railsim.cli import values
from railsim.cli.robustness import add_robustness_options, float_list
from railsim.errors import ConfigError
from railsim.studies.vc_vs_mb import DEFAULT_MB, DEFAULT_SERVICES, DEFAULT_VC, vc_vs_mb


def add_commands(sub: Any) -> None:
    p = sub.add_parser("study", help="line studies (vc-vs-mb: virtual coupling vs moving block)")
    studies = p.add_subparsers(dest="study", metavar="STUDY")
    q = studies.add_parser(
        "vc-vs-mb",
        help="minimum headway, capacity, running time, energy and gaps of moving "
        "block vs virtual coupling, side by side (DIR/vc_vs_mb.md)",
    )
    q.add_argument(
        "--out", required=True, type=values.path, help="output folder (probes are kept and reused on a re-run)"
    )
    q.add_argument("--workers", type=values.count, default=1, help="probes run in parallel (default 1)")
    q.add_argument(
        "--mb", default=str(DEFAULT_MB), type=values.path, help="moving-block scenario (default: %(default)s)"
    )
    q.add_argument(
        "--vc", default=str(DEFAULT_VC), type=values.path, help="virtual-coupling scenario (default: %(default)s)"
    )
    q.add_argument(
        "--services",
        default=",".join(DEFAULT_SERVICES),
        help="services whose headway is searched, comma-separated (default: %(default)s)",
    )
    q.add_argument("--lo", type=float, default=70.0, help="lower end of the headway grid [s] (default 70)")
    q.add_argument("--hi", type=float, default=200.0, help="upper end of the headway grid [s] (default 200)")
    q.add_argument("--tol", type=float, default=10.0, help="grid step [s] (default 10)")
    q.add_argument("--max-delay", type=float, default=120.0, help="feasible: max arrival delay [s] (default 120)")
    q.add_argument("--bisect", action="store_true", help="bisect the grid instead of probing every point")
    q.add_argument("--no-control", action="store_true", help="skip regime (c), the control experiment")
    q.add_argument(
        "--sensitivity", action="store_true", help="add the sensitivity block (target gap, t2t delay, formation share)"
    )
    q.add_argument("--dask", default=None, metavar="ADDRESS", help="run probes on this Dask scheduler")
    q.add_argument("--headway", type=float, default=None, help="skip the search: run both regimes at this headway")
    q.add_argument("--no-confirm", action="store_true", help="no confirmation probe with a second seed")
    q.add_argument("--no-progress", action="store_true", help="no progress bar even on a terminal")
    q.add_argument(
        "--disturbances",
        default=None,
        metavar="FILE",
        help="add the robustness comparison: Monte-Carlo primary delays, same seeds in both regimes",
    )
    q.add_argument("--robust-headways", default="110,130,150", help="headways [s] of the robustness runs")
    q.add_argument("--robustness-only", action="store_true", help="skip the capacity search (with --disturbances)")
    add_robustness_options(q)
    q.set_defaults(func=cmd_vc_vs_mb)
    p.set_defaults(func=lambda args: (p.print_help(), 0)[1])


def cmd_vc_vs_mb(args: argparse.Namespace) -> int:
    for name in ("mb", "vc"):
        if not Path(getattr(args, name)).is_file():
            raise ConfigError(getattr(args, name), None, f"expected a scenario file for --{name}, found none")
    if args.workers < 1:
        raise ConfigError("<command line>", "--workers", f"expected an integer >= 1, got {args.workers}")
    services = [s.strip() for s in args.services.split(",") if s.strip()]
    if not services:
        raise ConfigError("<command line>", "--services", "expected at least one service id")
    if args.robustness_only and not args.disturbances:
        raise ConfigError("<command line>", "--robustness-only", "expected --disturbances FILE with it")
    if args.disturbances:  # the robustness runs come last: their input is checked before anything runs
        _check_robustness(args, services)
    if args.robustness_only:
        print(_robustness(args, services))
        return 0
    results = vc_vs_mb(
        args.out,
        mb_scenario=args.mb,
        vc_scenario=args.vc,
        services=services,
        lo_s=args.lo,
        hi_s=args.hi,
        tol_s=args.tol,
        max_delay_s=args.max_delay,
        workers=args.workers,
        dask_address=args.dask,
        headway_s=args.headway,
        confirm=not args.no_confirm,
        scan=not args.bisect,
        control=not args.no_control,
        sensitivity=args.sensitivity,
        progress=False if args.no_progress else None,
    )
    for r in results.values():
        h = "none feasible" if r.headway_s is None else f"{r.headway_s:g} s"
        up = r.metrics.get("up.pax_per_h")
        print(
            f"{r.regime.label}: minimum headway {h}"
            + (
                f"; up {r.metrics['up.trains_per_h']:.0f} trains/h on {r.metrics['up.paths_per_h']:.0f} paths, "
                f"{up:,.0f} passengers/h"
                if up is not None
                else ""
            )
        )
    if args.disturbances:
        report = Path(args.out) / "vc_vs_mb.md"
        report.write_text(report.read_text(encoding="utf-8") + "\n" + _robustness(args, services), encoding="utf-8")
    print(f"report: {Path(args.out) / 'vc_vs_mb.md'}")
    return 0 if all(r.headway_s is not None for r in results.values()) else 1


def _check_robustness(args: argparse.Namespace, services: list[str]) -> None:
    """Both regimes' robustness plans checked as ``railsim robustness`` checks its own, the disturbances file
    named as the user's."""
    from railsim.studies.robustness import check_plan, load_disturbances
    from railsim.studies.vc_robustness import regime_plans

    source = Path(args.disturbances)
    plans = regime_plans(
        Path(args.mb),
        Path(args.vc),
        load_disturbances(source),
        float_list(args.robust_headways, "--robust-headways"),
        services,
        runs=args.runs,
        first_seed=args.first_seed,
        baseline_runs=args.baseline_runs,
        intensities=float_list(args.intensities, "--intensities"),
        disturbances_source=source,
    )
    for plan in plans.values():
        check_plan(plan)


def _robustness(args: argparse.Namespace, services: list[str]) -> str:
    """The disturbed comparison (:func:`railsim.studies.vc_robustness.compare_robustness`); its report section."""
    from railsim.studies.robustness import load_disturbances
    from railsim.studies.vc_robustness import compare_robustness

    text = compare_robustness(
        args.out,
        Path(args.mb),
        Path(args.vc),
        load_disturbances(Path(args.disturbances)),
        float_list(args.robust_headways, "--robust-headways"),
        services,
        runs=args.runs,
        first_seed=args.first_seed,
        baseline_runs=args.baseline_runs,
        intensities=float_list(args.intensities, "--intensities"),
        workers=args.workers,
        dask_address=args.dask,
        progress=False if args.no_progress else None,
    )
    print(f"robustness: {Path(args.out) / 'robustness' / 'vc_vs_mb_robustness.md'}")
    return text
