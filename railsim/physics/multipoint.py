"""Multi-point-mass train plant: n carriages joined by linear spring couplers, one force input per carriage.

This is the "truth" model of Paper B (Wang, Xing, Wang, IEEE Access 12, 2024, "Stability-Enhanced Model
Predictive Control for Urban Rail Transit Train"; extraction in ``shared/spec/001_ato_sempc.md``), Eq. (1)–(3):

    ẋ_i = v_i
    m_i v̇_i = u_i + k_s (x_{i−1} − x_i − l) − k_s (x_i − x_{i+1} − l) − m_i a_res,i      (missing terms at the ends)
    a_res,i = c0' + c1' v_i + c2' v_i² + g θ_i 10⁻³ + ŵ(t)

Carriage 1 leads (``x_1 > x_2 > …``); at rest every coupler is at its natural length ``l`` (spec §6 A4/A19).

Readings of the paper's ambiguities (all from the spec's suggestions, kept configurable):

* **Units.** Table 1 gives the Davis coefficients per tonne (N/t, N·s/(m·t), N·s²/(m²·t)); per unit mass in SI
  they are divided by 1000 (1 N/t = 10⁻³ m/s²; spec §2.2, A2).
* **Gradient per carriage** (A10): carriage ``i`` reads the gradient at ``x_1 − (i−1)·car_spacing_m``; the
  default spacing 0 is the paper-literal "every carriage at its own point" (the points are only ``l`` apart, so
  we simply use each point's own position ``x_i`` when the spacing is 0).
* **Wind** (A14): ``ŵ`` is an extra resistance per unit mass on every carriage (headwind positive), either
  constant (0.2) or harmonic ``a + b·cos(ω t)`` (0.1 + 0.1 cos t), in m/s² or in N/kN (× g/1000), from an onset
  time on.
* **Integration** (A13): the coupler modes reach ≈ 24 rad/s for Table 1 (``√(k_s/m)`` ≈ 12.4 rad/s per
  coupler), so explicit Euler at control periods ≥ 0.05 s is unstable. We integrate with classical RK4 on
  sub-steps of at most ``max_substep_s`` (default 5 ms, ``ω·h ≈ 0.12``: RK4's amplitude error per step is
  ``(ωh)⁶/144 ≈ 2·10⁻⁸``, so the undamped coupler oscillation neither grows nor decays noticeably over a run).
  The force input is zero-order held over the whole ``dt_s``; the gradient is re-read at every sub-step.
* **Holding brake / standstill** (A13): trains do not roll backwards. A moving train whose mean speed reaches
  ``standstill_mps`` while its total commanded force is not propulsive (Σu ≤ 0) is caught by the holding
  brake: all carriages stop, the state is flagged ``held``. A held train stays put until the total force is
  propulsive and exceeds the total standstill resistance (c0' + gradient + wind, all carriages; so a train on
  a down gradient does not roll away with zero command, as in :mod:`railsim.physics.dynamics`); then it is released and
  integrated normally. Within a sub-step, a carriage speed that would cross zero while the whole train is
  braking also triggers the hold (so a braking train cannot reverse).
* **Force saturation**: each ``u_i`` is clipped to ``[force_min_n, force_max_n]`` (Table 1: −6.5e4 … 7e4 N)
  before it acts; :func:`step` reports nothing about it, callers who care compare with
  :func:`clip_forces`.

For the engine (which moves one SUMO vehicle per train) the lead carriage is what SUMO sees:
:attr:`MultipointState.lead_position_m` and :attr:`MultipointState.lead_speed_mps`.
Pure numpy, no I/O.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from railsim.physics.units import G_MPS2  # noqa: E402

GradientFn = Callable[[np.ndarray], np.ndarray]
"""Gradient lookup: carriage positions [m] (array) → gradient in permille (array, uphill positive)."""

WIND_KINDS = ("none", "constant", "harmonic")
WIND_UNITS = ("mps2", "n_per_kn")


def flat(positions_m: np.ndarray) -> np.ndarray:
    """The level-track gradient function (0 ‰ everywhere)."""
    return np.zeros_like(np.asarray(positions_m, dtype=float))


@dataclass(frozen=True)
class MultipointParams:
    """Physical parameters of the n-carriage train; defaults are Paper B's Table 1 ("D-type", six carriages).

    Davis coefficients are per tonne as in Table 1; :attr:`c0_mps2` etc. give them per unit mass in SI.
    """

    n_cars: int = 6
    car_mass_kg: float = 64_800.0
    davis_c0_n_per_t: float = 9.888
    davis_c1_ns_per_m_t: float = 0.005
    davis_c2_ns2_per_m2_t: float = 0.00195
    coupler_stiffness_n_per_m: float = 1.0e7
    coupler_length_m: float = 1.2
    coupler_damping_ns_per_m: float = 0.0  # not in the paper (undamped springs); option for realism
    force_max_n: float = 7.0e4
    force_min_n: float = -6.5e4
    force_rate_max_n_per_s: float = 6.0e4
    force_rate_min_n_per_s: float = -6.0e4
    coupler_slack_m: float = 0.2  # l_safe: allowed deviation of a coupler from its target length
    car_spacing_m: float = 0.0  # gradient look-up offset between carriages (A10; 0 = paper-literal)
    max_substep_s: float = 0.005
    standstill_mps: float = 0.01

    def __post_init__(self) -> None:
        checks = (
            ("n_cars", self.n_cars >= 1 and float(self.n_cars).is_integer(), "an integer >= 1", self.n_cars),
            ("car_mass_kg", self.car_mass_kg > 0.0, "a number > 0", self.car_mass_kg),
            (
                "coupler_stiffness_n_per_m",
                self.coupler_stiffness_n_per_m > 0.0,
                "a number > 0",
                self.coupler_stiffness_n_per_m,
            ),
            ("coupler_length_m", self.coupler_length_m >= 0.0, "a number >= 0", self.coupler_length_m),
            (
                "coupler_damping_ns_per_m",
                self.coupler_damping_ns_per_m >= 0.0,
                "a number >= 0",
                self.coupler_damping_ns_per_m,
            ),
            ("force_max_n", self.force_max_n > 0.0, "a number > 0", self.force_max_n),
            ("force_min_n", self.force_min_n < 0.0, "a number < 0", self.force_min_n),
            ("force_rate_max_n_per_s", self.force_rate_max_n_per_s > 0.0, "a number > 0", self.force_rate_max_n_per_s),
            ("force_rate_min_n_per_s", self.force_rate_min_n_per_s < 0.0, "a number < 0", self.force_rate_min_n_per_s),
            ("coupler_slack_m", self.coupler_slack_m > 0.0, "a number > 0", self.coupler_slack_m),
            ("car_spacing_m", self.car_spacing_m >= 0.0, "a number >= 0", self.car_spacing_m),
            ("max_substep_s", 0.0 < self.max_substep_s <= 0.05, "a number in (0, 0.05]", self.max_substep_s),
            ("standstill_mps", self.standstill_mps > 0.0, "a number > 0", self.standstill_mps),
        )
        for name, ok, expectation, value in checks:
            if not ok:
                raise ValueError(f"{name}: expected {expectation}, got {value!r}")
        object.__setattr__(self, "n_cars", int(self.n_cars))

    # Per-unit-mass Davis coefficients in SI (spec §2.2): N/t → m/s² is a factor 1e-3.
    @property
    def c0_mps2(self) -> float:
        return self.davis_c0_n_per_t * 1e-3

    @property
    def c1_per_s(self) -> float:
        return self.davis_c1_ns_per_m_t * 1e-3

    @property
    def c2_per_m(self) -> float:
        return self.davis_c2_ns2_per_m2_t * 1e-3

    @property
    def total_mass_kg(self) -> float:
        return self.n_cars * self.car_mass_kg

    def masses_kg(self) -> np.ndarray:
        return np.full(self.n_cars, self.car_mass_kg)


@dataclass(frozen=True)
class WindDisturbance:
    """Paper B Scenario C wind: extra resistance per unit mass ``ŵ(t)`` on every carriage (spec §6 A14).

    ``kind``: ``"constant"`` → ``ŵ = constant``; ``"harmonic"`` → ``ŵ = offset + amplitude·cos(ω·(t))``
    (the paper's gust ``0.1 + 0.1·cos t``: t in simulation seconds, not shifted by the onset); ``"none"`` → 0.
    ``unit``: ``"mps2"`` (default) or ``"n_per_kn"`` (per-weight, × g/1000). Zero before ``onset_s``.
    """

    kind: str = "none"
    constant: float = 0.2
    offset: float = 0.1
    amplitude: float = 0.1
    omega_rad_per_s: float = 1.0
    unit: str = "mps2"
    onset_s: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in WIND_KINDS:
            raise ValueError(f"kind: expected one of {', '.join(WIND_KINDS)}, got {self.kind!r}")
        if self.unit not in WIND_UNITS:
            raise ValueError(f"unit: expected one of {', '.join(WIND_UNITS)}, got {self.unit!r}")
        for name in ("constant", "offset", "amplitude", "omega_rad_per_s", "onset_s"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{name}: expected a finite number, got {getattr(self, name)!r}")

    def accel_mps2(self, t_s: float) -> float:
        """ŵ(t) as a deceleration [m/s²] (positive opposes forward motion)."""
        if self.kind == "none" or t_s < self.onset_s:
            return 0.0
        if self.kind == "constant":
            w = self.constant
        else:
            w = self.offset + self.amplitude * math.cos(self.omega_rad_per_s * t_s)
        return w * G_MPS2 / 1000.0 if self.unit == "n_per_kn" else w


NO_WIND = WindDisturbance()


@dataclass(frozen=True)
class MultipointState:
    """Absolute carriage positions and speeds (carriage 1 leads) and the holding-brake flag.

    The arrays are stored read-only; use :func:`initial_state` to build one at rest.
    """

    positions_m: np.ndarray
    speeds_mps: np.ndarray
    held: bool = False
    _frozen: bool = field(default=True, repr=False)

    def __post_init__(self) -> None:
        x = np.array(self.positions_m, dtype=float)
        v = np.array(self.speeds_mps, dtype=float)
        if x.ndim != 1 or x.shape != v.shape or x.size < 1:
            raise ValueError("positions_m and speeds_mps must be 1-D arrays of the same length >= 1")
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(v))):
            raise ValueError("multipoint state is not finite (diverged integration or bad input)")
        x.setflags(write=False)
        v.setflags(write=False)
        object.__setattr__(self, "positions_m", x)
        object.__setattr__(self, "speeds_mps", v)

    @property
    def n_cars(self) -> int:
        return int(self.positions_m.size)

    @property
    def lead_position_m(self) -> float:
        """Position of carriage 1 (the train front as SUMO sees it)."""
        return float(self.positions_m[0])

    @property
    def lead_speed_mps(self) -> float:
        return float(self.speeds_mps[0])

    @property
    def mean_speed_mps(self) -> float:
        return float(np.mean(self.speeds_mps))

    def relative(self) -> np.ndarray:
        """Paper B's relative-coordinate state ``[x_1, x_{i,i−1}…, v_1, v_{i,i−1}…]`` (Eq. (4), spec §2.3)."""
        return np.concatenate(
            ([self.positions_m[0]], np.diff(self.positions_m), [self.speeds_mps[0]], np.diff(self.speeds_mps))
        )


def initial_state(params: MultipointParams, lead_position_m: float = 0.0, speed_mps: float = 0.0) -> MultipointState:
    """All carriages at ``speed_mps``, couplers at natural length, carriage 1 at ``lead_position_m`` (A19)."""
    x = lead_position_m - params.coupler_length_m * np.arange(params.n_cars)
    v = np.full(params.n_cars, float(speed_mps))
    return MultipointState(x, v, held=speed_mps <= 0.0)


def state_from_relative(relative: np.ndarray, held: bool = False) -> MultipointState:
    """Inverse of :meth:`MultipointState.relative`."""
    r = np.asarray(relative, dtype=float)
    n = r.size // 2
    x = r[0] + np.concatenate(([0.0], np.cumsum(r[1:n])))
    v = r[n] + np.concatenate(([0.0], np.cumsum(r[n + 1 :])))
    return MultipointState(x, v, held=held)


def clip_forces(params: MultipointParams, u_forces_n: np.ndarray) -> np.ndarray:
    """Per-carriage forces clipped to the traction/brake limits (Eq. (14))."""
    return np.clip(np.asarray(u_forces_n, dtype=float), params.force_min_n, params.force_max_n)


def carriage_gradients_permille(
    params: MultipointParams, positions_m: np.ndarray, gradient_fn: GradientFn
) -> np.ndarray:
    """θ_i for every carriage (spec A10): at ``x_1 − (i−1)·car_spacing_m``, or at ``x_i`` when the spacing is 0."""
    if params.car_spacing_m > 0.0:
        where = positions_m[0] - params.car_spacing_m * np.arange(positions_m.size)
    else:
        where = positions_m
    g = np.asarray(gradient_fn(where), dtype=float)
    return np.broadcast_to(g, positions_m.shape)


@lru_cache(maxsize=32)
def _chain_matrices(params: MultipointParams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(−k/m·L, −c/m·L, k·l/m at the two ends): the spring terms of Eq. (1) as one matrix product.

    ``L`` is the chain Laplacian, so ``−k/m·L·x + const`` equals the sum of the coupler forces over the mass.
    """
    n = params.n_cars
    lap = np.zeros((n, n))
    for i in range(n - 1):
        lap[i, i] += 1.0
        lap[i + 1, i + 1] += 1.0
        lap[i, i + 1] -= 1.0
        lap[i + 1, i] -= 1.0
    m = params.car_mass_kg
    const = np.zeros(n)
    if n > 1:
        const[0] = params.coupler_stiffness_n_per_m * params.coupler_length_m / m
        const[-1] = -const[0]
    for arr in (lap, const):
        arr.setflags(write=False)
    return -params.coupler_stiffness_n_per_m / m * lap, -params.coupler_damping_ns_per_m / m * lap, const


def coupler_forces_n(params: MultipointParams, positions_m: np.ndarray, speeds_mps: np.ndarray) -> np.ndarray:
    """Net coupler force on every carriage [N] (spring, plus the optional damper)."""
    ks, cs, const = _chain_matrices(params)
    return params.car_mass_kg * (ks @ positions_m + cs @ speeds_mps + const)


def accelerations_mps2(
    params: MultipointParams,
    positions_m: np.ndarray,
    speeds_mps: np.ndarray,
    u_forces_n: np.ndarray,
    gradient_permille: np.ndarray,
    wind_mps2: float = 0.0,
) -> np.ndarray:
    """Right-hand side of Eq. (1): carriage accelerations [m/s²] for already-clipped forces."""
    ks, cs, const = _chain_matrices(params)
    v = speeds_mps
    resist = (
        params.c0_mps2
        + params.c1_per_s * v
        + params.c2_per_m * v * np.abs(v)
        + G_MPS2 * 1e-3 * gradient_permille
        + wind_mps2
    )
    coupler = ks @ positions_m + const
    if params.coupler_damping_ns_per_m:
        coupler = coupler + cs @ v
    return u_forces_n / params.car_mass_kg + coupler - resist


def _standstill_resistance_n(params: MultipointParams, gradient_permille: np.ndarray, wind_mps2: float) -> float:
    return float(params.car_mass_kg * np.sum(params.c0_mps2 + G_MPS2 * gradient_permille * 1e-3 + wind_mps2))


def step(
    params: MultipointParams,
    state: MultipointState,
    u_forces_n: np.ndarray,
    dt_s: float,
    gradient_fn: GradientFn = flat,
    t_s: float = 0.0,
    wind: WindDisturbance = NO_WIND,
) -> MultipointState:
    """Advance the train by ``dt_s`` with the per-carriage forces ``u_forces_n`` held constant (ZOH).

    RK4 on ``ceil(dt_s / max_substep_s)`` equal sub-steps; the forces are clipped to the limits first; holding
    brake as described in the module docstring. ``t_s`` is the time at the start of the step (for the wind).
    Raises ValueError for a bad ``dt_s``, wrong input length or non-finite forces.
    """
    if not (0.0 < dt_s < math.inf):
        raise ValueError(f"dt_s must be a finite number > 0, got {dt_s!r}")
    u_raw = np.asarray(u_forces_n, dtype=float).reshape(-1)
    if u_raw.size != params.n_cars or state.n_cars != params.n_cars:
        raise ValueError(f"expected {params.n_cars} carriage forces and states, got {u_raw.size}/{state.n_cars}")
    if not np.all(np.isfinite(u_raw)):
        raise ValueError("u_forces_n contains NaN/inf: the controller produced no valid command")
    u = clip_forces(params, u_raw)
    total_force_n = float(np.sum(u))

    x = state.positions_m.copy()
    v = state.speeds_mps.copy()
    held = state.held
    n_sub = max(1, math.ceil(dt_s / params.max_substep_s - 1e-9))
    h = dt_s / n_sub
    for j in range(n_sub):
        t = t_s + j * h
        w = wind.accel_mps2(t)
        grad = carriage_gradients_permille(params, x, gradient_fn)
        if held:
            if total_force_n > max(_standstill_resistance_n(params, grad, w), 0.0):
                held = False
            else:
                continue

        def f(xx: np.ndarray, vv: np.ndarray) -> np.ndarray:
            return accelerations_mps2(params, xx, vv, u, grad, w)  # noqa: B023 - called in this iteration only

        k1v = f(x, v)
        k1x = v
        k2v = f(x + 0.5 * h * k1x, v + 0.5 * h * k1v)
        k2x = v + 0.5 * h * k1v
        k3v = f(x + 0.5 * h * k2x, v + 0.5 * h * k2v)
        k3x = v + 0.5 * h * k2v
        k4v = f(x + h * k3x, v + h * k3v)
        k4x = v + h * k3v
        x_new = x + h / 6.0 * (k1x + 2 * k2x + 2 * k3x + k4x)
        v_new = v + h / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v)
        braking = total_force_n <= 0.0
        if braking and (np.mean(v_new) <= params.standstill_mps or np.any(v_new < 0.0)):
            # The holding brake catches the train: keep the positions reached, zero every speed.
            if np.any(v_new < 0.0):
                # Do not let a carriage move backwards within the catching sub-step.
                x_new = np.maximum(x_new, x) if np.all(v >= 0.0) else x_new
            x, v, held = x_new, np.zeros_like(v_new), True
            continue
        x, v = x_new, v_new
    return MultipointState(x, v, held=held)
