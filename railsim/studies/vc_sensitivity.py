"""How the VC gain of ``railsim study vc-vs-mb`` moves with its conditions: a small sensitivity sweep.

VC capacity claims in the literature range from +5 % to +50 %, depending on exactly the conditions a study fixes.
This module re-runs the headway search of regimes (a) and (b) with one condition changed at a time:

* **target gap** of the formations (``formations[i].target_gap_m``; (b) only — (a) has no formation),
* **t2t comm delay** (mean of ``faults.comm.t2t.delay_s``; (b) only — moving block uses the ground channel),
* **formation share** (``services[i].departures.after.every`` of the services departing relative to the searched
  ones: one branch unit per ``every`` searched units; both regimes, the offered traffic changes with it).

Each variant is a bisection search (:func:`railsim.studies.headway.find_min_headway`, no second-seed
confirmation, to keep the sweep small) on the study's grid; a variant that does not touch (a) reuses the study's (a)
answer. Probes run ``workers`` at a time or on a Dask cluster (``dask_address``), and are kept as resumable rows
under ``DIR/sensitivity/<variant>/<regime>/search``. The table gives both answers, the gain and (b)'s analytic
cycle floor for each variant.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

TARGET_GAPS_M = (60.0,)
T2T_DELAYS_S = (1.0,)
EVERY = (2,)


@dataclass(frozen=True)
class Variant:
    """One changed condition: overrides for (b) and, when (a) is affected, for (a) (else (a) is reused)."""

    name: str
    vc_overrides: dict[str, Any]
    mb_overrides: dict[str, Any] | None = None

    @property
    def slug(self) -> str:
        return re.sub(r"[^a-z0-9]+", "_", self.name.lower()).strip("_")


@dataclass
class SensitivityRow:
    variant: Variant
    mb_headway_s: float | None
    vc_headway_s: float | None
    vc_cycle_floor_s: float | None
    mb_probes: int = 0
    vc_probes: int = 0

    @property
    def gain(self) -> float | None:
        if not self.mb_headway_s or not self.vc_headway_s:
            return None
        return self.mb_headway_s / self.vc_headway_s - 1.0


@dataclass
class SensitivityResult:
    baseline: SensitivityRow
    rows: list[SensitivityRow] = field(default_factory=list)
    grid: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def to_markdown_lines(self) -> list[str]:
        lo, hi, tol = self.grid
        lines = [
            f"One condition changed at a time; each variant a bisection search on [{lo:g}, {hi:g}] s every {tol:g} s "
            "(no second-seed confirmation); a variant that does not touch (a) reuses its answer.",
            "",
            "| variant | (a) moving block [s] | (b) virtual coupling [s] | VC gain (trains/h) | (b) cycle floor [s] | probes (a)/(b) |",
            "|---|---:|---:|---:|---:|---:|",
        ]
        for r in [self.baseline, *self.rows]:
            gain = "–" if r.gain is None else f"{100 * r.gain:+.0f} %"
            lines.append(
                f"| {r.variant.name} | {_h(r.mb_headway_s)} | {_h(r.vc_headway_s)} | {gain} | "
                f"{_h(r.vc_cycle_floor_s, 1)} | {r.mb_probes}/{r.vc_probes} |"
            )
        return lines

    def to_dict(self) -> dict[str, Any]:
        return {
            "grid": list(self.grid),
            "rows": [
                {
                    "variant": r.variant.name,
                    "vc_overrides": r.variant.vc_overrides,
                    "mb_overrides": r.variant.mb_overrides,
                    "mb_headway_s": r.mb_headway_s,
                    "vc_headway_s": r.vc_headway_s,
                    "gain": r.gain,
                    "vc_cycle_floor_s": r.vc_cycle_floor_s,
                }
                for r in [self.baseline, *self.rows]
            ],
        }


def _h(v: float | None, digits: int = 0) -> str:
    return "none feasible" if v is None else f"{v:.{digits}f}"


def variants(mb_scenario: Path, vc_scenario: Path, searched: Sequence[str]) -> list[Variant]:
    """The variants of the module docstring for these two scenarios (paths found in the files themselves)."""
    from railsim import scenario
    from railsim.scenario.loading import parse_yaml, read_text

    raw = parse_yaml(read_text(vc_scenario, str(vc_scenario)), str(vc_scenario))
    out: list[Variant] = []
    forms = raw.get("formations") or []
    for g in TARGET_GAPS_M:
        out.append(Variant(f"target gap {g:g} m", {f"formations[{i}].target_gap_m": g for i in range(len(forms))}))
    t2t = ((raw.get("faults") or {}).get("comm") or {}).get("t2t") or {}
    delay = t2t.get("delay_s")
    for d in T2T_DELAYS_S:
        if isinstance(delay, dict) and "mean" in delay:
            ov: dict[str, Any] = {"faults.comm.t2t.delay_s.mean": d}
        else:
            ov = {"faults.comm.t2t.delay_s": {"dist": "constant", "value": d}}
        out.append(Variant(f"t2t delay mean {d:g} s", ov))
    mb = scenario.load(mb_scenario)
    vc = scenario.load(vc_scenario)

    def every_paths(scn: Any) -> list[str]:
        ids = [s.id for s in scn.services]
        return [
            f"services[{ids.index(s.id)}].departures.after.every"
            for s in scn.services
            if s.departures_after is not None and s.departures_after.service in searched
        ]

    for n in EVERY:
        vp, mp = every_paths(vc), every_paths(mb)
        if vp and mp:
            out.append(Variant(f"formation share 1 per {n}", {p: n for p in vp}, {p: n for p in mp}))
    return out


def run_sensitivity(
    out_dir: Path,
    results: dict[str, Any],
    headway_paths: Sequence[str],
    *,
    lo_s: float,
    hi_s: float,
    tol_s: float,
    max_delay_s: float,
    workers: int = 1,
    dask_address: str | None = None,
    progress: bool | None = None,
) -> SensitivityResult:
    """The sensitivity block of the study (module docstring); ``results`` are the study's regime results."""
    from railsim import scenario
    from railsim.studies.floor import regime_floor
    from railsim.studies.headway import find_min_headway

    a, b = results["mb"], results["vc"]
    searched = [p for p in headway_paths]
    services = [s.id for s in scenario.load(b.regime.scenario).services]
    searched_ids = [services[int(re.match(r"services\[(\d+)\]", p).group(1))] for p in searched]  # type: ignore[union-attr]

    def search(scn_path: Path, overrides: dict[str, Any], folder: Path) -> tuple[float | None, int, Any]:
        res = find_min_headway(
            scn_path,
            searched,
            lo_s,
            hi_s,
            tol_s=tol_s,
            max_delay_s=max_delay_s,
            overrides=overrides,
            confirm_seeds=[],
            workers=workers,
            dask_address=dask_address,
            out_dir=folder,
            progress=progress,
        )
        return res.min_headway_s, len(res.probes), res

    def floor_of(overrides: dict[str, Any], h: float | None) -> float | None:
        at = h if h is not None else hi_s
        scn = scenario.load(b.regime.scenario, {**overrides, **{p: at for p in searched}})
        f = regime_floor(scn, tuple(searched_ids)).cycle_s
        return None if math.isnan(f) else f

    base = SensitivityRow(
        Variant("baseline (the study)", {}),
        a.headway_s,
        b.headway_s,
        b.floor.cycle_s if b.floor is not None else None,
        len(a.search.probes) if a.search else 0,
        len(b.search.probes) if b.search else 0,
    )
    result = SensitivityResult(base, grid=(lo_s, hi_s, tol_s))
    for v in variants(a.regime.scenario, b.regime.scenario, searched_ids):
        folder = out_dir / v.slug
        vc_h, vc_n, _ = search(b.regime.scenario, v.vc_overrides, folder / "vc" / "search")
        if v.mb_overrides is None:
            mb_h, mb_n = a.headway_s, 0
        else:
            mb_h, mb_n, _ = search(a.regime.scenario, v.mb_overrides, folder / "mb" / "search")
        result.rows.append(SensitivityRow(v, mb_h, vc_h, floor_of(v.vc_overrides, vc_h), mb_n, vc_n))
    return result
