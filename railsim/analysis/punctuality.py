"""Punctuality KPIs of a disturbed run, from ``delays.csv`` (:mod:`railsim.engine.primary_delays`).

The measures the industry uses, on the run's stop arrivals (every station after the origin, missed stops
left out) and, for the delay minutes, on each trip's arrival at its destination:

* **punctuality** — the share of arrivals no more than 1, 3 and 5 min late (``within_1min`` …), over all
  stations and per station along the line (``by_station``: the share within 3 min, in line order), and the
  delay CDF on :data:`CDF_GRID_S` (``cdf.le_0060s``: the share at most 60 s late);
* **mean and p95 arrival delay** [s] (early arrivals count as 0 late);
* **delay minutes at the destination**, split into **primary** (what the train's own injected disturbances
  alone cost it: its free run with them) and **secondary** (the rest: knock-on from other trains — waiting
  for authority, a held departure, a late incoming unit). Secondary below zero (a train that made up time
  against its own free run, possible only by a step's rounding) counts as 0;
* **propagation factor** = secondary ÷ primary minutes (None when nothing was injected). Secondary delay
  includes what the timetable costs without any disturbance (a plan tighter than the line can run), so compare
  a disturbed run with the same run at intensity 0 to see knock-on alone (``railsim robustness`` does);
* **recovery time** after each incident: from the incident's planned time to the last arrival, before the next
  incident, with more than :data:`RECOVERED_S` of secondary delay (0 when there is none).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from railsim.record import run_folder

PUNCTUALITY_MIN = (1, 3, 5)  # thresholds of the punctuality shares [min]
CDF_GRID_S = (0, 30, 60, 90, 120, 180, 240, 300, 420, 600, 900, 1200, 1800)  # the delay CDF's points [s]
RECOVERED_S = 60.0  # an arrival with at most this much secondary delay counts as recovered


def load(run_dir: Path) -> pd.DataFrame | None:
    """``delays.csv`` of a run, or None if the run had no ``disturbances:`` section.

    Only the run's own file counts: one its manifest does not list (an earlier run's) is not read
    (:func:`railsim.record.run_folder.member`).
    """
    path = run_folder.member(run_dir, "delays.csv")
    return pd.read_csv(path) if path is not None else None


def kpis(delays: pd.DataFrame, incidents: Sequence[Mapping[str, Any]] = ()) -> dict[str, Any]:
    """The KPIs of one run (module docstring) from its ``delays.csv`` rows."""
    arrived = delays[delays["arrival_delay_s"].notna() & ~delays["missed"].astype(bool)]
    late = np.maximum(arrived["arrival_delay_s"].to_numpy(dtype=float), 0.0)
    out: dict[str, Any] = {"n_arrivals": len(late)}
    for m in PUNCTUALITY_MIN:
        out[f"within_{m}min"] = float(np.mean(late <= 60.0 * m)) if len(late) else None
    out["mean_delay_s"] = float(np.mean(late)) if len(late) else None
    out["p95_delay_s"] = float(np.percentile(late, 95)) if len(late) else None
    last = destination_rows(arrived)
    primary_min = float(np.sum(np.maximum(last["primary_s"].to_numpy(dtype=float), 0.0))) / 60.0
    secondary_min = float(np.sum(np.maximum(last["secondary_s"].to_numpy(dtype=float), 0.0))) / 60.0
    out["primary_min"] = primary_min
    out["secondary_min"] = secondary_min
    out["propagation_factor"] = secondary_min / primary_min if primary_min > 0.0 else None
    out["mean_secondary_s"] = (
        float(np.mean(np.maximum(arrived["secondary_s"].to_numpy(float), 0.0))) if len(late) else None
    )
    out["cdf"] = {f"le_{t:04d}s": float(np.mean(late <= t)) if len(late) else None for t in CDF_GRID_S}
    groups = dict(list(arrived.groupby("station", sort=False)))
    order = line_order(arrived)
    out["by_station"] = {
        st: float(np.mean(np.maximum(groups[st]["arrival_delay_s"].to_numpy(float), 0.0) <= 180.0)) for st in order
    }
    out["station_order"] = ",".join(order)  # JSON files sort their keys: the line order, kept as one scalar
    rec = recovery_times(arrived, [float(i["planned_s"]) for i in incidents])
    out["recovery_s"] = rec
    out["recovery_max_s"] = max(rec) if rec else None
    out["recovery_mean_s"] = float(np.mean(rec)) if rec else None
    return out


def line_order(arrived: pd.DataFrame) -> list[str]:
    """Stations in the order the trip serving most of them reaches them, then any others (first seen first)."""
    if arrived.empty:
        return []
    longest = arrived.groupby("trip_id", sort=False).size().idxmax()
    order = [str(s) for s in arrived[arrived["trip_id"] == longest].sort_values("arrival_s")["station"]]
    return order + [str(s) for s in dict.fromkeys(arrived["station"]) if str(s) not in order]


def destination_rows(arrived: pd.DataFrame) -> pd.DataFrame:
    """Each trip's last recorded arrival (its destination when it arrived)."""
    return arrived.sort_values(["trip_id", "arrival_s"]).groupby("trip_id", sort=False).tail(1)


def recovery_times(arrived: pd.DataFrame, incident_s: Sequence[float]) -> list[float]:
    """Per incident (sorted by time): seconds until the last arrival with secondary delay > :data:`RECOVERED_S`
    before the next incident (module docstring)."""
    times = sorted(incident_s)
    arr = arrived["arrival_s"].to_numpy(float)
    sec = arrived["secondary_s"].to_numpy(float)
    out = []
    for k, t0 in enumerate(times):
        t1 = times[k + 1] if k + 1 < len(times) else math.inf
        bad = arr[(arr >= t0) & (arr < t1) & (sec > RECOVERED_S)]
        out.append(float(bad.max() - t0) if len(bad) else 0.0)
    return out


def run_kpis(run_dir: Path, summary: Mapping[str, Any]) -> dict[str, Any] | None:
    """The ``robustness`` block of a finished run's ``summary.json`` (None without ``delays.csv``)."""
    delays = load(run_dir)
    if delays is None:
        return None
    incidents = (summary.get("disturbances") or {}).get("incidents") or []
    return kpis(delays, incidents)
