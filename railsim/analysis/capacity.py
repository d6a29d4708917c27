"""Line capacity of a finished run: achieved headways, throughput and UIC 406 occupancy per line section.

Three readings of the same run, one table each (:func:`analyse_run` → :class:`CapacityReport`):

**Achieved headways** (``headways``, ``junction``). The time between consecutive *paths* leaving a section
(see :mod:`railsim.analysis.sections` for sections), per direction, as a distribution (min, p5, median, mean, p95, max).
A virtually coupled formation is one path: its follower is not a train of its own on the timetable graph, so it
is left out of the path headways (its 0–1 s "headway" behind the leader is in the section table). At a junction
(every switch of the world, e.g. Bijin's ``bijin_up`` diverge and ``bijin_down`` merge) the times are those at
which each train's front passes the switch point (interpolated in the trace); units decoupled before the switch
pass it one by one, so there every unit counts.

**Throughput** (``throughput``, ``directions``). Trains per hour and passengers per hour per section and
direction over the section's *busiest hour* (the 3600 s window, starting at a departure, holding the most path
departures). Passengers = the vehicles' ``capacity_pax`` (data pack: 6-car 1342, 8-car 1802) summed over the
units; a coupled formation carries both units' passengers while it occupies one path. ``directions`` keeps the
busiest section of each direction.

**UIC 406 occupancy by the compression method** (``uic406``). UIC Code 406 (2004; 2nd ed. 2013) defines

* *blocking time* of a block section for a train: the time the section is reserved for it — from the moment the
  train would have to see it clear (start of its approach) until its rear has cleared it and it is released;
  the blocking times along a line form the train's *blocking-time stairway*;
* *compression*: the paths of a time window are pushed together, in their given order and with their running
  times unchanged, until consecutive stairways touch (zero buffer); the minimum headway ``H(i, j)`` between
  path ``i`` and the next path ``j`` is the smallest shift at which no block is blocked by both;
* *occupancy time*: the length of the compressed sequence; for a periodic timetable the sequence repeats, so
  the last path is followed by the first of the next period: ``A = Σ_i H(i, i+1)`` with ``H(n, 1)`` closing the
  cycle;
* *capacity consumption* (occupancy) ``= A / U``, ``U`` the time window (here the section's busiest hour).
  The leaflet's recommended limits (2004, Table 2, peak hour / daily period): dedicated suburban passenger
  traffic 85 % / 70 %, dedicated high-speed lines 75 % / 60 %, mixed-traffic lines 75 % / 60 %. A metro line
  such as Chongqing Line 3 is dedicated suburban passenger traffic: :data:`PEAK_LIMIT_SUBURBAN` = 0.85 is the
  default ``limit`` (pass ``limit=0.75`` for the stricter high-speed/mixed figure).

Block model (our reading for a **moving-block** line; the simulated line has no signals). A train reserves the
track from its rear to the end of its *claim*::

    claim(t) = x_front(t) + v·T + v² / (2·b) + margin          (made non-decreasing in t)

the absolute braking distance of :func:`controllers.braking.stopping_distance_m` at zero present acceleration,
with ``b`` the vehicle's service deceleration, ``T`` = :func:`controllers.braking.build_up_delay_s` with the
separation controller's ``reaction_time_s`` plus one control step (as the separation controller counts it), and
``margin`` its ``margin_m`` (defaults 1 s and 50 m when the run has no separation controller). With
``block_length_m = 0`` (the default, *moving block*) every point ``x`` of a section (on a ``resolution_m`` grid)
is a block of zero length, blocked from the moment the claim reaches ``x`` until the rear passes ``x``. With
``block_length_m > 0`` the section is cut into fixed virtual blocks of that length (the data pack estimates
400 m for Line 3's speed-code fixed block), each blocked from "claim reaches its entry" to "rear clears its exit".
A section runs from the departure stopping mark to the arrival stopping mark, so the arrival platform and the
dwell there belong to the section; at a terminal the last blocks are released when the train is removed. A
coupled formation is compressed as one path: its claim is the leader's, its rear the follower's.

Closed form (a test): identical trains at constant speed ``v`` on one section of length ``S`` in moving block give
``H = (L + v·T + v²/(2b) + margin) / v`` for every pair, so occupancy = ``n·H / U``.

Times are simulation seconds; distances metres along each train's route, measured from the section's
departure stopping mark.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from controllers.braking import build_up_delay_s, stopping_distance_m
from railsim.analysis.sections import LineFrame, read_table, section_table
from railsim.errors import ConfigError

PEAK_LIMIT_SUBURBAN = 0.85  # UIC 406 (2004) Table 2: dedicated suburban passenger traffic, peak hour
PEAK_LIMIT_MIXED = 0.75  # UIC 406 (2004) Table 2: mixed-traffic and dedicated high-speed lines, peak hour
DEFAULT_MARGIN_M = 50.0  # controllers.separation default
DEFAULT_REACTION_S = 1.0  # controllers.separation default
HOUR_S = 3600.0


# --------------------------------------------------------------------------------------------------------------
# Blocking times and compression (pure functions, tested by closed forms)
# --------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BlockModel:
    """How a path reserves track: see the module docstring. ``block_length_m = 0`` is moving block."""

    block_length_m: float = 0.0
    resolution_m: float = 10.0  # grid of the moving-block points [m]
    margin_m: float = DEFAULT_MARGIN_M
    reaction_s: float = DEFAULT_REACTION_S

    def __post_init__(self) -> None:
        for name in ("block_length_m", "margin_m", "reaction_s"):
            if not (getattr(self, name) >= 0.0 and math.isfinite(getattr(self, name))):
                raise ConfigError("<capacity>", name, f"expected a number >= 0, got {getattr(self, name)!r}")
        if not (self.resolution_m > 0.0 and math.isfinite(self.resolution_m)):
            raise ConfigError("<capacity>", "resolution_m", f"expected a number > 0, got {self.resolution_m!r}")

    def blocks(self, section_length_m: float) -> tuple[np.ndarray, np.ndarray]:
        """``(entry_m, exit_m)`` of the blocks covering ``[0, section_length_m]``."""
        if section_length_m <= 0.0:
            raise ValueError(f"section length must be > 0, got {section_length_m}")
        step = self.block_length_m if self.block_length_m > 0.0 else self.resolution_m
        n = max(int(math.ceil(section_length_m / step - 1e-9)), 1)
        entry = np.minimum(np.arange(n) * step, section_length_m)
        if self.block_length_m > 0.0:
            return entry, np.minimum(entry + step, section_length_m)
        points = np.append(entry, section_length_m)
        return points, points.copy()

    @property
    def label(self) -> str:
        if self.block_length_m > 0.0:
            return f"fixed virtual blocks of {self.block_length_m:g} m"
        return f"moving block (points every {self.resolution_m:g} m)"


def claim_m(
    front_m: np.ndarray, speed_mps: np.ndarray, decel_mps2: float, delay_s: float, margin_m: float
) -> np.ndarray:
    """End of the track a train reserves ahead of its front: absolute braking distance + margin, made
    non-decreasing in time (a claim, once made, is not given back while the train is still behind it)."""
    brake = np.array([stopping_distance_m(float(v), decel_mps2, delay_s) for v in speed_mps])
    return np.maximum.accumulate(np.asarray(front_m, dtype=float) + brake + margin_m)


def first_time_at(t_s: np.ndarray, x_m: np.ndarray, targets_m: np.ndarray) -> np.ndarray:
    """For each target, the first time the non-decreasing sampled curve ``x(t)`` reaches it (linear between
    samples); ``t_s[0]`` if already reached at the first sample, NaN if never reached."""
    x = np.maximum.accumulate(np.asarray(x_m, dtype=float))
    t = np.asarray(t_s, dtype=float)
    idx = np.searchsorted(x, targets_m, side="left")
    out = np.full(len(targets_m), np.nan)
    for k, (i, target) in enumerate(zip(idx, targets_m)):
        if i == 0:
            out[k] = t[0]
        elif i < len(x):
            x0, x1 = x[i - 1], x[i]
            frac = (target - x0) / (x1 - x0) if x1 > x0 else 1.0
            out[k] = t[i - 1] + frac * (t[i] - t[i - 1])
    return out


@dataclass(frozen=True)
class Stairway:
    """A path's blocking times on one section, relative to its reference time (departure from the section)."""

    path: str
    reference_s: float
    start_s: np.ndarray  # per block: start of blocking, relative to reference_s
    end_s: np.ndarray  # per block: end of blocking (release), relative to reference_s


