"""Controller factories keep the contract of :func:`controllers.base.register`: bad parameters raise ``ValueError``
(``"<param>: expected ..."``), never a ``TypeError`` or a railsim error, so the scenario loader can name the field.

These cases used to raise ``TypeError`` from a comparison or a hash of a wrongly typed value.
"""

from __future__ import annotations

from typing import Any

import pytest

import controllers
from railsim.physics.vehicle import preset, preset_names

VEHICLE = preset(preset_names()[0])


@pytest.mark.parametrize(
    "name, params, field",
    [
        ("cf_cacc", {"theta_preset": []}, "theta_preset"),
        ("mcf_dmpc", {"theta_preset": {}}, "theta_preset"),
        ("policy_separation", {"k_speed_per_s": "x"}, "k_speed_per_s"),
        ("speed_profile", {"segments": -1}, "segments"),
    ],
)
def test_bad_parameter_types_raise_value_error(name: str, params: dict[str, Any], field: str) -> None:
    with pytest.raises(ValueError, match=rf"^{field}: expected "):
        controllers.create(name, params, VEHICLE)
