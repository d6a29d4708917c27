"""``railsim plot``: figures from finished run folders (PNG), chosen by what the run contains.

    railsim plot out/sd_dmpc out/sd_opo --out fig/          # Paper A runs: speeds, ΔS − D^(e), comparison
    railsim plot out/paper003_track_accel --out fig/         # Paper D runs: positions, speeds, accelerations, gaps
    railsim plot out/x --kind paper000 --out fig/            # force a kind

``--kind auto`` (default) reads each folder's ``scenario.resolved.yaml`` and uses the analysis that applies to its
controllers (:mod:`railsim.analysis.registry`); a line run (no paper family's controllers) gets every line-level
figure that applies (:mod:`railsim.report.plots.line`: train graph, speed, gap, headway; gap only with a
virtually coupled formation, headway only when two trains ran the same section — the others are reported as
skipped). Line figures are PNG + SVG named after their kind:

    railsim plot out/peak                                   # out/peak/time-distance.png, speed.png, gap.png, ...
    railsim plot out/peak --kind time-distance --out fig/   # fig/time-distance.png (+ .svg) [--direction up]
    railsim plot out/a out/b --out fig/                     # fig/a/..., fig/b/...

``--out`` is always a folder (created); without it line figures go into each run's own folder.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from railsim.cli import values
from railsim.errors import ConfigError

LINE_KINDS = ("time-distance", "speed", "gap", "headway")  # railsim.report.plots.line.KINDS (not imported: matplotlib)
KINDS = ("auto", "paper000", "paper003", *LINE_KINDS)


def add_commands(sub: Any) -> None:
    p = sub.add_parser("plot", help="write figures (PNG) for finished run folders")
    p.add_argument("runs", nargs="+", type=values.path, help="run output folders (from railsim run)")
    p.add_argument(
        "--out",
        default=None,
        help="folder for the figures (created; with several runs one sub-folder per run); "
        "default for line figures: each run's own folder",
    )
    p.add_argument("--kind", choices=KINDS, default="auto")
    p.add_argument("--direction", choices=("up", "down"), default=None, help="line kinds: one direction only")
    p.set_defaults(func=cmd_plot)


def _kind_of(run: Path) -> str:
    """The paper family whose figures apply to ``run``'s controllers, or ``"line"`` (the line-level figures)."""
    import yaml

    from railsim.analysis import registry as analyses

    resolved = run / "scenario.resolved.yaml"
    if not resolved.is_file():
        raise ConfigError(run, "scenario.resolved.yaml", "not a railsim run folder (no scenario.resolved.yaml)")
    raw = yaml.safe_load(resolved.read_text(encoding="utf-8")) or {}
    types = {c.get("type") for c in (raw.get("controllers") or {}).values() if isinstance(c, dict)}
    kinds = analyses.applicable_to_types(t for t in types if isinstance(t, str))
    return kinds[0] if kinds else "line"


def _line_figures(kinds: tuple[str, ...], run: Path, dest: Path, direction: str | None) -> list[Path]:
    """Each line figure of ``kinds`` that applies to ``run`` into ``dest/<kind>``; one that does not is skipped
    with its reason when several were asked for (``--kind auto``), an error when it was the one asked for."""
    from railsim.report.plots.line import write_kind

    written: list[Path] = []
    for kind in kinds:
        try:
            written += write_kind(kind, run, dest / kind, direction)
        except ConfigError as err:
            if len(kinds) == 1:
                raise
            print(f"{run}: {kind} skipped: {err.message}")
    if not written:
        raise ConfigError(run, None, "no line figure applies to this run")
    return written


def cmd_plot(args: argparse.Namespace) -> int:
    runs = [Path(r) for r in args.runs]
    for r in runs:
        if not r.is_dir():
            raise ConfigError(r, None, "no such run folder")
    written: list[Path] = []
    kinds = {r: (_kind_of(r) if args.kind == "auto" else args.kind) for r in runs}

    def dest_of(r: Path) -> Path:
        if args.out is None:
            return r
        return Path(args.out) / r.name if len(runs) > 1 else Path(args.out)

    for r in runs:
        if kinds[r] == "line" or kinds[r] in LINE_KINDS:
            line_kinds = LINE_KINDS if kinds[r] == "line" else (kinds[r],)
            written += _line_figures(line_kinds, r, dest_of(r), args.direction)
    paper_runs = [r for r in runs if kinds[r] not in ("line", *LINE_KINDS)]
    if paper_runs and args.out is None:
        raise ConfigError(None, "--out", f"a folder for the figures is required for {kinds[paper_runs[0]]} runs")
    dest = Path(args.out) if args.out is not None else Path()
    paper000 = [r for r in paper_runs if kinds[r] == "paper000"]
    if paper000:
        from railsim.report.plots.paper000 import write_figures

        written += write_figures({r.name: r for r in paper000}, dest)
    for r in (r for r in paper_runs if kinds[r] == "paper003"):
        from railsim.report.plots.paper003 import write_figures as write_d

        written += write_d(r, dest / r.name if len(runs) > 1 else dest)
    for path in written:
        print(path)
    return 0
