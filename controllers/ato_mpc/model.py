"""Paper B's controller model: relative coordinates, linearisation, discretisation, Δu augmentation, prediction.

Spec ``shared/spec/001_ato_sempc.md`` §2.3–2.8 (Eq. (4)–(9)). The state is

    x = [x_1, x_{2,1}, …, x_{n,n−1}, v_1, v_{2,1}, …, v_{n,n−1}]ᵀ,   x_{i,i−1} = x_i − x_{i−1} (≈ −l at rest)

and ``ẋ = A x + B u + d`` with the v² Davis term linearised about the reference speed ``v_r``
(``v² ≈ 2 v_r v − v_r²``, §2.4). Rather than typing the paper's (garbled) A21 and d, we build the linear model
in **absolute** coordinates — where every row is one line of Eq. (1) — and transform it with the difference
matrix ``T`` (``x_rel = T x_abs``): ``A = T A_abs T⁻¹``, ``B = T B_abs``, ``d = T d_abs``. This reproduces the
spec's corrected A21 and d for n = 6 (including ``d_{v_{i,i−1}} = w_{i−1} − w_i`` in the middle rows, an
erratum of the paper) and works for any n ≥ 1; the tests check it against the spec's explicit matrices.

Discretisation (Eq. (6)): forward Euler ``A_d = I + A T``, ``B_d = T B`` and **``d_d = T d``** (the paper's
"+ d" is dimensionally wrong, spec §2.6 / A6), or the exact zero-order hold (matrix exponential) as an option
(A7: the Euler model of the 12–24 rad/s coupler modes is violently unstable for T ≳ 0.1 s).

Augmentation (Eq. (7)): ``ξ = [x; u(k−1)]``, ``ξ(k+1) = Ã ξ + B̃ Δu + D̃``, ``Ã = [[A_d, B_d], [0, I]]``,
``B̃ = [B_d; I]``, ``D̃ = [d_d; 0]``. Prediction (Eq. (8)) over ``N_p`` steps with ``N_c ≤ N_p`` free increments
(``Δu(k+i) = 0`` for ``i ≥ N_c``, A22): ``Ξ = F ξ(k) + G ΔU + D``. ``D̃`` is frozen over the horizon at its
time-k value (v_r(k), slopes at k), as the paper implies.

Disturbance: an extra per-unit-mass resistance ``ŵ`` (wind, or an offset-free estimate) enters every
carriage like the gradient term, i.e. the v_1 row of ``d`` only (it cancels in the relative rows).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from railsim.physics.multipoint import G_MPS2, MultipointParams

DISCRETISATIONS = ("euler", "zoh")


def difference_matrix(n: int) -> np.ndarray:
    """``T_n``: row 0 picks x_1, row i gives x_{i+1} − x_i (the paper's relative coordinates)."""
    t = np.eye(n)
    t[np.arange(1, n), np.arange(n - 1)] = -1.0
    return t


def absolute_linear_model(
    p: MultipointParams, v_ref_mps: float, gradient_permille: np.ndarray, wind_mps2: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. (1)–(3) linearised about ``v_ref`` in absolute coordinates ``[x_1..x_n, v_1..v_n]``: (A, B, d)."""
    n = p.n_cars
    m = p.car_mass_kg
    k = p.coupler_stiffness_n_per_m
    c = p.coupler_damping_ns_per_m
    grad = np.broadcast_to(np.asarray(gradient_permille, dtype=float), (n,))
    # Chain Laplacian: coupler i (between carriages i, i+1) acts with +/- on its two ends.
    lap = np.zeros((n, n))
    for i in range(n - 1):
        lap[i, i] += 1.0
        lap[i + 1, i + 1] += 1.0
        lap[i, i + 1] -= 1.0
        lap[i + 1, i] -= 1.0
    a = np.zeros((2 * n, 2 * n))
    a[:n, n:] = np.eye(n)
    a[n:, :n] = -(k / m) * lap
    a[n:, n:] = -(c / m) * lap - (p.c1_per_s + 2.0 * p.c2_per_m * v_ref_mps) * np.eye(n)
    b = np.zeros((2 * n, n))
    b[n:, :] = np.eye(n) / m
    d = np.zeros(2 * n)
    spring_const = np.zeros(n)
    if n > 1:
        # k(x_{i−1} − x_i − l) − k(x_i − x_{i+1} − l): the natural length enters the end carriages only.
        spring_const[0] = k * p.coupler_length_m / m
        spring_const[-1] = -k * p.coupler_length_m / m
    d[n:] = -p.c0_mps2 + p.c2_per_m * v_ref_mps**2 + spring_const - G_MPS2 * grad * 1e-3 - wind_mps2
    return a, b, d


def continuous_model(
    p: MultipointParams, v_ref_mps: float, gradient_permille: np.ndarray, wind_mps2: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. (5) in relative coordinates: (A, B, d) with the spec's corrected A21 and d."""
    a_abs, b_abs, d_abs = absolute_linear_model(p, v_ref_mps, gradient_permille, wind_mps2)
    tn = difference_matrix(p.n_cars)
    t = scipy.linalg.block_diag(tn, tn)
    t_inv = np.linalg.inv(t)
    return t @ a_abs @ t_inv, t @ b_abs, t @ d_abs


def affine_term(
    p: MultipointParams, v_ref_mps: float, gradient_permille: np.ndarray, wind_mps2: float = 0.0
) -> np.ndarray:
    """Only ``d`` of Eq. (5) (relative coordinates): cheap, for per-step updates of a cached linearisation."""
    _, _, d_abs = absolute_linear_model(p, v_ref_mps, gradient_permille, wind_mps2)
    n = p.n_cars
    out = d_abs.copy()
    out[1:n] = np.diff(d_abs[:n])
    out[n + 1 :] = np.diff(d_abs[n:])
    return out


def affine_map(a: np.ndarray, period_s: float, method: str = "euler") -> np.ndarray:
    """``Γ`` with ``d_d = Γ d``: ``T·I`` for Euler, ``∫₀ᵀ e^{Aτ} dτ`` for ZOH."""
    if method == "euler":
        return period_s * np.eye(a.shape[0])
    if method == "zoh":
        nx = a.shape[0]
        big = np.zeros((2 * nx, 2 * nx))
        big[:nx, :nx] = a
        big[:nx, nx:] = np.eye(nx)
        return scipy.linalg.expm(big * period_s)[:nx, nx:]
    raise ValueError(f"discretisation: expected one of {', '.join(DISCRETISATIONS)}, got {method!r}")


def discretise(
    a: np.ndarray, b: np.ndarray, d: np.ndarray, period_s: float, method: str = "euler"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. (6): ``(A_d, B_d, d_d)``; forward Euler (paper, with ``d_d = T·d``) or exact ZOH."""
    if method == "euler":
        return np.eye(a.shape[0]) + a * period_s, b * period_s, d * period_s
    if method == "zoh":
        nx, nu = b.shape
        big = np.zeros((nx + nu + 1, nx + nu + 1))
        big[:nx, :nx] = a
        big[:nx, nx : nx + nu] = b
        big[:nx, -1] = d
        e = scipy.linalg.expm(big * period_s)
        return e[:nx, :nx], e[:nx, nx : nx + nu], e[:nx, -1]
    raise ValueError(f"discretisation: expected one of {', '.join(DISCRETISATIONS)}, got {method!r}")


def augment(ad: np.ndarray, bd: np.ndarray, dd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. (7): the Δu-augmented model ``(Ã, B̃, D̃)`` on ``ξ = [x; u(k−1)]``."""
    nx, nu = bd.shape
    at = np.zeros((nx + nu, nx + nu))
    at[:nx, :nx] = ad
    at[:nx, nx:] = bd
    at[nx:, nx:] = np.eye(nu)
    bt = np.vstack([bd, np.eye(nu)])
    return at, bt, np.concatenate([dd, np.zeros(nu)])


def prediction_matrices(
    at: np.ndarray, bt: np.ndarray, dt: np.ndarray, n_p: int, n_c: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. (8): ``Ξ = F ξ(k) + G ΔU + D`` with ``Ξ = [ξ(k+1)…ξ(k+N_p)]``, ``ΔU = [Δu(k)…Δu(k+N_c−1)]``."""
    if not (1 <= n_c <= n_p):
        raise ValueError(f"horizons: expected 1 <= N_c <= N_p, got N_c={n_c}, N_p={n_p}")
    ns, nu = bt.shape
    powers = [np.eye(ns)]
    for _ in range(n_p):
        powers.append(at @ powers[-1])
    f = np.vstack(powers[1:])
    g = np.zeros((ns * n_p, nu * n_c))
    dvec = np.zeros(ns * n_p)
    acc = np.zeros(ns)
    for i in range(n_p):
        acc = at @ acc + dt  # Σ_{j≤i} Ã^j D̃
        dvec[i * ns : (i + 1) * ns] = acc
        for j in range(min(i + 1, n_c)):
            g[i * ns : (i + 1) * ns, j * nu : (j + 1) * nu] = powers[i - j] @ bt
    return f, g, dvec


@dataclass(frozen=True)
class LinearModel:
    """One linearisation of the controller model (everything the QP needs)."""

    a: np.ndarray
    b: np.ndarray
    d: np.ndarray
    ad: np.ndarray
    bd: np.ndarray
    dd: np.ndarray
    at: np.ndarray
    bt: np.ndarray
    dt: np.ndarray


def build_model(
    p: MultipointParams,
    v_ref_mps: float,
    gradient_permille: np.ndarray,
    period_s: float,
    discretisation: str = "euler",
    wind_mps2: float = 0.0,
) -> LinearModel:
    """Continuous → discrete → augmented model at ``v_ref`` with the slopes/wind frozen (spec §2.5–2.7)."""
    a, b, d = continuous_model(p, v_ref_mps, gradient_permille, wind_mps2)
    ad, bd, dd = discretise(a, b, d, period_s, discretisation)
    at, bt, dt = augment(ad, bd, dd)
    return LinearModel(a, b, d, ad, bd, dd, at, bt, dt)


def feedforward_forces_n(
    p: MultipointParams, accel_mps2: float, speed_mps: float, gradient_permille: np.ndarray, wind_mps2: float = 0.0
) -> np.ndarray:
    """Per-carriage force for a uniform acceleration with unstretched couplers (the u-reference of A7)."""
    grad = np.broadcast_to(np.asarray(gradient_permille, dtype=float), (p.n_cars,))
    res = p.c0_mps2 + p.c1_per_s * speed_mps + p.c2_per_m * speed_mps**2 + G_MPS2 * grad * 1e-3 + wind_mps2
    return p.car_mass_kg * (accel_mps2 + res)
