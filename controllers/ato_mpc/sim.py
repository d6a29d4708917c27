"""Closed-loop runner for Paper B's scenarios on the multi-point plant (pure numpy; plots with matplotlib Agg).

Scenarios (spec §4; the line data are synthetic because the paper publishes none, see
:mod:`controllers.ato_mpc.reference`):

* **A** — single section of ``length_m`` (default 5 km), ATP 45.8 m/s, piecewise-constant gradient (±12 ‰).
* **B** — three sections with stops at 14687 / 25279 / 33086 m, synthetic ATP restrictions and gradient,
  dwell 30 s (dwell samples are excluded from E_v/E_x, A11).
* **C** — Scenario A with wind ``ŵ = 0.2`` (``wind="constant"``) or ``0.1 + 0.1 cos t`` (``"harmonic"``), as
  an extra resistance in m/s² acting on the plant only (A14; ``wind_known=True`` feeds it to the model).

The plant is :func:`railsim.physics.multipoint.step` (RK4, ≤ 5 ms sub-steps, ZOH forces, holding brake); the control
period ``T`` is 0.1 s (A1). The controllers are the laws of this package behind :class:`AtoDriver`.

Metrics (spec §2.16, A12; the shared definitions are :mod:`controllers.ato_mpc.metrics`), per run and section:

* ``E_u = Σ_i Σ_k u_i(k)²·T`` [N²·s] (reported ×10⁻¹² as ``e_u_1e12``);
* ``E_v``, ``E_x``: mean |v_r − v_1|, |x_r − x_1| over the non-dwell samples, against the **time-indexed**
  expected profile of each section started at the section's actual departure (the paper's metric also in
  "distance" reference mode);
* ``E_p``: |x_stop − x_1| at the first standstill near the stop (the holding brake caught the train within
  50 m of the mark), arithmetic mean over sections;
* ``max_force_rate_n_per_s``, counts of force and force-rate violations (beyond 1e-6 relative), counts of
  speed-limit and coupler-band violations, max |coupler deviation| and max |relative speed|;
* fallbacks and QP solve times.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from controllers.ato_mpc.afsmc import AfsmcLaw, AfsmcParams
from controllers.ato_mpc.core import AtoDriver, CarriageLaw, Situation
from controllers.ato_mpc.metrics import actuator_metrics, tracking_metrics
from controllers.ato_mpc.mpc import make_mpc_law
from controllers.ato_mpc.pid import PidLaw, PidParams
from controllers.ato_mpc.reference import (
    PAPER_ATP_MPS,
    PAPER_STOPS_M,
    Limit,
    PiecewiseConstant,
    SpeedDistanceProfile,
    paper_gradient,
    paper_multi_limits,
    time_profile,
)
from controllers.ato_mpc.sempc import make_sempc_law
from railsim.physics.multipoint import (
    MultipointParams,
    WindDisturbance,
    carriage_gradients_permille,
    initial_state,
    step,
)

CONTROLLERS = ("sempc", "mpc", "mpc_b", "afsmc", "pid")
SINGLE_WEIGHTS = {"q_x1": 0.5, "q_v1": 1e9, "r_du": 1e-5}
MULTI_WEIGHTS = {"q_x1": 0.05, "q_v1": 50.0, "r_du": 1e-8}


@dataclass(frozen=True)
class Scenario:
    name: str
    stops_m: tuple[float, ...]
    gradient: PiecewiseConstant
    limits: tuple[Limit, ...] = ()
    line_speed_mps: float = PAPER_ATP_MPS
    design_speed_mps: float = math.inf
    dwell_s: float = 30.0
    wind: WindDisturbance = WindDisturbance()
    wind_known: bool = False
    period_s: float = 0.1
    weights: dict = field(default_factory=lambda: dict(SINGLE_WEIGHTS))
    accel_mode: str = "ramp"
    max_time_s: float = 4000.0


def scenario_a(length_m: float = 5000.0, **kw: Any) -> Scenario:
    return Scenario("A", (length_m,), paper_gradient(length_m + 100.0, seed=3), **kw)


def scenario_b(**kw: Any) -> Scenario:
    kw.setdefault("weights", dict(SINGLE_WEIGHTS))
    return Scenario(
        "B", PAPER_STOPS_M, paper_gradient(PAPER_STOPS_M[-1] + 100.0, seed=7), limits=paper_multi_limits(), **kw
    )


def scenario_c(kind: str = "constant", length_m: float = 5000.0, **kw: Any) -> Scenario:
    return Scenario(
        f"C-{kind}", (length_m,), paper_gradient(length_m + 100.0, seed=3), wind=WindDisturbance(kind=kind), **kw
    )


def make_law(
    name: str, p: MultipointParams, period_s: float, weights: dict, reference_mode: str = "distance", **overrides: Any
) -> CarriageLaw:
    if name == "sempc":
        return make_sempc_law(p, reference_mode, period_s=period_s, **weights, **overrides)
    if name == "mpc":
        return make_mpc_law(p, "A", reference_mode, period_s=period_s, **weights, **overrides)
    if name == "mpc_b":
        r = {**weights, "r_u": weights.get("r_du", 1e-5)}
        return make_mpc_law(p, "B", reference_mode, period_s=period_s, **r, **overrides)
    if name == "afsmc":
        return AfsmcLaw(p, replace(AfsmcParams(period_s=period_s), **overrides), reference_mode)
    if name == "pid":
        return PidLaw(p, replace(PidParams(period_s=period_s), **overrides), reference_mode)
    raise ValueError(f"controller: expected one of {', '.join(CONTROLLERS)}, got {name!r}")


@dataclass
class RunResult:
    scenario: str
    controller: str
    period_s: float
    t_s: np.ndarray
    rel: np.ndarray  # (K, 2n)
    forces_n: np.ndarray  # (K, n) applied during [t_k, t_k + T)
    x_ref_m: np.ndarray
    v_ref_mps: np.ndarray
    section: np.ndarray
    dwell: np.ndarray
    v_max_mps: np.ndarray
    stop_errors_m: list[float]
    stop_times_s: list[float]
    fallbacks: int
    solve_times_s: list[float]
    metrics: dict = field(default_factory=dict)


def _profile(sc: Scenario, stop_m: float) -> SpeedDistanceProfile:
    return SpeedDistanceProfile(
        stop_m=stop_m, line_speed_mps=sc.line_speed_mps, design_speed_mps=sc.design_speed_mps, limits=sc.limits
    )


def run(
    sc: Scenario,
    controller: str,
    p: MultipointParams = MultipointParams(),
    reference_mode: str = "distance",
    law_overrides: dict | None = None,
) -> RunResult:
    """Simulate ``controller`` through all sections of ``sc``; returns the trajectories and :func:`metrics`."""
    period = sc.period_s
    law = make_law(controller, p, period, sc.weights, reference_mode, **(law_overrides or {}))
    driver = AtoDriver(law, p, period)
    state = initial_state(p, 0.0)
    t = 0.0
    section = 0
    profile = _profile(sc, sc.stops_m[0])
    tref = time_profile(profile, 0.0, period, sc.accel_mode)
    t_dep = 0.0
    dwell_until = -1.0
    arrived = False
    held_since: float | None = None
    rows_rel, rows_u, rows_t, rows_xr, rows_vr, rows_sec, rows_dw, rows_vmax = [], [], [], [], [], [], [], []
    stop_errors: list[float] = []
    stop_times: list[float] = []
    finished_at: float | None = None
    while t < sc.max_time_s:
        rel = state.relative()
        grad = carriage_gradients_permille(p, state.positions_m, sc.gradient)
        dwelling = arrived and t < dwell_until
        if arrived and not dwelling:
            if section + 1 >= len(sc.stops_m):
                break
            section += 1
            profile = _profile(sc, sc.stops_m[section])
            tref = time_profile(profile, state.lead_position_m, period, sc.accel_mode)
            t_dep = t
            arrived = False
            held_since = None
        sit = Situation(t, rel, grad, profile, tref, t - t_dep, sc.wind.accel_mps2(t) if sc.wind_known else 0.0)
        u, _ = driver.step(sit, dwelling)
        xr, vr = tref.at(tref.index(t - t_dep))
        rows_t.append(t)
        rows_rel.append(rel)
        rows_u.append(u)
        rows_xr.append(float(xr))
        rows_vr.append(float(vr))
        rows_sec.append(section)
        rows_dw.append(dwelling or (finished_at is not None))
        rows_vmax.append(float(profile.static_limit_mps(rel[0])))
        state = step(p, state, u, period, sc.gradient, t, sc.wind)
        t = round(t + period, 9)
        if finished_at is not None:
            if t >= finished_at:
                break
            continue
        if arrived:
            continue
        near = abs(profile.stop_m - state.lead_position_m) <= 50.0
        if state.held and near:
            held_since = t if held_since is None else held_since
            if len(stop_errors) == section:  # first standstill near the mark: E_p
                stop_errors.append(abs(profile.stop_m - state.lead_position_m))
                stop_times.append(t)
            if driver.holding or t - held_since > 20.0:
                arrived = True
                dwell_until = t + sc.dwell_s
                if section + 1 >= len(sc.stops_m):
                    finished_at = t + 2.0  # record a short hold after the last stop
        else:
            held_since = None
    res = RunResult(
        sc.name,
        controller,
        period,
        np.array(rows_t),
        np.array(rows_rel),
        np.array(rows_u),
        np.array(rows_xr),
        np.array(rows_vr),
        np.array(rows_sec),
        np.array(rows_dw, dtype=bool),
        np.array(rows_vmax),
        stop_errors,
        stop_times,
        driver.stats.fallbacks,
        list(driver.stats.solve_times_s),
    )
    res.metrics = metrics(res, p, len(sc.stops_m))
    return res


def metrics(r: RunResult, p: MultipointParams, n_sections: int) -> dict[str, Any]:
    n = p.n_cars
    T = r.period_s
    run_mask = ~r.dwell
    x1 = r.rel[:, 0]
    v1 = r.rel[:, n]
    coupler_dev = r.rel[:, 1:n] + p.coupler_length_m
    rel_speed = r.rel[:, n + 1 :]
    out: dict[str, Any] = {
        **tracking_metrics(x1, v1, r.x_ref_m, r.v_ref_mps, run_mask),
        "e_p_m": float(np.mean(r.stop_errors_m)) if len(r.stop_errors_m) == n_sections else float("inf"),
        "stop_errors_m": [float(e) for e in r.stop_errors_m],
        **actuator_metrics(r.forces_n, p, T),
        "speed_limit_violations": int(np.sum(v1 > r.v_max_mps + 1e-6)),
        "coupler_band_violations": int(np.sum(np.abs(coupler_dev) > p.coupler_slack_m)),
        "max_coupler_deviation_m": float(np.max(np.abs(coupler_dev))) if n > 1 else 0.0,
        "max_relative_speed_mps": float(np.max(np.abs(rel_speed))) if n > 1 else 0.0,
        "fallbacks": int(r.fallbacks),
        "duration_s": float(r.t_s[-1] + T) if r.t_s.size else 0.0,
        "steps": int(r.t_s.size),
    }
    if r.solve_times_s:
        st = np.array(r.solve_times_s)
        out["solve_ms_median"] = float(np.median(st) * 1e3)
        out["solve_ms_p95"] = float(np.percentile(st, 95) * 1e3)
    sections = []
    for s_idx in range(n_sections):
        m = (r.section == s_idx) & run_mask
        if not np.any(m):
            continue
        sections.append(
            {
                "section": s_idx + 1,
                "e_v_mps": float(np.mean(np.abs(r.v_ref_mps - v1)[m])),
                "e_x_m": float(np.mean(np.abs(r.x_ref_m - x1)[m])),
                "e_p_m": float(r.stop_errors_m[s_idx]) if s_idx < len(r.stop_errors_m) else float("inf"),
                "samples": int(np.sum(m)),
            }
        )
    out["sections"] = sections
    return out
