"""Paper A's tracking metrics (spec 000 §4 S-D/S-E, Table III/IV format, A7, A33) from a :class:`PlatoonRun`.

Per follower ``i``: mean |Δv_i| (``Δv_i = v_{i−1} − v_i``) and mean |ΔS_i − D^(e)_i| over all samples
``t_0 … t_T`` and over the late phase (A7: ``t ∈ [late_start_s, late_end_s)``, default [300, 500) s); the
VC-establishment time (A33: ``|ΔS − D^(e)| ≤ 10 m`` and ``|Δv| ≤ 0.01 m/s``) both as the first sample that
satisfies it and as the first sample from which it holds for at least ``sustain_s`` (30 s); the safety margin
``min(ΔS − D^(s))``; solve time mean/p95 and the fallback count.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from controllers.mcf_dmpc.sim import PlatoonRun

__all__ = ["FollowerMetrics", "follower_metrics", "format_table", "vc_times"]


@dataclass(frozen=True)
class FollowerMetrics:
    train: int  # 1-based (2 = first follower)
    mean_abs_dv_mps: float
    mean_abs_spacing_error_m: float
    late_mean_abs_dv_mps: float
    late_mean_abs_spacing_error_m: float
    vc_first_s: float  # NaN: never
    vc_sustained_s: float  # NaN: never for sustain_s
    min_safety_margin_m: float
    solve_time_mean_s: float
    solve_time_p95_s: float
    fallbacks: int


def vc_times(t: np.ndarray, ok: np.ndarray, sustain_s: float) -> tuple[float, float]:
    """First time the criterion holds, and first time it then holds for ≥ ``sustain_s`` (NaN if never)."""
    hits = np.flatnonzero(ok)
    first = float(t[hits[0]]) if hits.size else math.nan
    sustained = math.nan
    run_start = None
    for k in range(len(t)):
        if ok[k]:
            if run_start is None:
                run_start = k
            if t[k] - t[run_start] >= sustain_s:
                sustained = float(t[run_start])
                break
        else:
            run_start = None
    return first, sustained


def follower_metrics(
    run: PlatoonRun,
    late_start_s: float = 300.0,
    late_end_s: float = 500.0,
    spacing_tol_m: float = 10.0,
    speed_tol_mps: float = 0.01,
    sustain_s: float = 30.0,
) -> list[FollowerMetrics]:
    dv = run.speed_error_mps
    err = run.spacing_m - run.desired_m
    margin = run.spacing_m - run.safe_m
    late = (run.t >= late_start_s) & (run.t < late_end_s)
    out = []
    for c in range(dv.shape[1]):
        i = c + 1
        ok = (np.abs(err[:, c]) <= spacing_tol_m) & (np.abs(dv[:, c]) <= speed_tol_mps)
        first, sustained = vc_times(run.t, ok, sustain_s)
        st = run.solve_time_s[:, i]
        st = st[np.isfinite(st)]
        out.append(
            FollowerMetrics(
                train=i + 1,
                mean_abs_dv_mps=float(np.mean(np.abs(dv[:, c]))),
                mean_abs_spacing_error_m=float(np.mean(np.abs(err[:, c]))),
                late_mean_abs_dv_mps=float(np.mean(np.abs(dv[late, c]))) if late.any() else math.nan,
                late_mean_abs_spacing_error_m=float(np.mean(np.abs(err[late, c]))) if late.any() else math.nan,
                vc_first_s=first,
                vc_sustained_s=sustained,
                min_safety_margin_m=float(np.min(margin[:, c])),
                solve_time_mean_s=float(np.mean(st)) if st.size else math.nan,
                solve_time_p95_s=float(np.percentile(st, 95)) if st.size else math.nan,
                fallbacks=int(np.sum(run.fallback[:, i])),
            )
        )
    return out


def format_table(rows: dict[str, list[FollowerMetrics]]) -> str:
    """A plain-text table, one line per (method, train)."""
    head = (
        f"{'method':<14}{'train':>6}{'|dv|':>9}{'|e|':>9}{'late|dv|':>10}{'late|e|':>9}{'VC1st':>7}{'VC30':>7}"
        f"{'minSafe':>9}{'t_mean':>9}{'t_p95':>9}{'fb':>4}"
    )
    lines = [head]
    for name, ms in rows.items():
        for m in ms:
            d = asdict(m)
            lines.append(
                f"{name:<14}{d['train']:>6}{d['mean_abs_dv_mps']:>9.4f}{d['mean_abs_spacing_error_m']:>9.2f}"
                f"{d['late_mean_abs_dv_mps']:>10.4f}{d['late_mean_abs_spacing_error_m']:>9.2f}"
                f"{d['vc_first_s']:>7.0f}{d['vc_sustained_s']:>7.0f}{d['min_safety_margin_m']:>9.1f}"
                f"{d['solve_time_mean_s'] * 1e3:>8.2f}m{d['solve_time_p95_s'] * 1e3:>8.2f}m{d['fallbacks']:>4}"
            )
    return "\n".join(lines)
