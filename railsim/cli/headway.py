"""``railsim min-headway``: search the minimum feasible headway of a service pattern.

    railsim min-headway SCENARIO --path P [--path P2 ...] --lo S --hi S [--tol S] [--max-delay S] [--set PATH=VALUE]

A thin layer over :func:`railsim.studies.headway.find_min_headway` (criteria, search and answer are described in
:mod:`railsim.studies.headway`). Prints the probe table and the answer as Markdown; exits 0 when a feasible
headway was found, 1 when none in the range is, 2 on bad input (:mod:`railsim.cli.main`).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from typing import Any

from railsim.cli import values
from railsim.cli.sweep import require_one_backend
from railsim.errors import ConfigError
from railsim.studies.headway import DELAY_STATS, find_min_headway


def _parse_set(items: Sequence[str]) -> dict[str, Any]:
    import yaml

    out: dict[str, Any] = {}
    for item in items:
        path, sep, text = item.partition("=")
        if not sep or not path:
            raise ConfigError(None, "--set", f"expected PATH=VALUE, got {item!r}")
        try:
            out[path] = yaml.safe_load(text)
        except yaml.YAMLError:
            raise ConfigError(None, "--set", f"{path}: the value is not valid YAML: {text!r}") from None
    return out


def cmd_min_headway(args: argparse.Namespace) -> int:
    require_one_backend(args)
    result = find_min_headway(
        args.scenario,
        args.path,
        args.lo,
        args.hi,
        tol_s=args.tol,
        max_delay_s=args.max_delay,
        delay_stat=args.delay_stat,
        overrides=_parse_set(args.set),
        seed=args.seed,
        confirm_seeds=args.confirm_seed,
        workers=args.workers or 1,
        dask_address=args.dask,
        timeout_s=args.timeout,
        out_dir=args.out,
        keep_runs=args.keep_runs,
        progress=False if args.no_progress else None,
    )
    print(result.to_markdown())
    return 0 if result.feasible else 1


def add_commands(sub: Any) -> None:
    p = sub.add_parser(
        "min-headway",
        help="search the minimum feasible headway of a service pattern",
        description="Find the smallest headway in [lo, hi] at which a scenario runs without "
        "collision, with every stop served, every trip arrived and the arrival delay below a threshold.",
    )
    p.add_argument("scenario", metavar="SCENARIO", type=values.path, help="base scenario YAML file")
    p.add_argument(
        "--path",
        action="append",
        required=True,
        metavar="PATH",
        help="override path set to the headway, e.g. services[0].departures.headway_s (repeatable)",
    )
    p.add_argument("--lo", type=float, required=True, help="shortest headway to consider [s]")
    p.add_argument("--hi", type=float, required=True, help="longest headway to consider [s]")
    p.add_argument("--tol", type=float, default=5.0, help="resolution of the answer [s] (default 5)")
    p.add_argument("--max-delay", type=float, default=120.0, help="arrival delay threshold [s] (default 120)")
    p.add_argument("--delay-stat", choices=DELAY_STATS, default="max", help="delay statistic (default max)")
    p.add_argument("--seed", type=values.seed, default=None, help="seed of the search probes (default: the scenario's)")
    p.add_argument(
        "--confirm-seed",
        type=int,
        action="append",
        default=None,
        metavar="N",
        help="seed(s) that confirm the answer (default: seed + 1; repeatable)",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="PATH=VALUE",
        help="extra override applied to every probe (value in YAML), repeatable",
    )
    p.add_argument(
        "--workers", type=values.count, default=None, help="probes run in parallel (local processes, default 1)"
    )
    p.add_argument("--dask", default=None, metavar="ADDRESS", help="run the probes on this Dask scheduler")
    p.add_argument("--timeout", type=values.seconds, default=None, metavar="S", help="wall-clock limit per probe [s]")
    p.add_argument(
        "--out",
        default=None,
        type=values.path,
        help="folder for headway.json, probes.csv and the probe rows (resumable)",
    )
    p.add_argument("--keep-runs", action="store_true", help="keep every probe's run outputs under OUT/runs/")
    p.add_argument("--no-progress", action="store_true", help="no progress bar even on a terminal")
    p.set_defaults(func=cmd_min_headway)
