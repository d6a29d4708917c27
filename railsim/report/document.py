"""One-page report of a run or a sweep: the key tables and figures, as Markdown or self-contained HTML.

``railsim report DIR [--format md|html]`` (:func:`write_report`) writes ``DIR/report.md`` or ``DIR/report.html``
and the figures it shows into ``DIR/report_figures/`` (PNG and SVG).

**A run folder** (``railsim run``) gives

* the run summary (``summary.json``: arrivals, stops served, collisions, minimum gap, …);
* running times per service (``trips``: travel time departure → arrival, delay against the free-run plan,
  traction energy, time coupled), stops per service and per station (``stops``: dwell, stopping error, missed
  stops) and the formations (``formations``: coupling, gap error, minimum gap);
* the line figures of :mod:`railsim.report.plots.line`: train graph, speed profiles, headways and (when formations ran)
  coupled gaps;
* the capacity analysis of :func:`railsim.analysis.capacity.analyse_run` (throughput, achieved headways, UIC 406
  occupancy per section) when it applies to the run.

**A sweep folder** (``railsim sweep``) gives the case counts, the cases table (parameters and key metrics; every
column is in ``cases.csv``), the failed cases with their errors and, for every numeric parameter, the key
metrics against it (one line per combination of the other parameters, averaged over seeds; the single seeds
as faint dots). The sweep table's parameter columns are those between ``seed`` and ``wall_s`` (labels and
override paths, :mod:`railsim.studies.sweep`).

The page is written once as Markdown (figures as relative links, so it renders on GitHub or in any Markdown
viewer next to its ``report_figures/`` folder); the HTML form is the same page converted by :func:`markdown_to_html`
with every PNG embedded as base64, so the file can be mailed on its own.
"""

from __future__ import annotations

import base64
import html
import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from railsim.errors import ConfigError
from railsim.record import output
from railsim.report import export

if TYPE_CHECKING:
    import pandas as pd

FORMATS = ("md", "html")
FIGURES_DIR = "report_figures"
# key metrics of a sweep's cases table (exact names, or a prefix ending in "."), in display order
SWEEP_METRICS = (
    "collisions",
    "n_arrived",
    "n_stops_missed",
    "min_gap_m",
    "fallbacks",
    "mean_running_time_s.",
    "trips.arrival_delay_p95_s",
    "trips.arrival_delay_max_s",
    "trips.energy_kwh_total",
)


# --------------------------------------------------------------------------------------------------------------
# Table formatting
# --------------------------------------------------------------------------------------------------------------


def _cell(value: Any, digits: int) -> str:
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float) or hasattr(value, "dtype") and getattr(value.dtype, "kind", "") == "f":
        v = float(value)
        return "–" if math.isnan(v) else f"{v:.{digits}f}"
    return str(value)


def formatted(frame: pd.DataFrame, digits: Mapping[str, int] | None = None, default_digits: int = 1) -> pd.DataFrame:
    """``frame`` with every value as display text: floats to ``digits[column]`` decimals (else
    ``default_digits``), missing values as ``–``, booleans as yes/no."""
    import pandas as pd

    digits = dict(digits or {})
    out = {}
    for col in frame.columns:
        d = digits.get(str(col), default_digits)
        out[str(col)] = [_cell(None if (not isinstance(v, str) and pd.isna(v)) else v, d) for v in frame[col]]
    return pd.DataFrame(out, columns=[str(c) for c in frame.columns])


def md_table(frame: pd.DataFrame, digits: Mapping[str, int] | None = None, default_digits: int = 1) -> str:
    """A Markdown pipe table (:func:`railsim.analysis.capacity.markdown_table`) of :func:`formatted` ``frame``."""
    from railsim.analysis.capacity import markdown_table

    return markdown_table(formatted(frame, digits, default_digits))


# --------------------------------------------------------------------------------------------------------------
# Run report
# --------------------------------------------------------------------------------------------------------------