def stairway(
    path: str,
    reference_s: float,
    t_claim_s: np.ndarray,
    claim: np.ndarray,
    t_rear_s: np.ndarray,
    rear_m: np.ndarray,
    blocks: tuple[np.ndarray, np.ndarray],
    released_by_s: float,
) -> Stairway:
    """Blocking times of one path on a section: a block is blocked from the first time ``claim`` reaches its
    entry until the first time ``rear`` passes its exit (``released_by_s`` if the rear never does: a train removed
    at its terminal)."""
    entry, exit_ = blocks
    start = first_time_at(t_claim_s, claim, entry)
    end = first_time_at(t_rear_s, rear_m, exit_)
    end = np.where(np.isnan(end), released_by_s, end)
    return Stairway(path, reference_s, start - reference_s, end - reference_s)


def min_headway_s(ahead: Stairway, behind: Stairway) -> float:
    """UIC 406 minimum headway: the smallest time from ``ahead``'s reference to ``behind``'s at which no block
    is blocked by both, ``max_k (end_k(ahead) − start_k(behind))`` in the paths' own relative times."""
    diff = ahead.end_s - behind.start_s
    if np.all(np.isnan(diff)):
        raise ValueError(f"paths {ahead.path!r} and {behind.path!r} share no blocked block")
    return float(np.nanmax(diff))


