"""Paper A's comparison tables (spec 000 S-D Table III, S-E Table IV) over seeds, from the engine and from its
numpy twin under the same settings.

Two ways to run one scenario file of ``scenarios/paper000_*.yaml``:

* **engine** — ``railsim run`` in a child process (SUMO, the engine's control stage, t2t messages, recorder);
* **numpy twin** (:func:`numpy_twin`) — :func:`controllers.mcf_dmpc.sim.run_platoon` built from the *same*
  validated scenario: the leader's ``speed_profile`` with its parameters (so its plan is broadcast or not exactly
  as in the engine), each follower's coupled controller with its parameters, the start offsets and speeds, the
  actuator noise, the vehicle preset, the engine's message convention (``messages="engine"``: the report at
  ``t_k`` with the plan decided at ``t_{k−1}``) and its clock (first control step at ``t = step_s``, samples at
  paper time ``0 … duration − step``).

Both are scored by the same function, :func:`railsim.analysis.paper000.follower_row` (mean |Δv| and mean
|ΔS − D^(e)| over the whole run and the late phase: S-D [300, 500) s (A7), S-E [228, 380) s, the last 40 % of
its cycle, besides Table IV's whole cycle). What differs between the two columns is only what the engine adds
(SUMO's positions, the ATO role under min(), the recorder) and the noise stream (same σ, different generator), so
their means over seeds agree; ``tests/sumo/test_paper000_agreement.py`` pins this within 10 %.

:func:`paper000_tables` runs every (setting, method, seed) case, engine runs two at a time, and returns the rows;
:func:`markdown` formats them as mean ± sd over seeds (``railsim reproduce paper000``).
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from railsim.analysis.paper000 import FollowerSeries, VcCriterion, follower_series, score_series

__all__ = [
    "LATE_S",
    "METHODS",
    "SETTINGS",
    "Case",
    "label",
    "markdown",
    "numpy_twin",
    "paper000_tables",
    "reproduce_paper000",
    "run_case",
    "scenario_path",
]

ROOT = Path(__file__).resolve().parents[2]
METHODS = ("dmpc", "mcf_dmpc", "opo_mcf_dmpc")
SETTINGS = {"S-D": "paper000_sd_comparison_{method}.yaml", "S-E": "paper000_se_variable_speed_{method}.yaml"}
LATE_S = {"S-D": (300.0, 500.0), "S-E": (228.0, 380.0)}
METRICS = ("mean_abs_dv_mps", "mean_abs_spacing_error_m", "late_mean_abs_dv_mps", "late_mean_abs_spacing_error_m")


def scenario_path(setting: str, method: str) -> Path:
    return ROOT / "scenarios" / SETTINGS[setting].format(method=method)


def _chain(scenario: Any) -> list[Any]:
    """The services from the platoon's leader to its tail (formations chain leader → follower)."""
    follower_of = {f.leader.service: f.follower.service for f in scenario.formations}
    followers = set(follower_of.values())
    heads = [s for s in follower_of if s not in followers]
    if len(heads) != 1:
        raise ValueError(f"{scenario.source}: formations must form one chain, got heads {heads}")
    order = [heads[0]]
    while order[-1] in follower_of:
        order.append(follower_of[order[-1]])
    by_id = {s.id: s for s in scenario.services}
    return [by_id[s] for s in order]


