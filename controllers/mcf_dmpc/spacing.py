"""Paper A (spec 000) train unit and its two spacing laws: desired spacing D^(e) (Eq. 5) and safe spacing D^(s) (Eq. 6).

Paper A couples high-speed units under a *relative braking distance* regime. Both spacings are front-to-front
(ambiguity A3: ``ΔS_{i,i−1} = s_{i−1} − s_i``, the predecessor length ``L^(t)_{i−1}`` is inside the formula)::

    D^(e) = L^(s) + L^(t)_{i−1} + v_i²/(2|b^(c)_i|) − v_{i−1}²/(2|b^(m)_{i−1}|)      (5)  target of the CF laws
    D^(s) = L^(s) + L^(t)_{i−1} + v_i²/(2|b^(m)_i|) − v_{i−1}²/(2|b^(m)_{i−1}|)      (6)  hard constraint (20)

Readings: A4 — ``L^(s)`` is the constant ``1.5·v_m`` (145.833 m); A5 — the paper prints the decelerations as
signed numbers (−0.8, −1.0); here they are stored as positive magnitudes (``service_decel_mps2``) and the
control lower bound of Eq. (20) is ``−service_decel_mps2``. At equal speeds ``D^(e) = 348.833 + 0.125·v²`` and
``D^(s) = 348.833`` m with Table I.

The unit of Table I is also offered as a :class:`~railsim.physics.vehicle.VehicleParams` (:func:`paper000_vehicle`) with
mass 1 kg so that forces read as accelerations: the plant of :mod:`railsim.physics.dynamics` then integrates exactly
``dv/dt = u − (c0 + c1·v + c2·v²)`` (Eq. 1), and with ``step_method="ballistic"`` and τ = 1 s it reproduces the
zero-order hold of Eq. (2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from railsim.physics.vehicle import VehicleParams

__all__ = [
    "TABLE_I",
    "TrainParamsA",
    "desired_spacing_m",
    "paper000_vehicle",
    "safe_spacing_m",
    "train_params_from_vehicle",
]

V_MAX_MPS = 350.0 / 3.6  # Table I block speed limit v_m [m/s]


@dataclass(frozen=True)
class TrainParamsA:
    """One Paper A train unit (Table I); decelerations as positive magnitudes (A5), Davis per unit mass."""

    length_m: float = 203.0  # L^(t)
    safety_margin_m: float = 1.5 * V_MAX_MPS  # L^(s) = 1.5·v_m (A4: constant) [m]
    service_decel_mps2: float = 0.8  # |b^(c)|, also the lower bound of u (Eq. 20)
    emergency_decel_mps2: float = 1.0  # |b^(m)|
    max_accel_mps2: float = 1.0  # a^(m): upper bound of u and the IDM gain
    max_speed_mps: float = V_MAX_MPS  # v_m
    davis_c0_mps2: float = 1.18e-2  # c0 [m/s²]
    davis_c1_per_s: float = 7.76e-4  # c1 [1/s]
    davis_c2_per_m: float = 1.0e-5  # c2 [1/m]
    dt_s: float = 1.0  # τ, sampling time of Eq. (2)

    def __post_init__(self) -> None:
        for name in (
            "length_m",
            "service_decel_mps2",
            "emergency_decel_mps2",
            "max_accel_mps2",
            "max_speed_mps",
            "dt_s",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name}: expected a finite number > 0, got {value!r}")
        for name in ("safety_margin_m", "davis_c0_mps2", "davis_c1_per_s", "davis_c2_per_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name}: expected a finite number >= 0, got {value!r}")

    def resistance_mps2(self, speed_mps: np.ndarray | float) -> np.ndarray:
        """ω(v) = c0 + c1·|v| + c2·v² (Eq. 1), zero at standstill like :meth:`VehicleParams.resistance_n`."""
        v = np.abs(np.asarray(speed_mps, dtype=float))
        omega = self.davis_c0_mps2 + self.davis_c1_per_s * v + self.davis_c2_per_m * v * v
        return np.where(v == 0.0, 0.0, omega)

    def resistance_slope_per_s(self, speed_mps: np.ndarray | float) -> np.ndarray:
        """dω/dv = c1 + 2·c2·v (for v > 0), used to linearise Eq. (2) in the DMPC baseline."""
        v = np.abs(np.asarray(speed_mps, dtype=float))
        return self.davis_c1_per_s + 2.0 * self.davis_c2_per_m * v


TABLE_I = TrainParamsA()


def desired_spacing_m(
    own_speed_mps: np.ndarray | float,
    pred_speed_mps: np.ndarray | float,
    train: TrainParamsA = TABLE_I,
    pred_length_m: float | None = None,
    pred_emergency_decel_mps2: float | None = None,
) -> np.ndarray:
    """D^(e) of Eq. (5), front-to-front [m]: own service braking vs the predecessor's emergency braking.

    ``pred_length_m`` / ``pred_emergency_decel_mps2`` default to ``train``'s (Paper A: all units identical).
    """
    lp = train.length_m if pred_length_m is None else pred_length_m
    bp = train.emergency_decel_mps2 if pred_emergency_decel_mps2 is None else pred_emergency_decel_mps2
    v = np.asarray(own_speed_mps, dtype=float)
    vp = np.asarray(pred_speed_mps, dtype=float)
    return train.safety_margin_m + lp + v * v / (2.0 * train.service_decel_mps2) - vp * vp / (2.0 * bp)


def safe_spacing_m(
    own_speed_mps: np.ndarray | float,
    pred_speed_mps: np.ndarray | float,
    train: TrainParamsA = TABLE_I,
    pred_length_m: float | None = None,
    pred_emergency_decel_mps2: float | None = None,
) -> np.ndarray:
    """D^(s) of Eq. (6), front-to-front [m]: both trains at emergency braking (the hard constraint of Eq. 20)."""
    lp = train.length_m if pred_length_m is None else pred_length_m
    bp = train.emergency_decel_mps2 if pred_emergency_decel_mps2 is None else pred_emergency_decel_mps2
    v = np.asarray(own_speed_mps, dtype=float)
    vp = np.asarray(pred_speed_mps, dtype=float)
    return train.safety_margin_m + lp + v * v / (2.0 * train.emergency_decel_mps2) - vp * vp / (2.0 * bp)


def paper000_vehicle(train: TrainParamsA = TABLE_I, name: str = "paper000_203m") -> VehicleParams:
    """The Table I unit as plant parameters: mass 1 kg (forces = accelerations), Davis A, B, C = c0, c1, c2.

    Traction force 1 N (= a^(m)) with unlimited power, service/emergency braking 0.8/1.0 m/s², no actuator lag
    (τ = 0) and a jerk limit so large it never acts: Paper A's plant (Eq. 2) has neither.
    """
    return VehicleParams(
        name=name,
        length_m=train.length_m,
        mass_kg=1.0,
        rotating_mass_factor=1.0,
        davis_a_n=train.davis_c0_mps2,
        davis_b_n_per_mps=train.davis_c1_per_s,
        davis_c_n_per_mps2=train.davis_c2_per_m,
        max_speed_mps=train.max_speed_mps,
        traction_max_force_n=train.max_accel_mps2,
        traction_max_power_w=math.inf,
        service_decel_mps2=train.service_decel_mps2,
        emergency_decel_mps2=train.emergency_decel_mps2,
        jerk_limit_mps3=1.0e6,
        actuator_time_constant_s=0.0,
        capacity_pax=1000,
    )


def train_params_from_vehicle(
    vehicle: VehicleParams, safety_margin_m: float = TABLE_I.safety_margin_m, dt_s: float = 1.0
) -> TrainParamsA:
    """The prediction model of a controller from the plant's own :class:`VehicleParams` (one physics).

    Davis coefficients become per-unit-mass (divided by the effective mass); ``a^(m)`` is the low-speed traction
    limit ``F0/m_eff``.
    """
    m_eff = vehicle.effective_mass_kg
    return TrainParamsA(
        length_m=vehicle.length_m,
        safety_margin_m=safety_margin_m,
        service_decel_mps2=vehicle.service_decel_mps2,
        emergency_decel_mps2=vehicle.emergency_decel_mps2,
        max_accel_mps2=vehicle.traction_max_force_n / m_eff,
        max_speed_mps=vehicle.max_speed_mps,
        davis_c0_mps2=vehicle.davis_a_n / m_eff,
        davis_c1_per_s=vehicle.davis_b_n_per_mps / m_eff,
        davis_c2_per_m=vehicle.davis_c_n_per_mps2 / m_eff,
        dt_s=dt_s,
    )