def _summary_table(summary: Mapping[str, Any]) -> pd.DataFrame:
    import pandas as pd

    def num(key: str, fmt: str) -> str:
        v = summary.get(key)
        return "–" if v is None else format(v, fmt)

    rows = [
        (
            "trains arrived / inserted / total",
            f"{summary.get('n_arrived')} / {summary.get('n_inserted')} / {summary.get('n_trains')}",
        ),
        (
            "stops served / scheduled (missed)",
            f"{summary.get('n_stops_served')} / {summary.get('n_stops_scheduled')} ({summary.get('n_stops_missed')})",
        ),
        ("collisions (SUMO's own check)", f"{summary.get('collisions')} ({summary.get('sumo_collisions')})"),
        ("switch violations", str(summary.get("switch_violations"))),
        ("minimum true gap [m]", num("min_gap_m", ".1f")),
        ("controller fallbacks", str(summary.get("fallbacks"))),
        ("max stopping error [m]", num("max_stopping_error_m", ".3f")),
        ("simulated [s] / wall clock [s]", f"{num('sim_s', '.0f')} / {num('wall_s', '.1f')}"),
        ("steps × step [s]", f"{summary.get('steps')} × {summary.get('step_s')}"),
        ("seed", str(summary.get("seed"))),
    ]
    return pd.DataFrame(rows, columns=["", "value"])


def running_time_table(trips: pd.DataFrame) -> pd.DataFrame:
    """Per service: trips, arrived, running time (departure → arrival) mean/min/max [min], arrival delay against
    the free-run plan mean/max [s], traction energy per trip [kWh], time coupled per trip [min]."""
    import pandas as pd

    rows = []
    for svc, g in trips.groupby("service", sort=True):
        rt = pd.to_numeric(g["travel_time_s"], errors="coerce") / 60.0
        delay = pd.to_numeric(g["delay_s"], errors="coerce")
        rows.append(
            {
                "service": svc,
                "trips": len(g),
                "arrived": int(g["arrival_s"].notna().sum()),
                "running time mean [min]": rt.mean(),
                "min [min]": rt.min(),
                "max [min]": rt.max(),
                "delay mean [s]": delay.mean(),
                "delay max [s]": delay.max(),
                "energy per trip [kWh]": pd.to_numeric(g["energy_kwh"], errors="coerce").mean(),
                "coupled per trip [min]": pd.to_numeric(g["time_coupled_s"], errors="coerce").mean() / 60.0,
            }
        )
    return pd.DataFrame(rows)


def _missed(stops: pd.DataFrame) -> pd.Series:
    return stops["missed"].astype(str).str.lower().isin(("true", "1"))


def stop_service_table(stops: pd.DataFrame) -> pd.DataFrame:
    """Per service: stops recorded, served, missed, dwell mean/max [s], largest |stopping error| [m]."""
    import pandas as pd

    rows = []
    missed = _missed(stops)
    for svc, g in stops.groupby("service", sort=True):
        m = missed.loc[g.index]
        err = pd.to_numeric(g["stopping_error_m"], errors="coerce").abs()
        dwell = pd.to_numeric(g["dwell_s"], errors="coerce")
        rows.append(
            {
                "service": svc,
                "stops": len(g),
                "served": int((~m).sum()),
                "missed": int(m.sum()),
                "dwell mean [s]": dwell.mean(),
                "dwell max [s]": dwell.max(),
                "max abs stop error [m]": err.max(),
            }
        )
    return pd.DataFrame(rows)


def stop_station_table(stops: pd.DataFrame, stations: Sequence[Any]) -> pd.DataFrame:
    """Per station in line order (``stations``: :class:`railsim.report.plots.line.StationMark`): stops, missed, dwell
    mean/max [s], largest |stopping error| [m]."""
    import pandas as pd

    rows = []
    missed = _missed(stops)
    for st in stations:
        g = stops[stops["station"].astype(str) == st.id]
        if g.empty:
            continue
        err = pd.to_numeric(g["stopping_error_m"], errors="coerce").abs()
        dwell = pd.to_numeric(g["dwell_s"], errors="coerce")
        rows.append(
            {
                "station": st.name,
                "km": st.km,
                "stops": len(g),
                "missed": int(missed.loc[g.index].sum()),
                "dwell mean [s]": dwell.mean(),
                "dwell max [s]": dwell.max(),
                "max abs stop error [m]": err.max(),
            }
        )
    return pd.DataFrame(rows)


