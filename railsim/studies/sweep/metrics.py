"""The metric columns of a sweep row, read from a finished run folder.

A case's row holds every scalar of the run's ``summary.json`` (:func:`summary_metrics`, nested keys joined with
``.``) and four statistics of its ``trips.csv`` (:func:`trip_metrics`: arrival delay against the free-run plan,
traction energy). Both read files only, so they work on any run folder, not just on a sweep's own children.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from railsim.studies.sweep.spec import _is_scalar


def _flatten(prefix: str, value: Any, out: dict[str, Any]) -> None:
    if isinstance(value, Mapping):
        for k, v in value.items():
            _flatten(f"{prefix}.{k}" if prefix else str(k), v, out)
    elif _is_scalar(value):
        out[prefix] = value
    # lists (e.g. printable tables) are not metrics: dropped


def summary_metrics(summary: Mapping[str, Any]) -> dict[str, Any]:
    """The scalar metrics of a run's summary, nested keys joined with ``.``; ``wall_s`` renamed ``engine_wall_s``
    and the run's ``status`` (``completed``/``failed``/``interrupted``) ``run_status``: the row's own ``status``
    says whether the case ran (``ok``/``failed``)."""
    flat: dict[str, Any] = {}
    _flatten("", {k: v for k, v in summary.items() if k != "analysis_tables"}, flat)
    if "wall_s" in flat:
        flat["engine_wall_s"] = flat.pop("wall_s")
    if "status" in flat:
        flat["run_status"] = flat.pop("status")
    flat.pop("interrupted_by", None)  # a case is never interrupted by a signal on its own (the sweep stops it)
    flat.pop("seed", None)  # the row's own seed column
    return flat


def trip_metrics(run_dir: Path) -> dict[str, Any]:
    """Arrival-delay statistics [s] over the arrived trips and total traction energy [kWh] of a finished run."""
    import numpy as np

    path = Path(run_dir) / "trips.csv"
    if path.is_file():
        with open(path, newline="", encoding="utf-8") as fh:
            rows: list[Mapping[str, Any]] = list(csv.DictReader(fh))
    else:
        import pandas as pd

        rows = pd.read_parquet(Path(run_dir) / "trips.parquet").to_dict("records")

    def numbers(key: str) -> list[float]:
        vals = []
        for r in rows:
            x = r.get(key)
            if x is not None and x != "" and math.isfinite(float(x)):
                vals.append(float(x))
        return vals

    delays, energy = numbers("delay_s"), numbers("energy_kwh")
    return {
        "trips.arrival_delay_max_s": max(delays) if delays else None,
        "trips.arrival_delay_p95_s": float(np.percentile(delays, 95)) if delays else None,
        "trips.arrival_delay_mean_s": float(np.mean(delays)) if delays else None,
        "trips.energy_kwh_total": float(sum(energy)) if energy else None,
    }
