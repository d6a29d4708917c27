"""Collision-avoidance and coupling metrics of one engine run (Paper D, spec 003 §3.2–3.3, §3.8, §3.10).

Paper D judges each scenario by: does any pair collide, how close do consecutive vehicles come and when, when the
collision-avoidance (CA) trigger fires and releases, how long emergency braking lasts, how long coupling takes,
and where the formation ends (final gaps and speed differences). This module reads those numbers back from an
output folder — it never reruns anything:

* ``trace.csv`` at stride = step (the folder's ``scenario.resolved.yaml`` says which stride; a coarser stride is
  accepted but the minimum gap is then only sampled);
* ``events.csv`` (``ca_trigger``/``ca_release``, ``emergency_brake_on/off``, ``coupled``, ``collision``,
  ``obstacle_appeared/cleared``);
* ``formations.csv`` (time to couple) and ``summary.json`` (the engine's collision count).

Readings:

* **Pairs** are consecutive trains ordered by chainage at their first common sample (all the paper's vehicles run
  one route); the gap is the net front-to-rear gap ``x_ahead − L_ahead − x_follower`` from the trace chainages.
  An obstacle (events) makes a pair ``obstacle-<train>`` while it is on the line.
* **Safety distance.** The trigger the follower's CA role uses is recomputed at every sample from the resolved
  scenario (the ``ca`` role's ``threshold_mode`` etc., the follower's own emergency deceleration, both speeds),
  with :func:`controllers.monorail.braking_modes.required_gap_m` — the same function the controller calls. A
  sample with the gap below it is *guarded* if the follower's CA was triggered at most one step later (the
  controller sees the gap of the step it acts on); ``unguarded_s`` counts the rest. With a debounced trigger
  (``trigger_band_m`` > 0, :func:`controllers.monorail.states.ca_should_fire`) a shallow intrusion may last the
  dwell without CA by design, so ``unguarded_s`` counts only samples deeper than the band below the trigger
  (``below_trigger_s`` still counts every sample below it). Trains without a ``ca`` role get no safety-distance
  figures (None).
* **Final speed difference** is follower minus the one ahead (> 0: still closing).
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Mapping
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from controllers.monorail.braking_modes import required_gap_m
from controllers.monorail.collision_avoidance import CaParams


def _read_csv(path: Path) -> list[dict[str, str]]:
    if not path.exists():
        return []
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def _intervals(starts: list[float], ends: list[float]) -> list[tuple[float, float | None]]:
    """Pair on/off times in order; an interval still open at the end has ``None`` as its end."""
    out: list[tuple[float, float | None]] = []
    ends = sorted(ends)
    for t0 in sorted(starts):
        t1 = next((e for e in ends if e >= t0), None)
        if t1 is not None:
            ends.remove(t1)
        out.append((t0, t1))
    return out


def _ca_params(raw: Mapping[str, Any], service_id: str) -> CaParams | None:
    """The CaParams of the service's ``ca`` role (service override first), or None without a monorail_ca role."""
    svc: Mapping[str, Any] = next((s for s in raw.get("services", []) if s.get("id") == service_id), {})
    name = (svc.get("roles") or {}).get("ca") or (raw.get("roles") or {}).get("ca")
    if not name:
        return None
    ctl = (raw.get("controllers") or {}).get(name) or {}
    if ctl.get("type") != "monorail_ca":
        return None
    known = {f.name for f in fields(CaParams)}
    return CaParams(**{k: v for k, v in (ctl.get("params") or {}).items() if k in known})


def _vehicle_of(raw: Mapping[str, Any], service_id: str) -> Mapping[str, Any]:
    svc: Mapping[str, Any] = next((s for s in raw.get("services", []) if s.get("id") == service_id), {})
    return (raw.get("vehicles") or {}).get(svc.get("vehicle"), {})


