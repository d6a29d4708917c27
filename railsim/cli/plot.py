"""``railsim plot``: figures from finished run folders (PNG), chosen by what the run contains.

    railsim plot out/sd_dmpc out/sd_opo --out fig/          # Paper A runs: speeds, ΔS − D^(e), comparison
    railsim plot out/paper003_track_accel --out fig/         # Paper D runs: positions, speeds, accelerations, gaps
    railsim plot out/x --kind paper000 --out fig/            # force a kind

``--kind auto`` (default) reads each folder's ``scenario.resolved.yaml`` and uses the analysis that applies to its
controllers (:mod:`railsim.analysis.registry`). Line-level kinds (:mod:`railsim.report.plots.line`) write PNG and SVG to a file stem:

    railsim plot out/peak --kind time-distance [--out fig/peak_td] [--direction up]   # default stem RUN/<kind>
    railsim plot out/peak --kind speed|gap|headway
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from railsim.errors import ConfigError

LINE_KINDS = ("time-distance", "speed", "gap", "headway")  # railsim.report.plots.line.KINDS (not imported: matplotlib)
KINDS = ("auto", "paper000", "paper003", *LINE_KINDS)


def add_commands(sub: Any) -> None:
    p = sub.add_parser("plot", help="write figures (PNG) for finished run folders")
    p.add_argument("runs", nargs="+", help="run output folders (from railsim run)")
    p.add_argument(
        "--out",
        default=None,
        help="folder for the figures; for line kinds a file stem (default "
        "RUN/<kind>; with several runs <stem>-<run name>)",
    )
    p.add_argument("--kind", choices=KINDS, default="auto")
    p.add_argument("--direction", choices=("up", "down"), default=None, help="line kinds: one direction only")
    p.set_defaults(func=cmd_plot)


def _kind_of(run: Path) -> str:
    import yaml

    from railsim.analysis import registry as analyses

    resolved = run / "scenario.resolved.yaml"
    if not resolved.is_file():
        raise ConfigError(run, "scenario.resolved.yaml", "not a railsim run folder (no scenario.resolved.yaml)")
    raw = yaml.safe_load(resolved.read_text(encoding="utf-8")) or {}
    types = {c.get("type") for c in (raw.get("controllers") or {}).values() if isinstance(c, dict)}
    kinds = analyses.applicable_to_types(t for t in types if isinstance(t, str))
    if kinds:
        return kinds[0]
    raise ConfigError(run, "controllers", "no figure kind applies to this run's controllers yet (use --kind)")


def cmd_plot(args: argparse.Namespace) -> int:
    runs = [Path(r) for r in args.runs]
    for r in runs:
        if not r.is_dir():
            raise ConfigError(r, None, "no such run folder")
    written: list[Path] = []
    if args.kind in LINE_KINDS:
        from railsim.report.plots.line import write_kind

        for r in runs:
            stem = (
                r / args.kind
                if args.out is None
                else Path(args.out)
                if len(runs) == 1
                else Path(f"{args.out}-{r.name}")
            )
            written += write_kind(args.kind, r, stem, args.direction)
        for path in written:
            print(path)
        return 0
    if args.out is None:
        raise ConfigError(None, "--out", f"a folder for the figures is required with --kind {args.kind}")
    kinds = {r: (_kind_of(r) if args.kind == "auto" else args.kind) for r in runs}
    dest = Path(args.out)
    paper000 = [r for r in runs if kinds[r] == "paper000"]
    if paper000:
        from railsim.report.plots.paper000 import write_figures

        written += write_figures({r.name: r for r in paper000}, dest)
    for r in (r for r in runs if kinds[r] == "paper003"):
        from railsim.report.plots.paper003 import write_figures as write_d

        written += write_d(r, dest / r.name if len(runs) > 1 else dest)
    for path in written:
        print(path)
    return 0
