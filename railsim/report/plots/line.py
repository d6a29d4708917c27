"""Line-level figures of a finished run: the train graph (time-distance), speed profiles, coupled gaps, headways.

The **time-distance diagram** (train graph, *Bildfahrplan*, 运行图) is the picture rail planners read first:
time of day on one axis, the line's stations at their line km on the other, one line per train. A train
standing at a platform draws a flat segment (its dwell); a steeper line is a faster train; two lines that run
on top of each other are a virtually coupled pair. Here:

* **distance** is *line km*: every train's route chainage (trace ``chainage_m``, the front of the train) is
  mapped to line km through its route's stations (:class:`railsim.analysis.sections.ServiceFrame.km_of`, linear between
  platform centres). Branch stations keep the km the line description gives them, which continue the main
  line's km from the junction, so beyond a junction a branch and the main line share the axis: branch
  stations are labelled in italics with dashed grid lines, and branch services have their own colour;
* **time** is clock time (scenario ``simulation.start_time`` + simulation seconds);
* one panel per **direction** (``up`` = increasing line km), sharing the station axis;
* **colour** is the service's *route family*: the services between the same two end stations (``airport_up``
  and ``airport_down``) share a colour, unless two of them run in the same direction; a wide translucent band under a train marks where it ran **virtually
  coupled** (the follower's ``formation_state`` is ``coupled``; its leader runs in the same band).

Other kinds: :func:`speed` (speed over line km per direction, with the route's speed limits), :func:`gap`
(each formation's true front-to-rear gap over time while coupling/coupled/decoupling, with its configured
target gap) and :func:`headway` (achieved departure headways per section, from
:func:`railsim.analysis.sections.section_table`; a coupled follower's headway behind its own leader is marked apart,
because it is a few seconds by design).

Each ``kind(run_dir, out_stem, direction=None)`` writes ``<out_stem>.png`` and ``<out_stem>.svg`` and returns
their paths; ``kind_figure(...)`` returns the matplotlib figure instead (every train's line carries its trip id
as ``gid``, which also names its group in the SVG). Agg backend; no window opens.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.transforms as mtransforms  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.ticker import FuncFormatter, MultipleLocator  # noqa: E402

from railsim.analysis import sections
from railsim.errors import ConfigError  # noqa: E402
from railsim.report.plots.line_data import (  # noqa: E402
    DIRECTIONS,
    LineRun,
    StationMark,
    load_line_run,
    station_label,
)

KINDS = ("time-distance", "speed", "gap", "headway")
# colours of route families (colour-blind friendly, Okabe-Ito order), the coupled band and station grid lines
COUPLED_COLOUR = "#F0C419"
GRID_COLOUR = "#B8B8B8"
LABEL_PT = 6.5  # station label font size [pt]
DPI = 150


# --------------------------------------------------------------------------------------------------------------
# What a run looks like on the line
# --------------------------------------------------------------------------------------------------------------


# --------------------------------------------------------------------------------------------------------------
# Axis helpers
# --------------------------------------------------------------------------------------------------------------


def clock_label(seconds_after_midnight: float, _pos: Any = None) -> str:
    """``HH:MM`` of a clock time in seconds after midnight (hours may pass 24)."""
    minutes = int(round(seconds_after_midnight / 60.0))
    return f"{minutes // 60:02d}:{minutes % 60:02d}"


def clock_label_s(seconds_after_midnight: float, _pos: Any = None) -> str:
    """``HH:MM:SS`` of a clock time in seconds after midnight (for axes spanning a few minutes)."""
    s = int(round(seconds_after_midnight))
    return f"{s // 3600:02d}:{s // 60 % 60:02d}:{s % 60:02d}"


def _time_axis(ax: Any, t0: float, t1: float) -> None:
    """Clock-time ticks on x over [t0, t1]: at most ~14 major ticks at a round step (10 s … 4 h)."""
    span_s = max(t1 - t0, 10.0)
    major = next((m for m in (10, 30, 60, 120, 300, 600, 900, 1800, 3600, 7200) if span_s / m <= 14), 14400)
    ax.xaxis.set_major_locator(MultipleLocator(major))
    ax.xaxis.set_minor_locator(MultipleLocator(major / (5 if major in (300, 600, 900, 1800) else 2)))
    ax.xaxis.set_major_formatter(FuncFormatter(clock_label if major >= 60 else clock_label_s))
    ax.set_xlim(t0, t1)


def spread_labels(values: list[float], min_sep: float, lo: float, hi: float) -> list[float]:
    """Label positions near sorted ``values`` with at least ``min_sep`` between neighbours, kept in [lo, hi]
    where there is room (a forward pass pushes crowded labels up, a backward pass pulls them under ``hi``)."""
    pos = [float(v) for v in values]
    for i in range(1, len(pos)):
        pos[i] = max(pos[i], pos[i - 1] + min_sep)
    if pos and pos[-1] > hi:
        pos[-1] = hi
        for i in range(len(pos) - 2, -1, -1):
            pos[i] = min(pos[i], pos[i + 1] - min_sep)
    return pos


def _station_axis(ax: Any, stations: list[StationMark], side: str | None, fig_h_in: float) -> None:
    """Grid lines at the stations' km and their names (``side`` ``"left"``/``"right"``, None: grid only)."""
    for st in stations:
        ax.axhline(
            st.km,
            color="#808080" if st.turnback else GRID_COLOUR,
            lw=0.7 if st.turnback else 0.45,
            ls=(0, (4, 3)) if st.branch else "-",
            zorder=0.5,
        )
    ax.set_yticks([])
    if side is None or not stations:
        return
    y0, y1 = ax.get_ylim()
    axes_h_pt = ax.get_position().height * fig_h_in * 72.0
    min_sep = (LABEL_PT + 1.2) * (y1 - y0) / axes_h_pt
    ys = spread_labels([s.km for s in stations], min_sep, y0, y1)
    x_text, x_tick, ha = (-0.012, -0.004, "right") if side == "left" else (1.012, 1.004, "left")
    trans = mtransforms.blended_transform_factory(ax.transAxes, ax.transData)
    for st, y in zip(stations, ys):
        text = f"{st.name}  {st.km:.1f}" if side == "left" else f"{st.km:.1f}  {st.name}"
        ax.text(
            x_text,
            y,
            text,
            transform=trans,
            ha=ha,
            va="center",
            fontsize=LABEL_PT,
            style="italic" if st.branch else "normal",
            color="#5a3d7a" if st.branch else "black",
            fontweight="bold" if st.turnback else "normal",
        )
        edge = 0.0 if side == "left" else 1.0
        ax.plot([edge, x_tick], [st.km, y], transform=trans, color="#606060", lw=0.5, clip_on=False)


