"""Paper A's tracking metrics (spec 000 §7, Table III/IV format) computed after a run, from its output folder.

What a run leaves behind is enough: ``trace.csv`` (written at ``trace_stride_s`` = the step, ground truth) and
``scenario.resolved.yaml`` (which train follows which, the vehicles, the controllers). No SUMO, no controller
objects: the same function scores a railsim run and a run of any other engine that writes these two files.

Definitions, per follower ``i`` of a formation ``(leader i−1, follower i)``, at the samples where both trains are
in the trace:

* ``Δv_i = v_{i−1} − v_i`` and front-to-front ``ΔS_i = gap_m + L_{i−1}`` (``gap_m`` is the recorder's true
  front-to-rear gap to the train ahead, which in these scenarios is the predecessor; A3);
* ``D^(e)`` (Eq. 5) and ``D^(s)`` (Eq. 6) from the two speeds, with the units' length and braking rates from the
  resolved vehicles and ``L^(s) = 1.5·v_m`` (A4, :data:`controllers.mcf_dmpc.spacing.TABLE_I`);
* **paper time** ``t = t_s − t_first``: the recorder's first sample of a train is its state at insertion (engine
  time 1 s for a departure at 0), which is the paper's ``t = 0``;
* means of ``|Δv|`` and ``|ΔS − D^(e)|`` over all samples, and over the late phase ``t ∈ [late_start_s,
  late_end_s)`` (A7: [300, 500) s; ``None`` for S-E, whose Table IV uses the whole cycle);
* VC-establishment time (A33): ``|ΔS − D^(e)| ≤ 10 m`` and ``|Δv| ≤ 0.01 m/s``, reported both as the first
  sample that satisfies it and as the start of the first stretch that keeps satisfying it for ``sustain_s``
  (30 s); NaN when never;
* ``min(ΔS − D^(s))`` (safety, must be ≥ 0);
* solve time mean / p95 of the follower's controller and its fallback count. The fallback count comes from
  ``trips.csv``. Solve times need a per-step column the recorder does not write yet: ``solve_time_s`` in
  ``trace.csv`` (the winning command's ``Command.info["solve_time_s"]``, empty when absent). Until then the
  solve-time fields are NaN and ``wall_per_train_step_s`` (run wall time / steps / followers, from
  ``summary.json``) is an upper bound that includes SUMO and the engine.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from controllers.mcf_dmpc.spacing import TABLE_I, TrainParamsA, desired_spacing_m, safe_spacing_m
from railsim.errors import ConfigError

__all__ = [
    "FollowerRow",
    "FollowerSeries",
    "VcCriterion",
    "follower_row",
    "follower_series",
    "format_table",
    "paper000_metrics",
    "score_series",
    "vc_times",
]


@dataclass(frozen=True)
class VcCriterion:
    """A33: the VC-established band and how long it must hold for the "sustained" time; A7 late phase."""

    spacing_tol_m: float = 10.0
    speed_tol_mps: float = 0.01
    sustain_s: float = 30.0
    late_start_s: float | None = 300.0  # None: no late phase (S-E)
    late_end_s: float = 500.0


@dataclass(frozen=True)
class FollowerRow:
    """One line of Table III/IV: a follower's tracking, safety and effort."""

    follower: str
    leader: str
    controller: str
    samples: int
    mean_abs_dv_mps: float
    mean_abs_spacing_error_m: float
    late_mean_abs_dv_mps: float  # NaN without a late phase
    late_mean_abs_spacing_error_m: float
    vc_first_s: float  # NaN: never
    vc_sustained_s: float
    min_safety_margin_m: float  # min(ΔS − D^(s))
    final_spacing_error_m: float  # ΔS − D^(e) at the last sample (sign shows a steady offset)
    solve_time_mean_s: float  # NaN: not recorded (see module docstring)
    solve_time_p95_s: float
    fallbacks: int


def vc_times(t_s: np.ndarray, ok: np.ndarray, sustain_s: float) -> tuple[float, float]:
    """First time ``ok`` holds, and the start of the first run of ``ok`` lasting ≥ ``sustain_s`` (NaN if never).

    A run lasts from its first to its last true sample, so with 1 s samples "30 s" needs 31 consecutive hits.
    """
    hits = np.flatnonzero(ok)
    first = float(t_s[hits[0]]) if hits.size else math.nan
    start: int | None = None
    for k in range(len(t_s)):
        if not ok[k]:
            start = None
            continue
        if start is None:
            start = k
        if t_s[k] - t_s[start] >= sustain_s - 1e-9:
            return first, float(t_s[start])
    return first, math.nan


