"""Physical constants and unit conversions used across railsim (one definition each).

Inside railsim everything is SI; km/h appear only at the YAML edge and are converted on load.
"""

from __future__ import annotations

G_MPS2 = 9.81  # gravitational acceleration [m/s²]
KMH_PER_MPS = 3.6  # 1 m/s = 3.6 km/h


def kmh_to_mps(speed_kmh: float) -> float:
    """Speed in km/h → m/s."""
    return speed_kmh / KMH_PER_MPS