def formation_table(formations: pd.DataFrame) -> pd.DataFrame:
    """The formations with their coupling outcome, gap error and minimum gap."""
    cols = {
        "formation": "formation",
        "leader": "leader",
        "follower": "follower",
        "couple_successes": "coupled (times)",
        "time_to_couple_s": "time to couple [s]",
        "time_coupled_s": "time coupled [s]",
        "gap_error_p95_m": "gap error p95 [m]",
        "gap_error_max_m": "gap error max [m]",
        "min_gap_m": "min gap [m]",
        "final_state": "final state",
    }
    return formations[list(cols)].rename(columns=cols)


def fleet_markdown(fleet: Mapping[str, Any]) -> list[str]:
    """The rotations section of a run report: fleet size, km per unit, turnback times against the minimum."""
    import pandas as pd

    km = pd.Series(fleet.get("km_per_unit", {}), dtype=float)
    rows = pd.DataFrame(fleet.get("turnbacks", []))
    lines = [
        "## Fleet and turnbacks (rotations)",
        f"Units used: **{fleet['units_used']}**; peak units in service: **{fleet['peak_units_in_service']}**; "
        f"km per unit: mean {km.mean():.1f}, max {km.max():.1f}. Late starts caused by a late incoming unit: "
        f"{fleet['late_starts_from_incoming_unit']} ({fleet['knock_on_delay_s']:.0f} s in total). Minimum "
        f"turnback respected: {'yes' if fleet['turnback_min_respected'] else '**no**'}.",
    ]
    if len(rows):
        done = rows.dropna(subset=["achieved_s"])
        table = (
            done.groupby("station")
            .agg(
                turnbacks=("achieved_s", "size"),
                min_s=("min_s", "first"),
                achieved_min_s=("achieved_s", "min"),
                achieved_median_s=("achieved_s", "median"),
                knock_on_s=("knock_on_s", "sum"),
            )
            .reset_index()
        )
        table.columns = pd.Index(
            ["station", "turnbacks", "minimum [s]", "achieved min [s]", "achieved median [s]", "knock-on [s]"]
        )
        lines.append(md_table(table, {"turnbacks": 0}))
    if "depot_runs" in fleet:
        lines += depot_markdown(fleet)
    return lines


def depot_markdown(fleet: Mapping[str, Any]) -> list[str]:
    """Depot runs (``railsim.engine.depot``): runs, empty km per unit, units per depot at the start/end of the day."""
    import pandas as pd

    empty = pd.Series(fleet.get("empty_km_per_unit", {}), dtype=float)
    per = fleet.get("units_per_depot", {})
    start, end = per.get("start_of_day", {}), per.get("end_of_day", {})
    table = pd.DataFrame(
        [{"depot": d, "units at start": start.get(d, 0), "units at end": end.get(d, 0)} for d in sorted({*start, *end})]
    )
    missing = fleet.get("units_without_depot_runs", [])
    lines = [
        "### Depot runs",
        f"Depot runs: **{fleet['depot_runs']}** ({fleet['depot_runs_arrived']} arrived); empty km per unit: mean "
        f"{empty.mean():.1f}, max {empty.max():.1f}, total {empty.sum():.1f}. First trips that left late after their "
        f"depot-out run: {fleet['late_first_departures']}."
        + (f" Units no depot reaches (no depot runs): {', '.join(missing)}." if missing else ""),
    ]
    if len(table):
        lines.append(md_table(table, {"units at start": 0, "units at end": 0}))
    return lines