def follower_row(
    t_s: np.ndarray,
    v_lead: np.ndarray,
    v_fol: np.ndarray,
    spacing_m: np.ndarray,
    unit: TrainParamsA,
    lead_length_m: float,
    lead_emergency_mps2: float,
    criterion: VcCriterion = VcCriterion(),
    *,
    follower: str = "",
    leader: str = "",
    controller: str = "",
    solve_time_s: np.ndarray | None = None,
    fallbacks: int = 0,
) -> FollowerRow:
    """The metrics of one follower from aligned samples (``t_s`` paper time, front-to-front ``spacing_m``)."""
    if len(t_s) == 0:
        raise ValueError(f"follower {follower!r}: no samples shared with its leader {leader!r}")
    dv = v_lead - v_fol
    err = spacing_m - desired_spacing_m(v_fol, v_lead, unit, lead_length_m, lead_emergency_mps2)
    margin = spacing_m - safe_spacing_m(v_fol, v_lead, unit, lead_length_m, lead_emergency_mps2)
    ok = (np.abs(err) <= criterion.spacing_tol_m) & (np.abs(dv) <= criterion.speed_tol_mps)
    first, sustained = vc_times(t_s, ok, criterion.sustain_s)
    late = np.zeros(len(t_s), dtype=bool)
    if criterion.late_start_s is not None:
        late = (t_s >= criterion.late_start_s) & (t_s < criterion.late_end_s)
    st = np.asarray(solve_time_s, dtype=float) if solve_time_s is not None else np.array([])
    st = st[np.isfinite(st)]
    return FollowerRow(
        follower=follower,
        leader=leader,
        controller=controller,
        samples=int(len(t_s)),
        mean_abs_dv_mps=float(np.mean(np.abs(dv))),
        mean_abs_spacing_error_m=float(np.mean(np.abs(err))),
        late_mean_abs_dv_mps=float(np.mean(np.abs(dv[late]))) if late.any() else math.nan,
        late_mean_abs_spacing_error_m=float(np.mean(np.abs(err[late]))) if late.any() else math.nan,
        vc_first_s=first,
        vc_sustained_s=sustained,
        min_safety_margin_m=float(np.min(margin)),
        final_spacing_error_m=float(err[-1]),
        solve_time_mean_s=float(np.mean(st)) if st.size else math.nan,
        solve_time_p95_s=float(np.percentile(st, 95)) if st.size else math.nan,
        fallbacks=int(fallbacks),
    )


# ------------------------------------------------------------------------------------------------------------------
# Output folders


def _read_csv(path: Path) -> list[dict[str, str]]:
    if not path.is_file():
        raise ConfigError(str(path), "", "missing (not a railsim output folder, or written without csv format)")
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def _float(text: str | None) -> float:
    return float(text) if text not in (None, "") else math.nan


def _trip_of(raw: Mapping[str, Any], ref: Mapping[str, Any]) -> str:
    """Formation reference ``{service, trip}`` → trip id (``<service>.<index:03d>``, railsim's naming)."""
    return f"{ref['service']}.{int(ref.get('trip', 0)):03d}"


def _coupled_spec(raw: Mapping[str, Any], service_id: str) -> tuple[str, Mapping[str, Any]]:
    """``(instance name, controller mapping)`` of a service's ``coupled`` role in the resolved scenario."""
    roles = dict(raw.get("roles", {}))
    for svc in raw.get("services", []):
        if svc.get("id") == service_id:
            roles.update(svc.get("roles") or {})
    inst = roles.get("coupled")
    return str(inst or ""), ((raw.get("controllers") or {}).get(inst, {}) if inst else {})


def _controller_of(raw: Mapping[str, Any], service_id: str) -> str:
    inst, ctl = _coupled_spec(raw, service_id)
    return str(ctl.get("type", inst or ""))


def _safety_margin_of(raw: Mapping[str, Any], service_id: str) -> float:
    """L^(s) the follower's controller used (its ``safety_margin_m`` parameter), else Table I's 1.5·v_m."""
    _, ctl = _coupled_spec(raw, service_id)
    value = (ctl.get("params") or {}).get("safety_margin_m")
    return float(value) if value is not None else TABLE_I.safety_margin_m


