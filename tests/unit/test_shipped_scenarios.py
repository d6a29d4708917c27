"""Every scenario shipped in ``scenarios/`` validates against the schema and its world (``railsim validate``).

A user's first contact with railsim is running one of these files; a stale field or a renamed station must fail
here, not in front of them. (The SUMO runs of the important ones are in their own tests.)
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.helpers import ROOT

SCENARIOS = sorted((ROOT / "scenarios").glob("*.yaml"))


def test_there_are_shipped_scenarios() -> None:
    assert len(SCENARIOS) >= 10


SWEEPS = sorted(p for p in (ROOT / "scenarios" / "sweeps").glob("*.yaml") if "\nbase:" in "\n" + p.read_text())


@pytest.mark.parametrize("path", SWEEPS, ids=[p.stem for p in SWEEPS])
def test_shipped_sweep_validates(path: Path) -> None:
    """Every case of every shipped sweep file loads and passes the scenario schema (world ids: the scenarios above)."""
    from railsim.studies import sweep

    spec = sweep.load_sweep(path)
    assert spec.cases
    sweep.validate_cases(spec, world_check=False)


@pytest.mark.parametrize("regime", ["mb", "vc", "vc_together"])
def test_study_scenarios_are_the_peak_with_the_0730_0800_window(regime: str) -> None:
    """scenarios/studies/line3_peak_{mb,vc,vc_together}_0730_0800.yaml (the robustness study's, README) load, and
    differ from the shipped peak scenario only in name, description and the Airport services' last departure
    (and ``vc_together`` in its formations departing together)."""
    import yaml

    short = yaml.safe_load((ROOT / "scenarios" / "studies" / f"line3_peak_{regime}_0730_0800.yaml").read_text())
    full = yaml.safe_load((ROOT / "scenarios" / f"chongqing_line3_peak_{regime[:2]}.yaml").read_text())
    from railsim.scenario.loading import load

    load(ROOT / "scenarios" / "studies" / f"line3_peak_{regime}_0730_0800.yaml")
    if regime == "vc_together":
        assert all(f.pop("depart_together") is True for f in short["formations"])
    for k in (0, 1):
        assert short["services"][k]["departures"]["last"] == "08:00"
        short["services"][k]["departures"]["last"] = full["services"][k]["departures"]["last"]
    for key in ("name", "description"):
        short.pop(key), full.pop(key)
    assert short == full