def _figure_md(paths: Sequence[Path], base: Path, caption: str, alt: str, svg_link: bool) -> str:
    png = next(p for p in paths if p.suffix == ".png")
    svg = next((p for p in paths if p.suffix == ".svg"), None)
    rel = png.relative_to(base).as_posix()
    link = f" ([SVG]({svg.relative_to(base).as_posix()}))" if svg is not None and svg_link else ""
    alt = alt.replace("[", "(").replace("]", ")")
    return f"![{alt}]({rel})\n\n*{caption}*{link}"


def run_report_markdown(run_dir: Path | str, figures_dir: Path | None = None, svg_links: bool = True) -> str:
    """The report of a run folder as Markdown; figures are written to ``figures_dir`` (default
    ``RUN/report_figures``, inside the run folder: links are relative to it), each PNG followed by a link to its
    SVG unless ``svg_links`` is False."""
    from railsim.analysis import sections
    from railsim.report.plots import line

    run = Path(run_dir)
    if export.check_folder(run) != "run":
        raise ConfigError(run, None, "expected a run folder (railsim run), found a sweep folder")
    fig_dir = figures_dir or run / FIGURES_DIR
    summary = sections.read_summary(run)
    trips = export.read_table(run, "trips")
    stops = export.read_table(run, "stops")
    formations = export.read_table(run, "formations")
    line_run = line.load_line_run(run)
    scn = line_run.frame.scenario

    parts = [f"# Run report: {scn.name}"]
    if scn.description:
        parts.append(scn.description)
    parts.append(
        f"World `{scn.world.label}`, seed {summary.get('seed')}, simulation start "
        f"{line.clock_label(line_run.start_time_s)}, step {scn.simulation.step_s:g} s. Run folder "
        f"`{run}`; tables in `trips`, `stops`, `formations`, `events` (CSV/Parquet; `railsim export` for "
        f"JSON and the section table)."
    )
    parts += ["## Summary", md_table(_summary_table(summary))]
    parts += ["## Running times per service", md_table(running_time_table(trips), {"trips": 0, "arrived": 0})]
    parts += [
        "## Stops",
        "Per service:",
        md_table(stop_service_table(stops), {"max abs stop error [m]": 3}),
        "Per station (line order):",
        md_table(stop_station_table(stops, line_run.stations), {"km": 1, "max abs stop error [m]": 3}),
    ]
    if len(formations):
        parts += [
            "## Formations (virtual coupling)",
            md_table(formation_table(formations), {"gap error p95 [m]": 2, "gap error max [m]": 2}),
        ]

    if summary.get("fleet"):
        parts += fleet_markdown(summary["fleet"])
    if summary.get("robustness"):
        from railsim.report.robustness import run_section

        parts += run_section(summary, run, fig_dir)

    parts.append("## Figures")
    figures = [
        (
            "time-distance",
            "Train graph: time of day against line km, one line per train; flat segments "
            "are dwells, the wide band marks virtually coupled running.",
        ),
        ("speed", "Speed profiles over line km (dashed: the route's speed limits)."),
        (
            "headway",
            "Achieved departure headways per section (box: quartiles, excluding coupled "
            "followers behind their leader, shown as separate dots).",
        ),
    ]
    if any(line_run.paths.get(scn.trip_id(f.follower)) is not None for f in scn.formations):
        figures.append(
            (
                "gap",
                "True gap of each formation while coupling, coupled and decoupling, with the configured target gap.",
            )
        )
    for kind, caption in figures:
        try:
            paths = line.write_kind(kind, line_run, fig_dir / kind)
        except ConfigError as err:  # e.g. no two trains ran the same section: no headway figure
            parts.append(f"*No {kind} figure: {err.message}.*")
            continue
        parts.append(_figure_md(paths, run, caption, kind, svg_links))

    parts.append(_capacity_markdown(run, line_run.frame))
    return "\n\n".join(p.strip("\n") for p in parts if p) + "\n"


def _capacity_markdown(run: Path, frame: Any) -> str:
    try:
        from railsim.analysis import capacity
    except ModuleNotFoundError as exc:
        if exc.name == "railsim.analysis.capacity":
            return ""
        raise
    try:
        return capacity.analyse_run(run, frame=frame).to_markdown()
    except ConfigError as err:
        return f"## Capacity\n\nNo capacity analysis for this run: {err.message}"