def numpy_twin(scenario: Any, seed: int | None = None) -> list[FollowerSeries]:
    """Run ``scenario`` (a validated :class:`railsim.scenario.Scenario` of a Paper A platoon) in the numpy runner;
    the aligned samples per formation, as :func:`railsim.analysis.paper000.follower_series` gives for the engine."""
    import controllers as ctl
    from controllers.mcf_dmpc.sim import run_platoon
    from controllers.mcf_dmpc.spacing import TABLE_I, TrainParamsA, desired_spacing_m, safe_spacing_m

    chain = _chain(scenario)
    lead_svc, fol_svcs = chain[0], chain[1:]
    vehicle = scenario.vehicles[lead_svc.vehicle]
    lead_spec = scenario.controllers[lead_svc.roles["ato"]]
    fol_specs = [scenario.controllers[s.roles["coupled"]] for s in fol_svcs]
    leader = ctl.create(lead_spec.type, dict(lead_spec.params), vehicle)
    followers = [ctl.create(spec.type, dict(spec.params), vehicle) for spec in fol_specs]
    noise = scenario.faults.actuator_noise
    sd = float(noise.accel_sd_mps2) if noise is not None else 0.0
    if sd > 0.0 and set(noise.trains or ()) != {s.trip_ids[0] for s in fol_svcs}:
        raise ValueError(f"{scenario.source}: the numpy runner puts the noise on every follower and only there")
    dt = float(scenario.simulation.step_s)
    run = run_platoon(
        followers,
        [float(s.start_offset_m) for s in chain],
        [float(s.start_speed_mps) for s in chain],
        int(round(scenario.simulation.duration_s / dt)) - 1,
        leader=leader,
        vehicle=vehicle,
        noise_sd_mps2=sd,
        seed=int(scenario.simulation.seed if seed is None else seed),
        messages="engine",
        dt_s=dt,
        t0_s=dt,
    )
    out = []
    for i, (svc, spec) in enumerate(zip(fol_svcs, fol_specs), start=1):
        unit = TrainParamsA(
            length_m=vehicle.length_m,
            safety_margin_m=float(spec.params.get("safety_margin_m", TABLE_I.safety_margin_m)),
            service_decel_mps2=vehicle.service_decel_mps2,
            emergency_decel_mps2=vehicle.emergency_decel_mps2,
        )
        v_lead, v_fol = run.v[:, i - 1], run.v[:, i]
        spacing = run.x[:, i - 1] - run.x[:, i]
        lead_len, lead_em = vehicle.length_m, vehicle.emergency_decel_mps2
        out.append(
            FollowerSeries(
                follower=svc.trip_ids[0],
                leader=chain[i - 1].trip_ids[0],
                controller=spec.type,
                t_s=run.t,
                v_lead_mps=v_lead,
                v_fol_mps=v_fol,
                spacing_m=spacing,
                desired_m=desired_spacing_m(v_fol, v_lead, unit, lead_len, lead_em),
                safe_m=safe_spacing_m(v_fol, v_lead, unit, lead_len, lead_em),
                solve_time_s=np.append(run.solve_time_s[:, i], np.nan),
                unit=unit,
                lead_length_m=lead_len,
                lead_emergency_mps2=lead_em,
                objective=np.append(run.J[:, i], np.nan),
            )
        )
    return out


@dataclass(frozen=True)
class Case:
    """One run: a setting (S-D/S-E), a method, a seed, and the source (engine or numpy twin)."""

    setting: str
    method: str
    seed: int
    source: str  # "engine" | "numpy"
    overrides: tuple[tuple[str, Any], ...] = ()  # (controller params applied to every follower controller)


def _scenario_text(case: Case) -> str:
    raw = yaml.safe_load(scenario_path(case.setting, case.method).read_text(encoding="utf-8"))
    raw["simulation"]["seed"] = case.seed
    for spec in raw["controllers"].values():
        if spec.get("type") == case.method and case.overrides:
            spec.setdefault("params", {}).update(dict(case.overrides))
    return yaml.safe_dump(raw, sort_keys=False)


def _rows(case: Case, series: Iterable[FollowerSeries], extra: dict[str, Any]) -> list[dict[str, Any]]:
    lo, hi = LATE_S[case.setting]
    crit = VcCriterion(late_start_s=lo, late_end_s=hi)
    return [{**asdict(case), **asdict(score_series(fs, crit)), **extra} for fs in series]


def run_case(case: Case, work_dir: Path | None = None) -> list[dict[str, Any]]:
    """Run one case and score it: one row per follower (the :class:`FollowerRow` fields plus the case's)."""
    from railsim.scenario import loads

    text = _scenario_text(case)
    with tempfile.TemporaryDirectory(dir=work_dir) as tmp:
        path = Path(tmp) / f"{case.setting}_{case.method}_{case.seed}.yaml"
        path.write_text(text, encoding="utf-8")
        if case.source == "numpy":
            return _rows(case, numpy_twin(loads(text, str(path), ROOT / "scenarios")), {})
        out = Path(tmp) / "out"
        cmd = [sys.executable, "-m", "railsim.cli.main", "run", str(path), "--out", str(out), "--no-progress"]
        res = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, env=dict(os.environ))
        if res.returncode != 0:
            raise RuntimeError(f"engine run of {case} failed ({res.returncode}): {res.stderr[-2000:]}")
        summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
        return _rows(case, follower_series(out), {"collisions": summary.get("collisions")})