def metrics(out_dir: Path | str) -> dict[str, Any]:
    """All CA/coupling metrics of the run in ``out_dir`` (see the module docstring)."""
    out = Path(out_dir)
    raw = yaml.safe_load((out / "scenario.resolved.yaml").read_text(encoding="utf-8"))
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8")) if (out / "summary.json").exists() else {}
    step_s = float(raw["simulation"]["step_s"])
    rows = _read_csv(out / "trace.csv")
    events = _read_csv(out / "events.csv")
    trains: dict[str, dict[str, Any]] = {}
    for r in rows:
        d = trains.setdefault(r["train"], {"service": r["service"], "t": [], "x": [], "v": [], "a": []})
        d["t"].append(float(r["t_s"]))
        d["x"].append(float(r["chainage_m"]))
        d["v"].append(float(r["speed_mps"]))
        d["a"].append(float(r["applied_accel_mps2"]))
    times = np.unique(np.array([float(r["t_s"]) for r in rows])) if rows else np.zeros(0)
    series: dict[str, dict[str, Any]] = {}
    for tid, d in trains.items():
        t = np.asarray(d["t"])
        idx = np.searchsorted(times, t)
        grid = {k: np.full(len(times), np.nan) for k in ("x", "v", "a")}
        for k in grid:
            grid[k][idx] = d[k]
        veh = _vehicle_of(raw, d["service"])
        series[tid] = {
            **grid,
            "length_m": float(veh.get("length_m", 0.0)),
            "b_e": float(veh.get("emergency_decel_mps2", math.inf)),
            "service": d["service"],
        }

    def on_off(on_kind: str, off_kind: str, tid: str) -> list[tuple[float, float | None]]:
        on = [float(e["t_s"]) for e in events if e["kind"] == on_kind and e["subject"] == tid]
        off = [float(e["t_s"]) for e in events if e["kind"] == off_kind and e["subject"] == tid]
        return _intervals(on, off)

    ca = {tid: on_off("ca_trigger", "ca_release", tid) for tid in series}
    emergency = {tid: on_off("emergency_brake_on", "emergency_brake_off", tid) for tid in series}

    order = sorted(
        series,
        key=lambda tid: -float(series[tid]["x"][np.nanargmin(np.where(np.isnan(series[tid]["x"]), np.inf, times))]),
    )
    pairs: dict[str, dict[str, Any]] = {}
    for ahead, fol in zip(order, order[1:]):
        a, f = series[ahead], series[fol]
        gap = a["x"] - a["length_m"] - f["x"]
        pairs[f"{ahead}-{fol}"] = _pair_row(
            times, gap, f["v"], a["v"], _ca_params(raw, f["service"]), f["b_e"], ca[fol], step_s
        )
    for _k, ev in enumerate(e for e in events if e["kind"] == "obstacle_appeared"):
        detail = json.loads(ev["detail"] or "{}")
        tid, ch = detail.get("ahead_of"), detail.get("chainage_m")
        if tid not in series or ch is None:
            continue
        t0 = float(ev["t_s"])
        cleared = [float(e["t_s"]) for e in events if e["kind"] == "obstacle_cleared" and e["subject"] == ev["subject"]]
        t1 = min((c for c in cleared if c >= t0), default=math.inf)
        on = (times >= t0) & (times < t1)
        gap = np.where(on, float(ch) - series[tid]["x"], np.nan)
        pairs[f"{ev['subject']}-{tid}"] = _pair_row(
            times,
            gap,
            series[tid]["v"],
            np.zeros(len(times)),
            _ca_params(raw, series[tid]["service"]),
            series[tid]["b_e"],
            ca[tid],
            step_s,
        )
    couple: dict[str, float | None] = {}
    couple_by_follower: dict[str, float | None] = {}
    for r in _read_csv(out / "formations.csv"):
        couple[r["formation"]] = float(r["time_to_couple_s"]) if r.get("time_to_couple_s") else None
        couple_by_follower[r["follower"]] = couple[r["formation"]]
    truth_collisions = [e for e in events if e["kind"] == "collision"]
    n_coll = int(summary.get("collisions", len(truth_collisions)))
    return {
        "scenario": raw.get("name", out.name),
        "step_s": step_s,
        "collisions": n_coll,
        "collision": n_coll > 0 or any(p["collision"] for p in pairs.values()),
        "pairs": pairs,
        "ca_intervals": {k: v for k, v in ca.items() if v},
        "emergency_intervals": {k: v for k, v in emergency.items() if v},
        "time_to_couple_s": couple,
        "coupled": {k: v is not None for k, v in couple.items()},
        "time_to_couple_by_follower_s": couple_by_follower,
        "final_speeds_mps": {
            tid: float(s["v"][~np.isnan(s["v"])][-1]) for tid, s in series.items() if (~np.isnan(s["v"])).any()
        },
    }


