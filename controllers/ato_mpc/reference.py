"""Reference (expected) speed and displacement profiles for the ATO MPCs (spec §2.9, §6 A11, A17).

Two views of one speed–distance profile between a departure point and a stop point:

* **Speed cap** ``v_cap(s)`` (the "speed–distance curve" of ATO practice): the static limit
  ``v_max(s) = min(v_line(s), v_ATP(s), v_design) − margin`` and, ahead of every lower limit and of the stop
  point, the constant-deceleration braking curve ``√(v_j² + 2 b (s_j − s))``. It is evaluated at any position,
  so a controller can rebuild its reference from wherever the train is ("distance" mode: the reference
  never runs away from a delayed train, and the stop point is reached exactly on the curve).
* **Time profile** ``v_r(t), x_r(t)`` on the control grid (Paper B's "expected speed/displacement", "time"
  mode): a forward pass that accelerates at ``accel_mps2`` (``accel_mode="ramp"``) or jumps straight to the
  cap (``"step"`` — the paper's deliberately jerk-infeasible "acceleration phase with the maximum target
  speed", spec §4.1), follows ``v_cap`` and brakes onto the stop; ``x_r`` is integrated from ``v_r`` with the
  trapezoid rule so the two are consistent (A11: otherwise E_x is meaningless).

The paper's routes (spec §4): Scenario A, a single section with an ATP limit of 45.8 m/s and a time-varying
gradient; Scenario B, stops at 14687 / 25279 / 33086 m with a varying ATP curve and gradient, dwell 30 s. No
numbers for gradients or ATP curves are published, so :func:`paper_gradient` and :func:`paper_multi_limits`
are **synthetic** (deterministic, documented), within ±12 ‰ so that the reference acceleration stays feasible
for the Table-1 force limits (1.08 m/s² minus resistance).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

PAPER_STOPS_M = (14687.0, 25279.0, 33086.0)
PAPER_ATP_MPS = 45.8


@dataclass(frozen=True)
class PiecewiseConstant:
    """A function of position, constant on ``[breaks_m[i], breaks_m[i+1])``; ``values[i]`` from ``breaks_m[i]``.

    Before the first break the first value applies. Vectorised ``__call__``.
    """

    breaks_m: tuple[float, ...]
    values: tuple[float, ...]

    def __post_init__(self) -> None:
        if len(self.breaks_m) != len(self.values) or not self.breaks_m:
            raise ValueError("breaks_m and values must be non-empty and of the same length")
        if any(b2 <= b1 for b1, b2 in zip(self.breaks_m, self.breaks_m[1:])):
            raise ValueError("breaks_m must be strictly increasing")

    def __call__(self, positions_m: np.ndarray | float) -> np.ndarray:
        idx = np.searchsorted(np.asarray(self.breaks_m), np.asarray(positions_m, dtype=float), side="right") - 1
        return np.asarray(self.values)[np.clip(idx, 0, len(self.values) - 1)]


FLAT = PiecewiseConstant((0.0,), (0.0,))


@dataclass(frozen=True)
class Limit:
    """A speed limit on ``[start_m, end_m)`` (route chainage of the train front)."""

    start_m: float
    end_m: float
    speed_mps: float


@dataclass(frozen=True)
class SpeedDistanceProfile:
    """The speed cap between the current position and ``stop_m`` (see module docstring).

    ``limits`` are restrictions below ``line_speed_mps`` (line speed, ATP, …) and ``design_speed_mps`` is the
    train's own maximum, so ``v_max(s) = min(line, limits at s, design)``. ``margin_mps`` keeps the reference
    below the limit (ATP supervision); ``brake_mps2`` is the reference deceleration onto limits and the stop.
    """

    stop_m: float
    line_speed_mps: float = PAPER_ATP_MPS
    design_speed_mps: float = math.inf
    limits: tuple[Limit, ...] = ()
    margin_mps: float = 1.0
    brake_mps2: float = 0.7
    accel_mps2: float = 0.9

    def __post_init__(self) -> None:
        for name in ("line_speed_mps", "design_speed_mps", "brake_mps2", "accel_mps2"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name}: expected a number > 0, got {getattr(self, name)!r}")
        if not self.margin_mps >= 0.0:
            raise ValueError(f"margin_mps: expected a number >= 0, got {self.margin_mps!r}")

    def static_limit_mps(self, s_m: np.ndarray | float) -> np.ndarray:
        """``v_max(s) = min(v_line, v_ATP(s), v_design)`` (Eq. (13), A17), without margin or braking curves."""
        s = np.asarray(s_m, dtype=float)
        v = np.full(s.shape, min(self.line_speed_mps, self.design_speed_mps))
        for lim in self.limits:
            inside = (s >= lim.start_m) & (s < lim.end_m)
            v = np.where(inside, np.minimum(v, lim.speed_mps), v)
        return v

    def cap_mps(self, s_m: np.ndarray | float) -> np.ndarray:
        """The reference speed cap at positions ``s_m`` (static limit − margin, braking curves, 0 past the stop)."""
        s = np.asarray(s_m, dtype=float)
        b2 = 2.0 * self.brake_mps2
        v = np.maximum(self.static_limit_mps(s) - self.margin_mps, 0.0)
        for lim in self.limits:
            target = max(lim.speed_mps - self.margin_mps, 0.0)
            ahead = s < lim.start_m
            v = np.where(ahead, np.minimum(v, np.sqrt(target**2 + b2 * np.maximum(lim.start_m - s, 0.0))), v)
        return np.minimum(v, np.sqrt(b2 * np.maximum(self.stop_m - s, 0.0)))


@dataclass(frozen=True)
class TimeReference:
    """Expected speed/displacement of carriage 1 on the grid ``t = t0 + k·period_s`` (spec §2.9)."""

    period_s: float
    x_m: np.ndarray
    v_mps: np.ndarray
    t0_s: float = 0.0
    meta: dict = field(default_factory=dict)

    def index(self, t_s: float) -> int:
        return int(round((t_s - self.t0_s) / self.period_s))

    def at(self, k: int | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x_r, v_r) at sample indices ``k`` (clamped: before the start it is the start, after the end the end)."""
        kk = np.clip(np.asarray(k), 0, self.x_m.size - 1)
        return self.x_m[kk], self.v_mps[kk]


