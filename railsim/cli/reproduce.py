"""``railsim reproduce``: re-run a paper's numerical experiment and write its tables and figures.

    railsim reproduce paper000 --out DIR [--seeds 5] [--settings S-D S-E] [--methods dmpc mcf_dmpc opo_mcf_dmpc]
    railsim reproduce paper002 --out DIR [--topology union|path]
    railsim reproduce paper001 --out DIR [--scenario A|B|C-constant|C-harmonic] [--controllers sempc,mpc,afsmc]
    railsim reproduce paper004 --out DIR [--workers N | --dask ADDRESS]

A thin layer over :mod:`railsim.studies.reproduce` (what each experiment writes is described there). Exits 0, or
1 when Paper C's reference run violates a constraint.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from railsim.cli import values
from railsim.studies.reproduce import reproduce_paper001, reproduce_paper002, reproduce_paper004


def add_commands(sub: Any) -> None:
    p = sub.add_parser("reproduce", help="re-run a paper experiment in its numpy model and write its figures")
    p.add_argument("experiment", choices=["paper000", "paper001", "paper002", "paper004"], help="which experiment")
    p.add_argument("--seeds", type=values.count, default=5, help="paper000: seeds 0 … N−1 per case")
    p.add_argument("--settings", nargs="*", default=["S-D", "S-E"], choices=["S-D", "S-E"], help="paper000")
    p.add_argument("--methods", nargs="*", default=["dmpc", "mcf_dmpc", "opo_mcf_dmpc"], help="paper000")
    p.add_argument(
        "--workers", type=values.count, default=None, help="paper004: local worker processes (default: cores)"
    )
    p.add_argument("--dask", default=None, metavar="ADDRESS", help="paper004: run the cases on this Dask scheduler")
    p.add_argument("--out", required=True, type=values.path, help="output folder")
    p.add_argument(
        "--topology",
        choices=["union", "path"],
        default="union",
        help="paper002: reading of the lost Fig. 2 (spec 002 §3.2)",
    )
    p.add_argument(
        "--scenario",
        choices=["A", "B", "C-constant", "C-harmonic"],
        default="A",
        help="paper001: single section, multi-section, constant wind, harmonic gust",
    )
    p.add_argument("--controllers", default="sempc,mpc,afsmc", help="paper001: comma-separated controllers")
    p.set_defaults(func=cmd_reproduce)


def cmd_reproduce(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if args.experiment == "paper000":
        from railsim.studies.paper000_tables import reproduce_paper000

        res = reproduce_paper000(out, range(args.seeds), args.settings, args.methods, args.workers or 2)
        print(res["table"])
        return 0
    if args.experiment == "paper004":
        summary = reproduce_paper004(out, args.workers, args.dask)
        print(summary["table"])
        return 0
    if args.experiment == "paper001":
        summary = reproduce_paper001(out, args.scenario, args.controllers)
        for name, m in summary["metrics"].items():
            print(f"{name:8s} " + ", ".join(f"{k}={v:.4g}" for k, v in m.items() if isinstance(v, (int, float))))
        print(f"figure and metrics.json in {out}/")
        return 0
    summary = reproduce_paper002(out, args.topology)
    print(
        f"{summary['experiment']} ({summary['topology']}): {summary['steps']} steps, "
        f"{summary['violations']} constraint violations; figures and CSV in {out}/"
    )
    return 0 if summary["violations"] == 0 else 1
