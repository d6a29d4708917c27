"""Tiny controllers registered under test-only names, so scenario tests do not depend on the real library.

Imported by the scenario tests in-process, and by ``sitecustomize.py`` (this folder on ``PYTHONPATH``) in the
``railsim validate`` subprocesses. Factories follow the registry contract: ``ValueError("<param>: expected ...")``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from controllers.base import Command, Observation, register, registered
from railsim.physics.vehicle import VehicleParams


class _Constant:
    def __init__(self, accel_mps2: float) -> None:
        self.accel_mps2 = accel_mps2

    def command(self, obs: Observation) -> Command:
        return Command(self.accel_mps2)


def _check_keys(params: Mapping[str, Any], allowed: tuple[str, ...]) -> None:
    for key in params:
        if key not in allowed:
            raise ValueError(f"{key}: unknown parameter; expected one of {', '.join(allowed)}")


def _number(params: Mapping[str, Any], key: str, default: float) -> float:
    value = params.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{key}: expected a number, got {value!r}")
    return float(value)


def make_ctrl(params: Mapping[str, Any], vehicle: VehicleParams) -> _Constant:
    """``gain`` > 0 (default 1)."""
    _check_keys(params, ("gain",))
    gain = _number(params, "gain", 1.0)
    if gain <= 0:
        raise ValueError(f"gain: expected a number > 0, got {params['gain']!r}")
    return _Constant(0.0)


def make_follow(params: Mapping[str, Any], vehicle: VehicleParams) -> _Constant:
    """``margin_m`` >= 0; ``brake_mps2`` no larger than the vehicle's emergency deceleration (vehicle-dependent)."""
    _check_keys(params, ("margin_m", "brake_mps2"))
    margin = _number(params, "margin_m", 50.0)
    if margin < 0:
        raise ValueError(f"margin_m: expected a number >= 0, got {params['margin_m']!r}")
    brake = _number(params, "brake_mps2", vehicle.service_decel_mps2)
    if brake > vehicle.emergency_decel_mps2:
        raise ValueError(
            f"brake_mps2: expected at most the emergency deceleration of {vehicle.name} "
            f"({vehicle.emergency_decel_mps2}), got {brake}"
        )
    return _Constant(-brake)


for _name, _factory in (("_test_ctrl", make_ctrl), ("_test_follow", make_follow)):
    if _name not in registered():
        register(_name)(_factory)