def compress(stairways: Sequence[Stairway]) -> tuple[float, list[float]]:
    """Compressed occupancy time ``A`` of a periodic sequence (in the given order) and the minimum headways
    ``H(i, i+1)`` (the last one is ``H(n, 1)``, the first path of the next period)."""
    if not stairways:
        return 0.0, []
    heads = [min_headway_s(a, b) for a, b in zip(stairways, list(stairways[1:]) + [stairways[0]])]
    return float(sum(heads)), heads


# --------------------------------------------------------------------------------------------------------------
# The report
# --------------------------------------------------------------------------------------------------------------


def markdown_table(frame: pd.DataFrame, digits: int = 1) -> str:
    """A GitHub-flavoured Markdown table of ``frame`` (floats rounded to ``digits``; NaN shown as ``–``)."""

    def cell(v: Any) -> str:
        if isinstance(v, (float, np.floating)):
            return "–" if math.isnan(v) else f"{v:.{digits}f}"
        return str(v).replace("|", "\\|")

    cols = [str(c) for c in frame.columns]
    lines = ["| " + " | ".join(cols) + " |", "|" + "|".join("---" for _ in cols) + "|"]
    for row in frame.itertuples(index=False):
        lines.append("| " + " | ".join(cell(v) for v in row) + " |")
    return "\n".join(lines)


@dataclass
class CapacityReport:
    """The capacity analyses of one run. ``tables``: ``headways``, ``junction``, ``throughput``, ``directions``,
    ``uic406`` and ``uic406_pairs`` (per consecutive pair of paths in the window: minimum headway, achieved
    headway between their departures and the buffer time, achieved − minimum); ``params``: the block model,
    period and limit used."""

    run_dir: Path
    tables: dict[str, pd.DataFrame]
    params: dict[str, Any] = field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        """Flat scalars per direction: busiest-section trains/h, paths/h, pax/h, max UIC 406 occupancy, median
        path headway on the busiest section."""
        out: dict[str, Any] = {}
        for row in self.tables["directions"].itertuples(index=False):
            for col in ("trains_per_h", "paths_per_h", "pax_per_h", "max_occupancy", "max_occupancy_section"):
                out[f"{row.direction}.{col}"] = getattr(row, col)
        return out

    def to_markdown(self) -> str:
        """The report as Markdown: one heading and table per analysis."""
        p = self.params
        parts = [
            "## Capacity",
            f"Busiest hour per section ({p['period_s']:g} s window). UIC 406 compression with "
            f"{p['block_model']}, braking at the vehicle's service deceleration, reaction + control step "
            f"{p['reaction_s']:g} s, margin {p['margin_m']:g} m; limit {100 * p['limit']:.0f} % (UIC 406 peak hour, "
            f"{p['limit_label']}). A virtually coupled formation counts as one path carrying both units.",
            "### Per direction (busiest section)",
            markdown_table(self.tables["directions"], 2),
            "### Throughput per section",
            markdown_table(self.tables["throughput"], 1),
            "### UIC 406 occupancy per section",
            markdown_table(self.tables["uic406"], 3),
            "### Achieved path headways per section [s]",
            markdown_table(self.tables["headways"], 1),
            "### Junction headways (front passing the switch) [s]",
            markdown_table(self.tables["junction"], 1),
        ]
        return "\n\n".join(parts) + "\n"