# --------------------------------------------------------------------------------------------------------------
# Sweep report
# --------------------------------------------------------------------------------------------------------------


def parameter_columns(cases: pd.DataFrame) -> list[str]:
    """The parameter columns of a sweep's cases table: labels and override paths, between ``seed`` and
    ``wall_s`` (:mod:`railsim.studies.sweep`'s column order)."""
    cols = [str(c) for c in cases.columns]
    if "seed" not in cols or "wall_s" not in cols:
        raise ConfigError(None, "cases", "not a railsim sweep table (expected the columns seed and wall_s)")
    return cols[cols.index("seed") + 1 : cols.index("wall_s")]


def metric_columns(cases: pd.DataFrame) -> list[str]:
    """The key metrics (:data:`SWEEP_METRICS`) present in a cases table, in display order."""
    cols = [str(c) for c in cases.columns]
    out: list[str] = []
    for key in SWEEP_METRICS:
        out += [c for c in cols if (c.startswith(key) if key.endswith(".") else c == key) and c not in out]
    return out


def _independent(cases: pd.DataFrame, params: list[str]) -> list[str]:
    """``params`` without those that are a one-to-one function of an earlier one (a ``link:`` copy such as the
    down headway that always equals the up headway): plotting against them would repeat the same figure."""
    keep: list[str] = []
    for p in params:
        if not any(
            cases.groupby(k, dropna=False)[p].nunique(dropna=False).max() <= 1
            and cases.groupby(p, dropna=False)[k].nunique(dropna=False).max() <= 1
            for k in keep
        ):
            keep.append(p)
    return keep


def _short_param(name: str) -> str:
    """``services[0].departures.headway_s`` → ``services[0].headway_s`` (first and last part of a long path)."""
    parts = name.split(".")
    return name if len(parts) <= 2 else f"{parts[0]}.{parts[-1]}"


def _metric_plot(cases: pd.DataFrame, param: str, others: list[str], metrics: list[str], stem: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pandas as pd

    ok = cases[cases["status"].astype(str) == "ok"]
    ncol = min(3, len(metrics))
    nrow = math.ceil(len(metrics) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.3 * ncol, 3.0 * nrow + 0.8), squeeze=False)
    fig.suptitle(f"key metrics against {param}", fontsize=10)
    groups = list(ok.groupby(others, sort=True, dropna=False)) if others else [((), ok)]
    cmap = plt.get_cmap("viridis" if len(groups) > 8 else "tab10")
    for ax, metric in zip(axes.ravel(), metrics):
        for k, (key, g) in enumerate(groups):
            colour = cmap(k / max(len(groups) - 1, 1)) if len(groups) > 8 else cmap(k % 10)
            x = pd.to_numeric(g[param], errors="coerce")
            y = pd.to_numeric(g[metric], errors="coerce")
            ax.scatter(x, y, s=10, color=colour, alpha=0.35, lw=0)
            mean = pd.DataFrame({"x": x, "y": y}).groupby("x", sort=True)["y"].mean()
            key = key if isinstance(key, tuple) else (key,)
            label = ", ".join(f"{_short_param(o)}={v}" for o, v in zip(others, key)) or "mean over seeds"
            ax.plot(mean.index.to_numpy(float), mean.to_numpy(float), "-o", ms=3, lw=1.1, color=colour, label=label)
        ax.set_title(metric, fontsize=8)
        ax.set_xlabel(_short_param(param), fontsize=7)
        ax.tick_params(labelsize=7)
        ax.grid(color="#e6e6e6", lw=0.5)
    for ax in axes.ravel()[len(metrics) :]:
        ax.set_visible(False)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    if len(groups) > 1 and len(groups) <= 12:
        fig.legend(handles, labels, loc="lower center", ncol=min(4, len(groups)), fontsize=7, frameon=False)
    fig.tight_layout(rect=(0, 0.06 if len(groups) > 1 else 0, 1, 0.95))
    stem.parent.mkdir(parents=True, exist_ok=True)
    paths = [stem.with_name(stem.name + ".png"), stem.with_name(stem.name + ".svg")]
    fig.savefig(paths[0], dpi=130)
    fig.savefig(paths[1])
    plt.close(fig)
    return paths


