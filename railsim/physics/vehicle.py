"""Vehicle (train unit) parameters: the one definition shared by the plant and the controllers.

A :class:`VehicleParams` describes one train unit (a 6-car monorail set, a 203 m high-speed unit...) in SI
units. The plant in :mod:`railsim.physics.dynamics` and every model-based controller read the *same* object, so a
controller's prediction model and the simulated train are the same physics unless a scenario says otherwise
(the do-mpc idea: one model feeds both the controller and the simulator).

Forces follow the usual traction-calculation conventions:

* running resistance (Davis): ``R(v) = A + B·v + C·v²`` [N], ``v`` in m/s;
* gradient resistance: ``m·g·i/1000`` [N] for a gradient of ``i`` per mille (uphill positive);
* traction envelope: ``F_max(v) = min(F0, P/v)`` [N] (constant force, then constant power);
* braking envelope: a constant service deceleration (blended electric + friction braking keeps metro
  service braking flat over speed) and a higher emergency deceleration, both as decelerations of the
  effective (rotating) mass;
* effective mass ``m_eff = m·(1 + rotating allowance)`` i.e. ``rotating_mass_factor·m``.

Presets come from ``railsim/data/vehicles.yaml`` (values and sources copied from the Chongqing Line 3
data pack; see that file's comments).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from functools import lru_cache
from importlib import resources
from typing import Any

import yaml

from railsim.physics import forces
from railsim.physics.units import G_MPS2  # noqa: F401  (re-exported: vehicle presets use it)


@dataclass(frozen=True)
class VehicleParams:
    """Physical parameters of one train unit, SI units (names carry the unit)."""

    name: str
    length_m: float
    mass_kg: float
    rotating_mass_factor: float = 1.08
    davis_a_n: float = 0.0  # constant term A [N]
    davis_b_n_per_mps: float = 0.0  # linear term B [N/(m/s)]
    davis_c_n_per_mps2: float = 0.0  # quadratic (aerodynamic) term C [N/(m/s)²]
    max_speed_mps: float = 20.8
    traction_max_force_n: float = 2.4e5  # F0: tractive effort at low speed [N]
    traction_max_power_w: float = 1.92e6  # P: power at the wheel [W]
    service_decel_mps2: float = 1.11  # full service braking deceleration (positive number) [m/s²]
    emergency_decel_mps2: float = 1.25  # emergency braking deceleration (positive number) [m/s²]
    jerk_limit_mps3: float = 0.75  # comfort jerk limit on the applied acceleration [m/s³]
    actuator_time_constant_s: float = 0.5  # first-order lag between command and applied acceleration [s]
    capacity_pax: int = 1342  # passengers per unit (for passengers/h)

    @property
    def effective_mass_kg(self) -> float:
        """Mass including the rotating-mass allowance [kg]."""
        return self.mass_kg * self.rotating_mass_factor

    def resistance_n(self, speed_mps: float, gradient_permille: float = 0.0) -> float:
        """Davis running resistance plus gradient resistance [N]; uphill gradients positive.

        A standing train feels no Davis term (static friction is not modelled), only the gradient. The law is
        :func:`railsim.physics.forces.resistance_n`, written once.
        """
        return forces.resistance_n(  # type: ignore[no-any-return]
            self.mass_kg, self.davis_a_n, self.davis_b_n_per_mps, self.davis_c_n_per_mps2, speed_mps, gradient_permille
        )

    def net_to_applied(self, net_accel_mps2: float, speed_mps: float, gradient_permille: float = 0.0) -> float:
        """Applied specific force [m/s²] that yields ``net_accel_mps2`` once resistance and gradient act."""
        return net_accel_mps2 + self.resistance_n(speed_mps, gradient_permille) / self.effective_mass_kg

    def __reduce__(self) -> tuple[type[VehicleParams], tuple[Any, ...]]:
        """Pickled and copied as a call of the constructor with the fields in order (compiled by
        :mod:`railsim.native`, a frozen dataclass has no way to set its fields back one by one)."""
        return (type(self), tuple(getattr(self, f.name) for f in fields(self)))

    def with_overrides(self, **changes: Any) -> VehicleParams:
        """Return a copy with some fields replaced (scenario overrides on top of a preset)."""
        return replace(self, **changes)


@lru_cache(maxsize=1)
def _preset_table() -> dict[str, dict[str, Any]]:
    text = resources.files("railsim").joinpath("data/vehicles.yaml").read_text(encoding="utf-8")
    data = yaml.safe_load(text) or {}
    return dict(data.get("vehicles", {}))


def preset_names() -> list[str]:
    """Names of the shipped vehicle presets."""
    return sorted(_preset_table())


def preset(name: str) -> VehicleParams:
    """The shipped preset ``name`` (KeyError if unknown; the scenario loader turns that into a ConfigError)."""
    fields = dict(_preset_table()[name])
    fields.pop("sources", None)
    # YAML 1.1 reads "1.0e9" as a string; presets are numbers by construction, so coerce explicitly
    fields = {k: (int(v) if k == "capacity_pax" else float(v)) for k, v in fields.items()}
    return VehicleParams(name=name, **fields)