def _pair_row(
    times: np.ndarray,
    gap: np.ndarray,
    v_fol: np.ndarray,
    v_ahead: np.ndarray,
    params: CaParams | None,
    b_e: float,
    ca: list[tuple[float, float | None]],
    step_s: float,
) -> dict[str, Any]:
    ok = ~np.isnan(gap)
    if not ok.any():
        return {
            "min_gap_m": None,
            "min_gap_t_s": None,
            "collision": False,
            "final_gap_m": None,
            "final_speed_diff_mps": None,
            "safety_distance": None,
            "below_trigger_s": None,
            "unguarded_s": None,
        }
    g = np.where(ok, gap, np.inf)
    k = int(np.argmin(g))
    last = int(np.nonzero(ok)[0][-1])
    row: dict[str, Any] = {
        "min_gap_m": float(g[k]),
        "min_gap_t_s": float(times[k]),
        "collision": bool(g[k] <= 0.0),
        "final_gap_m": float(gap[last]),
        "final_speed_diff_mps": float(v_fol[last] - v_ahead[last]),
        "safety_distance": None,
        "below_trigger_s": None,
        "unguarded_s": None,
    }
    if params is None:
        return row
    policy = params.policy()
    below = np.zeros(len(times), bool)
    deep = np.zeros(len(times), bool)
    for j in np.nonzero(ok)[0]:
        vf, va = max(float(v_fol[j]), 0.0), max(float(v_ahead[j]), 0.0)
        if math.isnan(vf) or math.isnan(va):
            continue
        trigger = required_gap_m(policy, vf, va, b_e)
        below[j] = gap[j] < trigger
        deep[j] = gap[j] < trigger - params.trigger_band_m
    guarded = np.zeros(len(times), bool)
    for t0, t1 in ca:
        guarded |= (times >= t0 - step_s - 1e-9) & (times <= (math.inf if t1 is None else t1) + 1e-9)
    stride = float(np.median(np.diff(times))) if len(times) > 1 else step_s
    row.update(
        safety_distance=policy.mode if policy.mode != "fixed" else f"fixed {policy.fixed_threshold_m:g} m",
        below_trigger_s=float(below.sum() * stride),
        unguarded_s=float((deep & ~guarded).sum() * stride),
    )
    return row


def _fmt(x: Any, spec: str = ".1f") -> str:
    if x is None:
        return "-"
    if isinstance(x, float):
        return format(x, spec)
    return str(x)


def format_table(results: Mapping[str, Any] | Mapping[str, Mapping[str, Any]]) -> str:
    """A plain-text table, one row per pair; ``results`` is one :func:`metrics` dict or ``{label: metrics}``."""
    if "pairs" in results:
        results = {str(results.get("scenario", "run")): results}
    head = (
        f"{'run':<28} {'pair':<22} {'min gap':>8} {'at':>6} {'final':>7} {'dv_end':>7} {'<trig':>6} "
        f"{'unguard':>7} {'CA trigger->release':<22} {'EB s':>5} {'couple':>7} coll"
    )
    lines = [head, "-" * len(head)]
    for label, m in results.items():
        for pair, p in m["pairs"].items():
            fol = pair.split("-", 1)[1]
            ca = m["ca_intervals"].get(fol, [])
            ca_txt = ", ".join(f"{a:.1f}->{_fmt(b)}" for a, b in ca) or "-"
            eb = sum((b if b is not None else math.nan) - a for a, b in m["emergency_intervals"].get(fol, []))
            form = m.get("time_to_couple_by_follower_s", {}).get(fol)
            lines.append(
                f"{label:<28} {pair:<22} {_fmt(p['min_gap_m'], '.2f'):>8} {_fmt(p['min_gap_t_s']):>6} "
                f"{_fmt(p['final_gap_m'], '.2f'):>7} {_fmt(p['final_speed_diff_mps'], '.2f'):>7} "
                f"{_fmt(p['below_trigger_s']):>6} {_fmt(p['unguarded_s']):>7} {ca_txt:<22} "
                f"{eb:>5.1f} {_fmt(form):>7} {'YES' if p['collision'] else 'no'}"
            )
    return "\n".join(lines)


__all__ = ["format_table", "metrics"]