def _km_limits(stations: list[StationMark]) -> tuple[float, float]:
    kms = [s.km for s in stations] or [0.0, 1.0]
    pad = max(0.015 * (max(kms) - min(kms)), 0.2)
    return min(kms) - pad, max(kms) + pad


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Index ranges [i, j] (inclusive) where ``mask`` is True."""
    out = []
    idx = np.flatnonzero(np.diff(np.concatenate(([0], mask.astype(np.int8), [0]))))
    for a, b in zip(idx[::2], idx[1::2]):
        out.append((int(a), int(b) - 1))
    return out


def _check_direction(run: LineRun, direction: str | None) -> list[str]:
    dirs = run.directions()
    if direction is None:
        if not dirs:
            raise ConfigError(run.run_dir, "trace.csv", "no train left its origin: nothing to plot")
        return dirs
    if direction not in DIRECTIONS:
        raise ConfigError(None, "direction", f"expected up or down, got {direction!r}")
    if direction not in dirs:
        raise ConfigError(run.run_dir, "direction", f"no train ran {direction} in this run")
    return [direction]


def _save(fig: Figure, out_stem: Path | str) -> list[Path]:
    stem = Path(out_stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    paths = [stem.with_name(stem.name + ".png"), stem.with_name(stem.name + ".svg")]
    fig.savefig(paths[0], dpi=DPI)
    fig.savefig(paths[1])
    plt.close(fig)
    return paths


def _service_legend(ax: Any, run: LineRun, services: list[str], coupled: bool, loc: str = "upper left") -> None:
    handles = [Line2D([], [], color=run.colours[s], lw=1.4, label=s) for s in services]
    if coupled:
        handles.append(Line2D([], [], color=COUPLED_COLOUR, lw=6, alpha=0.6, label="virtually coupled"))
    ax.legend(handles=handles, loc=loc, fontsize=7, framealpha=0.9)


# --------------------------------------------------------------------------------------------------------------
# Time-distance
# --------------------------------------------------------------------------------------------------------------


def time_distance_figure(run_dir: Path | str | LineRun, direction: str | None = None) -> Figure:
    """The train graph of a run: one panel per direction (or only ``direction``), one line per trip."""
    run = run_dir if isinstance(run_dir, LineRun) else load_line_run(run_dir)
    dirs = _check_direction(run, direction)
    t_lo = min(float(p.clock_s[0]) for p in run.paths.values())
    t_hi = max(float(p.clock_s[-1]) for p in run.paths.values())
    pad = 0.01 * (t_hi - t_lo)
    n_st = len(run.stations)
    height = float(np.clip(1.6 + 0.205 * n_st, 5.0, 16.0))
    panel_w = float(np.clip(3.5 + (t_hi - t_lo) / 2000.0, 6.0, 11.0))
    longest = max((len(s.name) for s in run.stations), default=8) + 6  # name, two spaces and "62.6"
    label_w = 0.25 + longest * LABEL_PT * 0.56 / 72.0  # [in] (average glyph width of DejaVu Sans ~0.56 em)
    width = len(dirs) * panel_w + label_w * len(dirs) + 0.3
    fig, axes = plt.subplots(1, len(dirs), figsize=(width, height), sharey=True, squeeze=False)
    fig.subplots_adjust(
        left=label_w / width,
        right=1.0 - (label_w if len(dirs) == 2 else 0.3) / width,
        bottom=0.9 / height,
        top=1.0 - 0.75 / height,
        wspace=0.04,
    )
    fig.suptitle(f"{run.name}: train graph", fontsize=11, y=1.0 - 0.2 / height)
    lo, hi = _km_limits(run.stations)
    for k, (ax, d) in enumerate(zip(axes[0], dirs)):
        ax.set_gid(d)
        ax.set_ylim(lo, hi)
        side = "left" if k == 0 else "right"
        _station_axis(ax, run.stations, side, height)
        any_coupled = False
        for p in sorted(run.trips_in(d), key=lambda p: p.clock_s[0]):
            coupled = p.formation_state == "coupled"
            for a, b in _runs(coupled):
                ax.plot(
                    p.clock_s[a : b + 1],
                    p.km[a : b + 1],
                    color=COUPLED_COLOUR,
                    lw=5.0,
                    alpha=0.55,
                    solid_capstyle="butt",
                    zorder=1,
                )
                any_coupled = True
            (line,) = ax.plot(p.clock_s, p.km, color=run.colours[p.service], lw=0.75, zorder=2)
            line.set_gid(p.trip_id)
        _time_axis(ax, t_lo - pad, t_hi + pad)
        ax.tick_params(axis="x", labelsize=8)
        ax.grid(axis="x", which="major", color="#d8d8d8", lw=0.5)
        ax.grid(axis="x", which="minor", color="#eeeeee", lw=0.4)
        ax.set_axisbelow(True)
        arrow = "↑ towards higher km" if d == "up" else "↓ towards lower km"
        ax.set_title(f"{d} ({arrow}): {len(run.trips_in(d))} trains", fontsize=9)
        ax.set_xlabel(f"time of day (simulation start {clock_label(run.start_time_s)})", fontsize=8)
        _service_legend(ax, run, run.services_in(d), any_coupled, loc="upper left" if d == "up" else "lower left")
    return fig


def time_distance(run_dir: Path | str, out_stem: Path | str, direction: str | None = None) -> list[Path]:
    """Write the train graph as ``<out_stem>.png`` and ``.svg``; returns both paths."""
    return _save(time_distance_figure(run_dir, direction), out_stem)


# --------------------------------------------------------------------------------------------------------------
# Speed profiles
# --------------------------------------------------------------------------------------------------------------


def speed_figure(run_dir: Path | str | LineRun, direction: str | None = None) -> Figure:
    """Speed [km/h] over line km, one panel per direction (travel runs left to right), one line per trip, the
    speed limits of each service's route dashed."""
    run = run_dir if isinstance(run_dir, LineRun) else load_line_run(run_dir)
    dirs = _check_direction(run, direction)
    height = 4.6 * len(dirs) + 0.5
    fig, axes = plt.subplots(len(dirs), 1, figsize=(14, height), squeeze=False)
    fig.subplots_adjust(left=0.06, right=0.99, bottom=1.0 / height, top=1.0 - 1.75 / height, hspace=1.05)
    fig.suptitle(f"{run.name}: speed profiles", fontsize=11, y=1.0 - 0.15 / height)
    lo, hi = _km_limits(run.stations)
    for ax, d in zip(axes[:, 0], dirs):
        ax.set_gid(d)
        for svc in run.services_in(d):
            sf = run.frame.services[svc]
            xs, vs = [], []
            for a, b, v in sf.route.speed_limits:
                ka, kb = sf.km_of(np.array([a, b]))
                xs += [ka, kb]
                vs += [v * 3.6, v * 3.6]
            ax.plot(xs, vs, color="#555555", lw=0.7, ls="--", zorder=1)
        for p in run.trips_in(d):
            (line,) = ax.plot(p.km, p.speed_mps * 3.6, color=run.colours[p.service], lw=0.5, alpha=0.45, zorder=2)
            line.set_gid(p.trip_id)
        ax.set_xlim((lo, hi) if d == "up" else (hi, lo))
        ax.set_ylim(bottom=0.0)
        ax.set_xlabel("line km" + ("" if d == "up" else " (decreasing: direction of travel)"), fontsize=8)
        ax.tick_params(labelsize=7)
        top = ax.secondary_xaxis("top")
        top.set_xticks([s.km for s in run.stations], labels=[s.name for s in run.stations], rotation=90, fontsize=5.5)
        for st in run.stations:
            ax.axvline(st.km, color=GRID_COLOUR, lw=0.4, ls=(0, (4, 3)) if st.branch else "-", zorder=0)
        ax.set_ylabel(f"{d}: speed [km/h]", fontsize=8)
        handles = [Line2D([], [], color=run.colours[s], lw=1.2, label=s) for s in run.services_in(d)]
        handles.append(Line2D([], [], color="#555555", lw=0.8, ls="--", label="speed limit of the route"))
        ax.legend(
            handles=handles,
            fontsize=7,
            loc="upper right",
            bbox_to_anchor=(1.0, -0.13),
            ncol=len(handles),
            frameon=False,
        )
    return fig


