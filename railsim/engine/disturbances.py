"""Sensor and actuator faults of a scenario (``faults``), with their own random streams.

A scenario may disturb what the controllers see and what the actuators do: Gaussian noise on every train's
measured position and speed (``faults.sensor_noise``, drawn in :meth:`railsim.engine.control.ControlStage._situation`,
position then speed, train by train), Gaussian noise on the applied command (``faults.actuator_noise``, every train
or a listed few) and injected biases (``faults.actuator_bias``: a train's actuator adds a constant acceleration over
a time window). Each stream is seeded from the run's generator in a fixed order (sensor, then actuator), so a seed
gives the same disturbances whatever else the run draws. A train whose actuator is disturbed is never stepped by
the compiled line step (its command must pass through the noise and the biases).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass
class Disturbances:
    """Sensor and actuator faults of the scenario, with their own random streams."""

    position_sd_m: float
    speed_sd_mps: float
    noise_rng: np.random.Generator
    actuator_sd_mps2: float
    actuator_rng: np.random.Generator
    actuator_trains: Any  # None = every train
    biases: tuple[Any, ...]  # scenario faults.actuator_bias

    @classmethod
    def from_faults(cls, faults: Any, rng: np.random.Generator) -> Disturbances:
        """The scenario's ``faults`` (sensor noise, actuator noise and bias); the sensor then the actuator stream
        are seeded from ``rng``."""
        noise_rng = np.random.default_rng(rng.integers(2**63))
        actuator_rng = np.random.default_rng(rng.integers(2**63))
        return cls(
            float(faults.sensor_noise.position_sd_m),
            float(faults.sensor_noise.speed_sd_mps),
            noise_rng,
            float(faults.actuator_noise.accel_sd_mps2),
            actuator_rng,
            faults.actuator_noise.trains,
            tuple(faults.actuator_bias),
        )

    def biased(self, t: float, train_id: str, u_mps2: float) -> float:
        """``u`` plus every injected actuator bias active for this train at ``t``."""
        for bias in self.biases:
            if bias.train == train_id and bias.from_s <= t < bias.until_s:
                u_mps2 += bias.accel_mps2
        return u_mps2