def sweep_report_markdown(sweep_dir: Path | str, figures_dir: Path | None = None, svg_links: bool = True) -> str:
    """The report of a sweep folder as Markdown (figures written to ``figures_dir``, default
    ``SWEEP/report_figures``; see :func:`run_report_markdown`)."""
    import pandas as pd
    import yaml

    folder = Path(sweep_dir)
    if export.check_folder(folder) != "sweep":
        raise ConfigError(folder, None, "expected a sweep folder (railsim sweep), found a run folder")
    fig_dir = figures_dir or folder / FIGURES_DIR
    cases = export.read_table(folder, export.CASE_TABLE)
    try:
        params = parameter_columns(cases)
    except ConfigError as err:
        table = next(p for p in (folder / "cases.parquet", folder / "cases.csv") if p.is_file())
        raise ConfigError(table, "columns", err.message) from None
    metrics = metric_columns(cases)
    spec: dict[str, Any] = {}
    if (folder / "sweep.yaml").is_file():
        try:
            spec = yaml.safe_load((folder / "sweep.yaml").read_text(encoding="utf-8")) or {}
        except yaml.YAMLError as exc:
            raise ConfigError(folder / "sweep.yaml", None, f"not valid YAML: {exc}") from None
    name = str(spec.get("name") or folder.name)
    status = cases["status"].astype(str)
    n_ok, n_failed = int((status == "ok").sum()), int((status != "ok").sum())
    parts = [f"# Sweep report: {name}"]
    if spec.get("description"):
        parts.append(str(spec["description"]))
    parts.append(
        f"Base scenario `{spec.get('base', '?')}`; {len(cases)} cases ({n_ok} ok, {n_failed} failed), "
        f"seeds {', '.join(str(s) for s in sorted(cases['seed'].dropna().unique()))}. Parameters: "
        + (", ".join(f"`{p}`" for p in params) or "none")
        + f". Every column is in `cases.csv` / "
        f"`cases.parquet` of `{folder}`."
    )
    shown = ["case_id", "status", "seed", *params, *metrics, "wall_s"]
    parts += [
        "## Cases",
        md_table(cases[shown], {"seed": 0, "collisions": 0, "n_arrived": 0, "n_stops_missed": 0, "fallbacks": 0}, 1),
    ]
    if n_failed:
        failed = cases.loc[status != "ok", ["case_id", *params, "error"]].copy()
        failed["error"] = failed["error"].astype(str).str.replace("\n", " ").str.slice(0, 200)
        parts += ["## Failed cases", md_table(failed)]
    independent = _independent(cases, params)
    numeric = [
        p for p in independent if pd.to_numeric(cases[p], errors="coerce").notna().all() and cases[p].nunique() > 1
    ]
    varying = [m for m in metrics if pd.to_numeric(cases[m], errors="coerce").nunique() > 1]
    if numeric and varying and n_ok:
        parts.append("## Metrics against parameters")
        parts.append("Lines: mean over seeds for each combination of the other parameters; dots: single cases.")
        for p in numeric:
            others = [o for o in independent if o != p and cases[o].nunique() > 1]
            slug = re.sub(r"[^A-Za-z0-9_.-]+", "_", p).strip("_")
            paths = _metric_plot(cases, p, others, varying, fig_dir / f"metrics_vs_{slug}")
            parts.append(_figure_md(paths, folder, f"Key metrics against {p}.", f"metrics vs {p}", svg_links))
    return "\n\n".join(part.strip("\n") for part in parts if part) + "\n"


# --------------------------------------------------------------------------------------------------------------
# Markdown → HTML
# --------------------------------------------------------------------------------------------------------------