def _busiest_window(departures_s: np.ndarray, period_s: float) -> tuple[float, np.ndarray]:
    """Start of the window ``[w, w + period)`` (``w`` a departure) holding most departures, and the mask."""
    d = np.sort(departures_s)
    best_w, best_n = float(d[0]), -1
    for w in d:
        n = int(np.count_nonzero((d >= w) & (d < w + period_s)))
        if n > best_n:
            best_w, best_n = float(w), n
    return best_w, (departures_s >= best_w) & (departures_s < best_w + period_s)


def _stats(values: np.ndarray) -> dict[str, float]:
    if len(values) == 0:
        return {
            "min_s": math.nan,
            "p5_s": math.nan,
            "median_s": math.nan,
            "mean_s": math.nan,
            "p95_s": math.nan,
            "max_s": math.nan,
        }
    return {
        "min_s": float(np.min(values)),
        "p5_s": float(np.percentile(values, 5)),
        "median_s": float(np.median(values)),
        "mean_s": float(np.mean(values)),
        "p95_s": float(np.percentile(values, 95)),
        "max_s": float(np.max(values)),
    }


def _separation_params(scn: Any) -> tuple[float, float]:
    """(margin_m, reaction_time_s) of the scenario's separation controller, else the defaults."""
    name = scn.roles.get("separation")
    spec = scn.controllers.get(name) if name else None
    params = dict(spec.params) if spec is not None else {}
    return float(params.get("margin_m", DEFAULT_MARGIN_M)), float(params.get("reaction_time_s", DEFAULT_REACTION_S))


def _section_label(row: Any) -> str:
    return f"{row.from_station} → {row.to_station}"