def speed(run_dir: Path | str, out_stem: Path | str, direction: str | None = None) -> list[Path]:
    """Write the speed profiles as ``<out_stem>.png`` and ``.svg``; returns both paths."""
    return _save(speed_figure(run_dir, direction), out_stem)


# --------------------------------------------------------------------------------------------------------------
# Coupled gaps
# --------------------------------------------------------------------------------------------------------------

_FORMATION_STATES = ("coupling", "coupled", "decoupling")


def gap_figure(run_dir: Path | str | LineRun, direction: str | None = None) -> Figure:
    """Each formation's true gap (follower front to leader rear) [m] over time while it is coupling, coupled or
    decoupling, the coupled time shaded, its configured target gap dashed. One small panel per formation."""
    run = run_dir if isinstance(run_dir, LineRun) else load_line_run(run_dir)
    scn = run.frame.scenario
    if direction is not None:
        _check_direction(run, direction)
    forms = []
    for f in scn.formations:
        fol = scn.trip_id(f.follower)
        path = run.paths.get(fol)
        if path is not None and (direction is None or path.direction == direction):
            forms.append((f, scn.trip_id(f.leader), path))
    if not forms:
        raise ConfigError(run.run_dir, "formations", "no virtually coupled formation ran in this run: no gap plot")
    ncol = 1 if len(forms) == 1 else 2
    nrow = math.ceil(len(forms) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(6.5 * ncol, 1.9 * nrow + 1.0), squeeze=False, sharey=True)
    fig.subplots_adjust(
        left=0.08,
        right=0.98,
        bottom=0.6 / (1.9 * nrow + 1.0) + 0.02,
        top=1.0 - 0.7 / (1.9 * nrow + 1.0),
        hspace=0.65,
        wspace=0.08,
    )
    fig.suptitle(f"{run.name}: true gap of each virtually coupled formation", fontsize=11)
    for ax, (f, leader, p) in zip(axes.ravel(), forms):
        ax.set_gid(f.id)
        active = np.isin(p.formation_state, _FORMATION_STATES)
        if not active.any():
            ax.text(0.5, 0.5, "never coupled", transform=ax.transAxes, ha="center", va="center", fontsize=8)
        idx = np.flatnonzero(active)
        for a, b in _runs(p.formation_state == "coupled"):
            ax.axvspan(p.clock_s[a], p.clock_s[b], color=COUPLED_COLOUR, alpha=0.25, lw=0)
        gap = np.where(active, p.gap_m, np.nan)
        (line,) = ax.plot(p.clock_s, gap, color=run.colours[p.service], lw=0.8)
        line.set_gid(p.trip_id)
        ax.axhline(float(f.target_gap_m), color="black", lw=0.8, ls="--", zorder=1)
        if len(idx):
            t_a, t_b = p.clock_s[idx[0]], p.clock_s[idx[-1]]
            pad = 0.02 * max(t_b - t_a, 60.0)
            _time_axis(ax, t_a - pad, t_b + pad)
        else:
            ax.xaxis.set_major_formatter(FuncFormatter(clock_label))
        ax.set_title(f"{f.id}: {leader} + {p.trip_id} (target {float(f.target_gap_m):g} m)", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.set_ylabel("gap [m]", fontsize=7)
    for ax in axes.ravel()[len(forms) :]:
        ax.set_visible(False)
    coupled = [p.gap_m[p.formation_state == "coupled"] for _, _, p in forms]
    vals = np.concatenate([c[np.isfinite(c)] for c in coupled]) if coupled else np.zeros(0)
    if len(vals):  # zoom on the coupled gaps; coupling/decoupling gaps beyond 2.5x that are clipped
        axes[0, 0].set_ylim(0.0, max(2.5 * float(np.max(vals)), max(float(f.target_gap_m) for f, _, _ in forms) * 2))
    handles = [
        Line2D([], [], color="#555555", lw=0.8, label="true gap while coupling/coupled/decoupling"),
        Line2D(
            [],
            [],
            color="black",
            lw=0.8,
            ls="--",
            label="configured target gap (the gap policy may keep more at speed)",
        ),
        Line2D([], [], color=COUPLED_COLOUR, lw=6, alpha=0.4, label="coupled"),
    ]
    fig.legend(handles=handles, loc="lower center", ncol=3, fontsize=7, frameon=False)
    return fig


def gap(run_dir: Path | str, out_stem: Path | str, direction: str | None = None) -> list[Path]:
    """Write the formations' gap plots as ``<out_stem>.png`` and ``.svg``; returns both paths."""
    return _save(gap_figure(run_dir, direction), out_stem)


# --------------------------------------------------------------------------------------------------------------
# Headways
# --------------------------------------------------------------------------------------------------------------


def headway_table(run_dir: Path | str | LineRun) -> pd.DataFrame:
    """Achieved departure headways per section: the section table's rows with a headway, plus ``label`` (the
    section's start station, with its end where several sections start there) and ``vc_follower`` (the
    headway of a coupled follower behind its own leader)."""
    run_path = run_dir.run_dir if isinstance(run_dir, LineRun) else Path(run_dir)
    frame = run_dir.frame if isinstance(run_dir, LineRun) else sections.LineFrame.from_run(run_path)
    table = sections.section_table(run_path, frame)
    names = {sid: station_label(st.name) for sid, st in frame.bundle.stations.items()}
    table = table[table["headway_s"].notna()].copy()
    n_to = table.groupby(["direction", "from_station"])["to_station"].transform("nunique")
    table["label"] = [
        names.get(a, a) + (f" → {names.get(b, b)}" if n > 1 else "")
        for a, b, n in zip(table["from_station"], table["to_station"], n_to)
    ]
    table["vc_follower"] = table["formation_role"].astype(str) == "follower"
    return table


def headway_figure(run_dir: Path | str | LineRun, direction: str | None = None) -> Figure:
    """Distribution of achieved departure headways [s] per section (rows in travel order), one panel per
    direction: a box per section and every departure as a dot; coupled followers' headways in the VC colour."""
    run = run_dir if isinstance(run_dir, LineRun) else load_line_run(run_dir)
    dirs = _check_direction(run, direction)
    table = headway_table(run)
    if table.empty or not table["direction"].isin(dirs).any():
        raise ConfigError(run.run_dir, "sections", "no two trains completed the same section: no headway to plot")
    n_rows = max(
        (table[table["direction"] == d].groupby(["from_station", "to_station"]).ngroups for d in dirs), default=1
    )
    height = float(np.clip(1.5 + 0.17 * n_rows, 4.0, 14.0))
    fig, axes = plt.subplots(1, len(dirs), figsize=(6.8 * len(dirs) if len(dirs) == 2 else 8.0, height), squeeze=False)
    fig.subplots_adjust(
        left=0.2 if len(dirs) == 2 else 0.3, right=0.98, bottom=0.9 / height, top=1.0 - 0.75 / height, wspace=0.55
    )
    fig.suptitle(f"{run.name}: achieved departure headways per section", fontsize=11)
    rng = np.random.default_rng(0)  # jitter of the dots only (fixed: the same run gives the same picture)
    for ax, d in zip(axes[0], dirs):
        ax.set_gid(d)
        sub = table[table["direction"] == d]
        keys = sub.groupby(["from_station", "to_station"], sort=False)["from_km"].first()
        order = sorted(keys.index, key=lambda k: (keys[k] if d == "up" else -keys[k], k[1]))
        labels, data = [], []
        for y, key in enumerate(order):
            rows = sub[(sub["from_station"] == key[0]) & (sub["to_station"] == key[1])]
            labels.append(str(rows["label"].iloc[0]))
            h = rows["headway_s"].to_numpy(float)
            vc = rows["vc_follower"].to_numpy(bool)
            data.append(h[~vc])
            jitter = rng.uniform(-0.25, 0.25, len(h))
            ax.scatter(h[~vc], y + jitter[~vc], s=4, color="#444444", alpha=0.5, lw=0, zorder=3)
            ax.scatter(h[vc], y + jitter[vc], s=9, color=COUPLED_COLOUR, edgecolor="#8a6d00", lw=0.3, zorder=4)
        if data:
            ax.boxplot(
                data,
                positions=range(len(data)),
                orientation="horizontal",
                widths=0.6,
                showfliers=False,
                medianprops={"color": "#0072B2", "lw": 1.2},
                boxprops={"lw": 0.7},
                whiskerprops={"lw": 0.7},
                capprops={"lw": 0.7},
                manage_ticks=False,
            )
        ax.set_yticks(range(len(labels)), labels=labels, fontsize=6)
        ax.set_ylim(max(len(labels), 1) - 0.5, -0.5)  # travel order top to bottom
        if not labels:
            ax.text(0.5, 0.5, "no headway in this direction", transform=ax.transAxes, ha="center", fontsize=8)
        ax.set_xscale("symlog", linthresh=10.0, linscale=0.6)
        ticks = [0, 10, 30, 60, 120, 300, 600, 1200, 3600]
        top = float(np.nanmax(sub["headway_s"])) if len(sub) else 600.0
        ax.set_xticks([t for t in ticks if t <= max(top * 1.5, 10)])
        ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _p: f"{v:g}"))
        ax.set_xlim(-0.5, max(top * 1.5, 10))
        ax.grid(axis="x", color="#e0e0e0", lw=0.5)
        ax.set_axisbelow(True)
        ax.tick_params(axis="x", labelsize=7)
        ax.set_xlabel("departure headway behind the previous train on the section [s]", fontsize=8)
        ax.set_title(f"{d}: {len(sub)} headways on {len(order)} sections", fontsize=9)
    handles = [
        Line2D([], [], ls="", marker="o", ms=3, color="#444444", label="departure headway"),
        Line2D([], [], ls="", marker="o", ms=4, color=COUPLED_COLOUR, label="coupled follower behind its leader"),
        Line2D([], [], color="#0072B2", lw=1.2, label="median of the other headways (box: quartiles)"),
    ]
    fig.legend(handles=handles, loc="lower center", ncol=3, fontsize=7, frameon=False)
    return fig


def headway(run_dir: Path | str, out_stem: Path | str, direction: str | None = None) -> list[Path]:
    """Write the headway distributions as ``<out_stem>.png`` and ``.svg``; returns both paths."""
    return _save(headway_figure(run_dir, direction), out_stem)


# --------------------------------------------------------------------------------------------------------------
# By name (for railsim plot and the report)
# --------------------------------------------------------------------------------------------------------------

FIGURES: dict[str, Callable[..., Figure]] = {
    "time-distance": time_distance_figure,
    "speed": speed_figure,
    "gap": gap_figure,
    "headway": headway_figure,
}


def write_kind(
    kind: str, run_dir: Path | str | LineRun, out_stem: Path | str, direction: str | None = None
) -> list[Path]:
    """Write figure ``kind`` (one of :data:`KINDS`) of a run; returns the PNG and SVG paths."""
    if kind not in FIGURES:
        raise ConfigError(None, "kind", f"expected one of {', '.join(KINDS)}, got {kind!r}")
    return _save(FIGURES[kind](run_dir, direction), out_stem)
