"""The scenarios that come with railsim, found from any working directory.

The YAML files of ``scenarios/`` sit next to the ``railsim`` package in the source tree (the editable install
``make venv`` makes), so a notebook or script started elsewhere names them without a path::

    from railsim import scenario
    scn = scenario.load(scenario.shipped("chongqing_line3_peak"))

A name that is not shipped is a :class:`railsim.errors.ConfigError` listing the names that are.
"""

from __future__ import annotations

from pathlib import Path

from railsim.errors import ConfigError

SCENARIOS_DIR = Path(__file__).resolve().parents[2] / "scenarios"


def shipped_names() -> list[str]:
    """The names (file stems) of the shipped scenarios, sorted."""
    return sorted(p.stem for p in SCENARIOS_DIR.glob("*.yaml"))


def shipped(name: str) -> Path:
    """The path of the shipped scenario ``name`` (``"chongqing_line3_peak"``, with or without ``.yaml``)."""
    path = SCENARIOS_DIR / (name if name.endswith(".yaml") else f"{name}.yaml")
    if not path.is_file():
        names = ", ".join(shipped_names()) or f"none: no folder {SCENARIOS_DIR}"
        raise ConfigError(name, None, f"not a shipped scenario; shipped: {names}")
    return path