def analyse_run(
    run_dir: str | Path,
    *,
    block_length_m: float = 0.0,
    resolution_m: float = 10.0,
    period_s: float = HOUR_S,
    limit: float = PEAK_LIMIT_SUBURBAN,
    sections: pd.DataFrame | None = None,
    frame: LineFrame | None = None,
) -> CapacityReport:
    """Headways, throughput and UIC 406 occupancy of the run in ``run_dir`` (see the module docstring).

    ``block_length_m`` 0 = moving block; > 0 fixed virtual blocks. ``period_s`` is the UIC 406 time window
    (the busiest ``period_s`` of each section). ``limit`` the occupancy limit flagged in the table.
    """
    if not (period_s > 0.0 and math.isfinite(period_s)):
        raise ConfigError("<capacity>", "period_s", f"expected a number > 0, got {period_s!r}")
    if not (0.0 < limit <= 1.0):
        raise ConfigError("<capacity>", "limit", f"expected a fraction in (0, 1], got {limit!r}")
    run = Path(run_dir)
    frame = frame or LineFrame.from_run(run)
    secs = sections if sections is not None else section_table(run, frame)
    if secs.empty:
        raise ConfigError(run, None, "the run has no completed line section (no train ran between two stations)")
    margin_m, reaction_time_s = _separation_params(frame.scenario)
    step_s = float(frame.scenario.simulation.step_s)
    model = BlockModel(block_length_m, resolution_m, margin_m, reaction_time_s + step_s)
    trips = read_table(run, "trips").set_index("trip_id")
    by_train = frame.trace_by_train()

    # per trip: time, front, claim, rear arrays in its route frame (claim uses the path's vehicle)
    cache: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def arrays(trip: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if trip not in cache:
            g = by_train.get(trip)
            if g is None or g.empty:
                raise ConfigError(run / "trace.csv", "train", f"no trace samples for trip {trip!r}")
            veh = frame.scenario.vehicle_of(str(trips.at[trip, "service"]))
            delay = build_up_delay_s(
                0.0, veh.service_decel_mps2, veh.actuator_time_constant_s, veh.jerk_limit_mps3, model.reaction_s
            )
            t = g["t_s"].to_numpy(float)
            x = g["chainage_m"].to_numpy(float)
            c = claim_m(x, g["speed_mps"].to_numpy(float), veh.service_decel_mps2, delay, model.margin_m)
            cache[trip] = (t, x, c)
        return cache[trip]

    def end_of(trip: str) -> float:
        t_last = float(arrays(trip)[0][-1])
        arr = trips.at[trip, "arrival_s"]
        return max(t_last, float(arr)) if not pd.isna(arr) else t_last

    head_rows, thr_rows, uic_rows, pair_rows = [], [], [], []  # type: ignore[var-annotated]
    paths_all = secs[secs["formation_role"] != "follower"]
    for (direction, a, b), grp in secs.groupby(["direction", "from_station", "to_station"], sort=False):
        paths = paths_all[
            (paths_all["direction"] == direction) & (paths_all["from_station"] == a) & (paths_all["to_station"] == b)
        ].sort_values("departure_s", kind="mergesort")
        if paths.empty:  # only followers ran here, their leaders elsewhere (before a merge): each is a path
            paths = grp.sort_values("departure_s", kind="mergesort")
        first = grp.iloc[0]
        label = {
            "direction": direction,
            "section": _section_label(first),
            "from_km": first.from_km,
            "to_km": first.to_km,
        }
        dep = paths["departure_s"].to_numpy(float)
        head_rows.append({**label, "paths": len(paths), **_stats(np.diff(dep))})

        w0, mask = _busiest_window(dep, period_s)
        win = paths[mask]
        units = grp[(grp["departure_s"] >= w0) & (grp["departure_s"] < w0 + period_s)]
        pax = sum(frame.capacity_pax(s) for s in units["service"])
        scale = HOUR_S / period_s
        thr_rows.append(
            {
                **label,
                "window_start_s": w0,
                "paths_per_h": len(win) * scale,
                "trains_per_h": len(units) * scale,
                "pax_per_h": pax * scale,
            }
        )

        # UIC 406: one stairway per path in the window (a formation: leader's claim, follower's rear)
        length = float(first.length_m)
        if length <= 0.0:  # two stops at one mark (an imported route stopping twice at one station): no running
            continue
        blocks = model.blocks(length)
        stairs = []
        for row in win.itertuples(index=False):
            lead = str(row.trip_id)
            rear_trip = lead
            if row.formation_role == "leader":
                fol = grp[(grp["formation"] == row.formation) & (grp["formation_role"] == "follower")]
                if not fol.empty:
                    rear_trip = str(fol.iloc[0]["trip_id"])
            lf = frame.services[str(row.service)]
            t_c, _, claim = arrays(lead)
            t_r, x_r, _ = arrays(rear_trip)
            rf = frame.services[str(trips.at[rear_trip, "service"])]
            rear = x_r - rf.mark_m[a] - frame.length_m(rf.service)
            stairs.append(
                stairway(lead, float(row.departure_s), t_c, claim - lf.mark_m[a], t_r, rear, blocks, end_of(rear_trip))
            )
        compressed, heads = compress(stairs)
        occ = compressed / period_s
        for ahead, behind, h in zip(stairs, stairs[1:], heads):
            achieved = behind.reference_s - ahead.reference_s
            pair_rows.append(
                {
                    **label,
                    "ahead": ahead.path,
                    "behind": behind.path,
                    "min_headway_s": h,
                    "achieved_s": achieved,
                    "buffer_s": achieved - h,
                }
            )
        uic_rows.append(
            {
                **label,
                "paths": len(stairs),
                "window_start_s": w0,
                "min_headway_mean_s": float(np.mean(heads)) if heads else math.nan,
                "min_headway_max_s": float(np.max(heads)) if heads else math.nan,
                "compressed_s": compressed,
                "occupancy": occ,
                "paths_per_h_at_limit": (limit * HOUR_S / float(np.mean(heads))) if heads else math.nan,
                "over_limit": bool(occ > limit),
            }
        )

    headways = pd.DataFrame(head_rows)
    throughput = pd.DataFrame(thr_rows)
    uic = pd.DataFrame(uic_rows)
    directions = []
    for direction, g in throughput.groupby("direction", sort=True):
        best = g.sort_values(["paths_per_h", "pax_per_h"], ascending=False, kind="mergesort").iloc[0]
        u = uic[uic["direction"] == direction]
        worst = u.sort_values("occupancy", ascending=False, kind="mergesort").iloc[0]
        directions.append(
            {
                "direction": direction,
                "busiest_section": best.section,
                "trains_per_h": best.trains_per_h,
                "paths_per_h": best.paths_per_h,
                "pax_per_h": best.pax_per_h,
                "max_occupancy": worst.occupancy,
                "max_occupancy_section": worst.section,
            }
        )
    return CapacityReport(
        run,
        {
            "headways": headways,
            "junction": junction_table(run, frame),
            "throughput": throughput,
            "directions": pd.DataFrame(directions),
            "uic406": uic,
            "uic406_pairs": pd.DataFrame(pair_rows),
        },
        {
            "block_model": model.label,
            "block_length_m": block_length_m,
            "resolution_m": resolution_m,
            "margin_m": margin_m,
            "reaction_s": model.reaction_s,
            "period_s": period_s,
            "limit": limit,
            "limit_label": "dedicated suburban passenger traffic" if limit == PEAK_LIMIT_SUBURBAN else "user-given",
        },
    )


def junction_passes(run_dir: str | Path, frame: LineFrame | None = None) -> pd.DataFrame:
    """One row per (switch, trip) whose route passes the switch: ``t_pass_s`` when the front passed the switch
    point (linear between trace samples; NaN if the train never got there)."""
    run = Path(run_dir)
    frame = frame or LineFrame.from_run(run)
    by_train = frame.trace_by_train()
    rows = []
    for tid, svc in read_table(run, "trips")[["trip_id", "service"]].itertuples(index=False):
        sf = frame.services.get(str(svc))
        if sf is None:
            continue
        for sw in sf.route.switches:
            g = by_train.get(tid)
            t = math.nan
            if g is not None and not g.empty:
                t = float(
                    first_time_at(g["t_s"].to_numpy(float), g["chainage_m"].to_numpy(float), np.array([sw.point_m]))[0]
                )
            rows.append(
                {"switch": sw.switch_id, "leg": sw.leg, "trip_id": str(tid), "service": str(svc), "t_pass_s": t}
            )
    return (
        pd.DataFrame(rows, columns=["switch", "leg", "trip_id", "service", "t_pass_s"])
        .sort_values(["switch", "t_pass_s"], kind="mergesort")
        .reset_index(drop=True)
    )


def junction_table(run_dir: str | Path, frame: LineFrame | None = None) -> pd.DataFrame:
    """Per switch: trains passed and the distribution of the time between consecutive fronts passing it."""
    passes = junction_passes(run_dir, frame)
    rows = []
    for sw, g in passes.groupby("switch", sort=True):
        t = g["t_pass_s"].dropna().to_numpy(float)
        legs = g.dropna(subset=["t_pass_s"])["leg"].value_counts()
        rows.append(
            {
                "switch": sw,
                "trains": len(t),
                "normal_leg": int(legs.get("normal", 0)),
                "reverse_leg": int(legs.get("reverse", 0)),
                **_stats(np.diff(np.sort(t))),
            }
        )
    return pd.DataFrame(
        rows,
        columns=[
            "switch",
            "trains",
            "normal_leg",
            "reverse_leg",
            "min_s",
            "p5_s",
            "median_s",
            "mean_s",
            "p95_s",
            "max_s",
        ],
    )