_IMG_RE = re.compile(r"^!\[(?P<alt>[^\]]*)\]\((?P<src>[^)]+)\)$")
_LINK_RE = re.compile(r"\[(?P<text>[^\]]+)\]\((?P<href>[^)]+)\)")

_CSS = """body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;max-width:1200px;margin:2em auto;
padding:0 1em;color:#222;line-height:1.45}table{border-collapse:collapse;margin:.6em 0 1.2em;font-size:.85em}
th,td{border:1px solid #ccc;padding:.25em .6em;text-align:right}th{background:#f2f2f2}td:first-child,th:first-child
{text-align:left}img{max-width:100%;border:1px solid #eee}code{background:#f4f4f4;padding:0 .2em}
h1{border-bottom:2px solid #0072B2}h2{border-bottom:1px solid #ddd;margin-top:1.6em}"""


def _inline(text: str) -> str:
    """Escape ``text`` for HTML and render ``code``, *emphasis* and [links](href)."""
    out = html.escape(text, quote=False)
    out = re.sub(r"`([^`]+)`", r"<code>\1</code>", out)
    out = re.sub(r"(?<![\w*])\*([^*]+)\*(?![\w*])", r"<em>\1</em>", out)
    return _LINK_RE.sub(lambda m: f'<a href="{html.escape(m["href"])}">{m["text"]}</a>', out)


def markdown_to_html(markdown: str, base_dir: Path, title: str = "railsim report") -> str:
    """The Markdown this module writes (headings, paragraphs, pipe tables, images) as one self-contained HTML
    page: images (PNG paths relative to ``base_dir``) are embedded as base64 data URIs."""
    body: list[str] = []
    for block in re.split(r"\n\s*\n", markdown.strip()):
        lines = block.strip("\n").split("\n")
        first = lines[0]
        if first.startswith("#"):
            level = len(first) - len(first.lstrip("#"))
            body.append(f"<h{level}>{_inline(first[level:].strip())}</h{level}>")
        elif first.startswith("|") and len(lines) >= 2:

            def cells(row: str) -> list[str]:
                return [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", row.strip())[1:-1]]

            head = "".join(f"<th>{_inline(c)}</th>" for c in cells(lines[0]))
            rows = "".join("<tr>" + "".join(f"<td>{_inline(c)}</td>" for c in cells(r)) + "</tr>" for r in lines[2:])
            body.append(f"<table><thead><tr>{head}</tr></thead><tbody>{rows}</tbody></table>")
        elif _IMG_RE.match(first):
            m = _IMG_RE.match(first)
            assert m is not None
            data = base64.b64encode((base_dir / m["src"]).read_bytes()).decode("ascii")
            body.append(f'<figure><img alt="{html.escape(m["alt"])}" src="data:image/png;base64,{data}"></figure>')
        else:
            body.append(f"<p>{_inline(' '.join(lines))}</p>")
    return (
        f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>'
        f"<style>{_CSS}</style></head>\n<body>\n" + "\n".join(body) + "\n</body></html>\n"
    )


# --------------------------------------------------------------------------------------------------------------
# Entry points
# --------------------------------------------------------------------------------------------------------------


def write_report(folder: Path | str, fmt: str = "md") -> Path:
    """Write ``FOLDER/report.md`` (or ``report.html``, self-contained) for a run or sweep folder; returns its
    path. Figures go to ``FOLDER/report_figures/``."""
    if fmt not in FORMATS:
        raise ConfigError(None, "format", f"expected one of {', '.join(FORMATS)}, got {fmt!r}")
    folder = Path(folder)
    kind = export.check_folder(folder)
    build = run_report_markdown if kind == "run" else sweep_report_markdown
    markdown = build(folder, svg_links=fmt == "md")  # the HTML page embeds PNGs and links no other file
    path = folder / f"report.{fmt}"
    if fmt == "md":
        text = markdown
    else:
        title = markdown.split("\n", 1)[0].lstrip("# ").strip()
        text = markdown_to_html(markdown, folder, title)
    output.write_bytes(path, text.encode("utf-8"))
    return path