@dataclass(frozen=True)
class FollowerSeries:
    """One formation's aligned samples from a run (paper time ``t_s``, front-to-front ``spacing_m``)."""

    follower: str
    leader: str
    controller: str
    t_s: np.ndarray
    v_lead_mps: np.ndarray
    v_fol_mps: np.ndarray
    spacing_m: np.ndarray
    desired_m: np.ndarray  # D^(e), Eq. (5)
    safe_m: np.ndarray  # D^(s), Eq. (6)
    solve_time_s: np.ndarray | None  # None: not recorded
    unit: TrainParamsA
    lead_length_m: float
    lead_emergency_mps2: float
    objective: np.ndarray | None = None  # the controller's J per sample (NaN where it did not report one)


def _load_run(out: Path) -> tuple[dict[str, Any], list[FollowerSeries], dict[str, int], dict[str, Any], bool]:
    resolved = out / "scenario.resolved.yaml"
    if not resolved.is_file():
        raise ConfigError(str(out), "scenario.resolved.yaml", "missing (not a railsim output folder)")
    raw = yaml.safe_load(resolved.read_text(encoding="utf-8"))
    formations = raw.get("formations") or []
    if not formations:
        raise ConfigError(str(resolved), "formations", "no formation: nothing to score (Paper A runs chain them)")
    vehicles = raw.get("vehicles") or {}
    service_vehicle = {s["id"]: vehicles[s["vehicle"]] for s in raw.get("services", [])}

    rows = _read_csv(out / "trace.csv")
    has_solve = bool(rows) and "solve_time_s" in rows[0]
    by_train: dict[str, list[dict[str, str]]] = {}
    for r in rows:
        by_train.setdefault(r["train"], []).append(r)
    series: dict[str, dict[str, np.ndarray]] = {}
    for train, rs in by_train.items():
        series[train] = {
            "t": np.array([float(r["t_s"]) for r in rs]),
            "v": np.array([float(r["speed_mps"]) for r in rs]),
            "gap": np.array([_float(r["gap_m"]) for r in rs]),
            "solve": np.array([_float(r.get("solve_time_s")) for r in rs]) if has_solve else np.array([]),
            "objective": np.array([_float(r.get("objective")) for r in rs]),
        }
    fallbacks = {r["trip_id"]: int(float(r["fallbacks"] or 0)) for r in _read_csv(out / "trips.csv")}
    summary_path = out / "summary.json"
    summary = json.loads(summary_path.read_text(encoding="utf-8")) if summary_path.is_file() else {}

    result = []
    for f in formations:
        lead_id, fol_id = _trip_of(raw, f["leader"]), _trip_of(raw, f["follower"])
        if lead_id not in series or fol_id not in series:
            # a train without trace samples (not inserted yet; trips.csv gives its status, and one never inserted
            # by the end is an event and exit 3) has nothing to score; the run's other formations still are
            continue
        lead, fol = series[lead_id], series[fol_id]
        common, il, jf = np.intersect1d(lead["t"], fol["t"], return_indices=True)
        gap = fol["gap"][jf]
        keep = np.isfinite(gap)
        lead_veh = service_vehicle[f["leader"]["service"]]
        fol_veh = service_vehicle[f["follower"]["service"]]
        unit = TrainParamsA(
            length_m=float(fol_veh["length_m"]),
            safety_margin_m=_safety_margin_of(raw, f["follower"]["service"]),
            service_decel_mps2=float(fol_veh["service_decel_mps2"]),
            emergency_decel_mps2=float(fol_veh["emergency_decel_mps2"]),
        )
        lead_len, lead_em = float(lead_veh["length_m"]), float(lead_veh["emergency_decel_mps2"])
        v_lead, v_fol = lead["v"][il][keep], fol["v"][jf][keep]
        spacing = gap[keep] + lead_len
        result.append(
            FollowerSeries(
                follower=fol_id,
                leader=lead_id,
                controller=_controller_of(raw, f["follower"]["service"]),
                t_s=common[keep] - float(fol["t"][0]),
                v_lead_mps=v_lead,
                v_fol_mps=v_fol,
                spacing_m=spacing,
                desired_m=desired_spacing_m(v_fol, v_lead, unit, lead_len, lead_em),
                safe_m=safe_spacing_m(v_fol, v_lead, unit, lead_len, lead_em),
                solve_time_s=fol["solve"][jf][keep] if has_solve else None,
                objective=fol["objective"][jf][keep],
                unit=unit,
                lead_length_m=lead_len,
                lead_emergency_mps2=lead_em,
            )
        )
    return raw, result, fallbacks, summary, has_solve