def paper000_tables(
    seeds: Sequence[int],
    settings: Sequence[str] = tuple(SETTINGS),
    methods: Sequence[str] = METHODS,
    sources: Sequence[str] = ("engine", "numpy"),
    workers: int = 2,
    variants: dict[str, dict[str, Any]] | None = None,
    progress: Callable[[Case], None] | None = None,
) -> list[dict[str, Any]]:
    """Every (setting, method, seed, source) case, plus every ``variants`` entry (``method: overrides`` of its
    follower controllers' parameters); rows as :func:`run_case` gives them, in case order."""
    runs = [(m, ()) for m in methods] + [(m, tuple(sorted(ov.items()))) for m, ov in (variants or {}).items()]
    cases = [Case(s, m, seed, src, ov) for s in settings for m, ov in runs for seed in seeds for src in sources]
    rows: list[dict[str, Any]] = []
    with ProcessPoolExecutor(max(1, workers)) as pool:
        for case, result in zip(cases, pool.map(run_case, cases)):
            if progress is not None:
                progress(case)
            rows.extend(result)
    return rows


def _mean_sd(values: list[float]) -> str:
    arr = np.array([v for v in values if v is not None and math.isfinite(v)], dtype=float)
    if arr.size == 0:
        return "–"
    sd = float(arr.std(ddof=1)) if arr.size > 1 else 0.0
    digits = 3 if abs(arr.mean()) < 1.0 else 2
    return f"{arr.mean():.{digits}f} ± {sd:.{digits}f}"


def label(row: dict[str, Any]) -> str:
    """A method with its parameter overrides, e.g. ``opo_mcf_dmpc (opo_bias=False)``."""
    over = ", ".join(f"{k}={v}" for k, v in row.get("overrides") or ())
    return f"{row['method']} ({over})" if over else str(row["method"])


def markdown(rows: list[dict[str, Any]]) -> str:
    """Mean ± sd over seeds per (setting, method, train), engine and numpy side by side, with their ratio."""

    def order(key: tuple[str, str, str]) -> tuple[str, int, str, str]:
        base = key[1].split(" ")[0]
        return (key[0], METHODS.index(base) if base in METHODS else len(METHODS), key[1], key[2])

    keys = sorted({(r["setting"], label(r), r["follower"]) for r in rows}, key=order)
    heads = ("|Δv| [m/s]", "|ΔS−D^e| [m]", "late |Δv| [m/s]", "late |ΔS−D^e| [m]")
    lines = [
        "| setting | method | train | seeds | source | " + " | ".join(heads) + " |",
        "|---|---|---|---|---|" + "---|" * len(heads),
    ]
    for setting, method, follower in keys:
        mine = [r for r in rows if (r["setting"], label(r), r["follower"]) == (setting, method, follower)]
        means = {}
        for source in ("engine", "numpy"):
            sel = [r for r in mine if r["source"] == source]
            if not sel:
                continue
            cells = [_mean_sd([r[m] for r in sel]) for m in METRICS]
            means[source] = [float(np.mean([r[m] for r in sel])) for m in METRICS]
            lines.append(f"| {setting} | {method} | {follower} | {len(sel)} | {source} | " + " | ".join(cells) + " |")
        if len(means) == 2:
            ratio = [e / n if n else math.nan for e, n in zip(means["engine"], means["numpy"])]
            joined = " | ".join(f"{x:.3f}" for x in ratio)
            lines.append(f"| {setting} | {method} | {follower} | | engine/numpy | {joined} |")
    return "\n".join(lines)


def reproduce_paper000(
    out: Path,
    seeds: Sequence[int],
    settings: Sequence[str] = tuple(SETTINGS),
    methods: Sequence[str] = METHODS,
    workers: int = 2,
    paper_opo: bool = True,
) -> dict[str, Any]:
    """``railsim reproduce paper000``: the tables over ``seeds``, engine and numpy twin; writes ``tables.md`` and
    ``rows.json`` (one row per run and follower) into ``out``. ``paper_opo`` adds OPO-MCF-DMPC in the paper's
    reading (θ1 … θ7 only, ``opo_bias: false``) next to ours."""
    out.mkdir(parents=True, exist_ok=True)
    variants = {"opo_mcf_dmpc": {"opo_bias": False}} if paper_opo and "opo_mcf_dmpc" in methods else None

    def note(case: Case) -> None:
        print(f"  done: {case.setting} {case.method} seed {case.seed} {case.source}", file=sys.stderr, flush=True)

    rows = paper000_tables(seeds, settings, methods, workers=workers, variants=variants, progress=note)
    table = markdown(rows)
    (out / "tables.md").write_text(table + "\n", encoding="utf-8")
    clean = [{k: (list(v) if isinstance(v, tuple) else v) for k, v in r.items()} for r in rows]
    (out / "rows.json").write_text(json.dumps(clean, indent=1, default=str) + "\n", encoding="utf-8")
    return {"table": table, "rows": len(rows)}