def time_profile(
    profile: SpeedDistanceProfile, start_m: float, period_s: float, accel_mode: str = "ramp", max_steps: int = 10**6
) -> TimeReference:
    """Forward pass over the speed cap from a standstill at ``start_m`` to the stop (see module docstring)."""
    if accel_mode not in ("ramp", "step"):
        raise ValueError(f"accel_mode: expected ramp or step, got {accel_mode!r}")
    xs = [start_m]
    vs = [0.0]
    x, v = start_m, 0.0
    for _ in range(max_steps):
        if profile.stop_m - x <= 1e-3 and v == 0.0:
            break
        if accel_mode == "ramp":
            v_next = min(v + profile.accel_mps2 * period_s, float(profile.cap_mps(x + v * period_s)))
        else:
            v_next = float(profile.cap_mps(x + v * period_s))
        x_next = x + 0.5 * (v + v_next) * period_s
        if x_next >= profile.stop_m or (v_next < 1e-3 and profile.stop_m - x_next < 0.05):
            x_next, v_next = profile.stop_m, 0.0
        x, v = x_next, v_next
        xs.append(x)
        vs.append(v)
    else:  # pragma: no cover - a profile that never reaches its stop is a bug
        raise RuntimeError("time_profile did not reach the stop")
    return TimeReference(period_s, np.array(xs), np.array(vs))


def distance_window(
    profile: SpeedDistanceProfile, x1_m: float, v1_mps: float, period_s: float, n_p: int
) -> tuple[np.ndarray, np.ndarray, float]:
    """Reference over the horizon rebuilt from the measured state ("distance" mode).

    ``v_r(k+i) = min(v_cap(s_i), v_1 + a_ref·i·T)`` with ``s_i`` advanced along the reference itself and
    ``x_r(k) = x_1``. Returns ``(x_ref[1..N], v_ref[1..N], v_r(k))``. The acceleration clamp keeps the
    reference reachable at departure and after a hold; the cap makes the train ride the braking curve.
    """
    v0 = float(min(profile.cap_mps(x1_m), max(v1_mps, 0.0)))  # type: ignore[arg-type]
    xr = np.empty(n_p)
    vr = np.empty(n_p)
    s, v = x1_m, v0
    for i in range(n_p):
        cap_mps = float(profile.cap_mps(s + v * period_s))
        v_next = min(cap_mps, max(v1_mps, 0.0) + profile.accel_mps2 * (i + 1) * period_s)
        s = min(s + 0.5 * (v + v_next) * period_s, max(profile.stop_m, x1_m))
        v = v_next
        xr[i], vr[i] = s, v
    return xr, vr, v0


def paper_gradient(length_m: float, seed: int = 3, max_permille: float = 12.0) -> PiecewiseConstant:
    """Synthetic piecewise-constant gradient (A10): a new value in ±max every 200–800 m, 0 ‰ on the first 300 m.

    Deterministic for a given seed (the paper's Fig. 3 profiles are not published in numbers).
    """
    rng = np.random.default_rng(seed)
    breaks = [0.0, 300.0]
    values = [0.0]
    while breaks[-1] < length_m:
        values.append(float(np.round(rng.uniform(-max_permille, max_permille), 1)))
        breaks.append(breaks[-1] + float(rng.uniform(200.0, 800.0)))
    return PiecewiseConstant(tuple(breaks[:-1]), tuple(values))


def paper_multi_limits() -> tuple[Limit, ...]:
    """Synthetic ATP restrictions for Scenario B (real on-board data are not published)."""
    return (
        Limit(5000.0, 7000.0, 30.0),
        Limit(18000.0, 20500.0, 35.0),
        Limit(28500.0, 30000.0, 25.0),
    )