def score_series(fs: FollowerSeries, criterion: VcCriterion = VcCriterion(), fallbacks: int = 0) -> FollowerRow:
    """:func:`follower_row` of one formation's aligned samples (from a run folder or any other source)."""
    return follower_row(
        fs.t_s,
        fs.v_lead_mps,
        fs.v_fol_mps,
        fs.spacing_m,
        fs.unit,
        fs.lead_length_m,
        fs.lead_emergency_mps2,
        criterion,
        follower=fs.follower,
        leader=fs.leader,
        controller=fs.controller,
        solve_time_s=fs.solve_time_s,
        fallbacks=fallbacks,
    )


def follower_series(out_dir: Path | str) -> list[FollowerSeries]:
    """The aligned per-formation samples of a run's output folder (what the metrics and the figures use)."""
    return _load_run(Path(out_dir))[1]


def paper000_metrics(out_dir: Path | str, criterion: VcCriterion | None = None) -> dict[str, Any]:
    """Metrics of a Paper A run's output folder.

    Returns ``{"scenario", "followers": [FollowerRow as dict, ...], "wall_per_train_step_s", "collisions",
    "solve_times_recorded"}``, followers in formation order. ``criterion`` defaults to :class:`VcCriterion`
    (late phase [300, 500) s; a run with no sample in that window reports NaN late means).
    """
    crit = criterion or VcCriterion()
    raw, series, fallbacks, summary, has_solve = _load_run(Path(out_dir))
    rows = [asdict(score_series(fs, crit, fallbacks.get(fs.follower, 0))) for fs in series]
    steps = float(summary.get("steps") or 0)
    wall = float(summary.get("wall_s") or math.nan)
    return {
        "scenario": raw.get("name", ""),
        "followers": rows,
        "wall_per_train_step_s": wall / (steps * len(series)) if steps and series else math.nan,
        "collisions": summary.get("collisions"),
        "solve_times_recorded": has_solve,
    }


def format_table(metrics: Mapping[str, Any] | Mapping[str, Mapping[str, Any]]) -> str:
    """Plain-text Table III/IV: one line per (run, follower). Accepts one :func:`paper000_metrics` result or a
    mapping ``label -> result`` (e.g. the three S-D methods)."""
    runs: dict[str, Any] = {str(metrics.get("scenario", "run")): metrics} if "followers" in metrics else dict(metrics)
    head = (
        f"{'run':<16}{'train':>8}{'ctl':>14}{'|dv|':>9}{'|e|':>9}{'late|dv|':>10}{'late|e|':>9}"
        f"{'VC1st':>7}{'VC30':>7}{'minSafe':>9}{'e_end':>8}{'t_ms':>9}{'p95_ms':>9}{'wall_ms':>9}{'fb':>4}"
    )
    lines = [head]

    def num(x: float, spec: str, width: int) -> str:
        return f"{'-':>{width}}" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:>{width}{spec}}"

    for label, m in runs.items():
        for r in m["followers"]:
            lines.append(
                f"{label[:16]:<16}{r['follower']:>8}{r['controller'][:13]:>14}{num(r['mean_abs_dv_mps'], '.4f', 9)}"
                f"{num(r['mean_abs_spacing_error_m'], '.2f', 9)}{num(r['late_mean_abs_dv_mps'], '.4f', 10)}"
                f"{num(r['late_mean_abs_spacing_error_m'], '.2f', 9)}{num(r['vc_first_s'], '.0f', 7)}"
                f"{num(r['vc_sustained_s'], '.0f', 7)}{num(r['min_safety_margin_m'], '.1f', 9)}"
                f"{num(r['final_spacing_error_m'], '.2f', 8)}{num(r['solve_time_mean_s'] * 1e3, '.2f', 9)}"
                f"{num(r['solve_time_p95_s'] * 1e3, '.2f', 9)}{num(m['wall_per_train_step_s'] * 1e3, '.1f', 9)}"
                f"{r['fallbacks']:>4}"
            )
    return "\n".join(lines)
