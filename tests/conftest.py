"""pytest configuration shared by the suite.

Hypothesis: no per-example deadline (a loaded 2-core machine makes timing deadlines flaky); under CI
(``CI=true``) examples are derandomized so a CI run is reproducible — local runs keep exploring.
"""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

settings.register_profile("local", deadline=None)
settings.register_profile("ci", deadline=None, derandomize=True, print_blob=True,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("ci" if os.environ.get("CI", "").lower() in ("1", "true", "yes") else "local")
