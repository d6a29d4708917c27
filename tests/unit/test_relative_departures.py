"""Relative departures (``departures: {after: ...}``) and ``pairs`` formations: dependent services re-time exactly.

What is pinned: trip ``k`` of a dependent service departs at ``t_i + phase·(t_{i+1} − t_i) + offset_s`` with
``i = first_trip + k·every`` for *every* headway of the reference (the study changes only the reference's
``headway_s``); trips before t = 0 are dropped; a ``pairs`` formation names each dependent trip with exactly the
reference trip it departs after; bad input names the file and field; and the shipped Line 3 twins differ only in
their formations.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from railsim import scenario
from railsim.errors import ConfigError

ROOT = Path(__file__).resolve().parents[2]
MINI = ROOT / "tests" / "data" / "scenarios" / "mini_line.yaml"


def _mini(after: dict[str, Any], pairs: bool = False) -> dict[str, Any]:
    raw = yaml.safe_load(MINI.read_text())
    raw["world"] = {"line": str((MINI.parent / raw["world"]["line"]).resolve())}
    for svc in raw["services"]:
        if svc["id"] == "main_up":
            svc["departures"] = {"first": 0, "last": 1200, "headway_s": 120}
        if svc["id"] == "br_up":
            svc["departures"] = {"after": after}
    raw["formations"] = (
        [{"id": "pair", "pairs": {"leader": "main_up", "follower": "br_up"}, "target_gap_m": 30}] if pairs else []
    )
    return raw


def _load(raw: dict[str, Any], overrides: dict[str, Any] | None = None) -> Any:
    from railsim.scenario.overrides import with_overrides

    return scenario.from_mapping(with_overrides(raw, overrides or {}), source="mini.yaml", base_dir=MINI.parent)


@pytest.mark.parametrize("headway_s", [60, 90, 120, 150, 240])
def test_dependent_service_is_retimed_exactly_at_every_headway(headway_s: int) -> None:
    raw = _mini({"service": "main_up", "every": 3, "first_trip": 1, "offset_s": 125, "phase": 0.5})
    scn = _load(raw, {"services[0].departures.headway_s": headway_s})
    ref = scn.service("main_up").departures_s
    dep = scn.service("br_up")
    n_ref = 1200 // headway_s + 1
    assert len(ref) == n_ref
    expected_refs = list(range(1, n_ref, 3))
    assert list(dep.departures_after.reference_trips) == expected_refs
    # integers throughout: the re-timing is exact, not approximately right
    expected = [
        i * headway_s + 0.5 * ((i + 1) * headway_s - i * headway_s if i + 1 < n_ref else headway_s) + 125
        for i in expected_refs
    ]
    assert list(dep.departures_s) == expected
    assert dep.trip_ids[0] == "br_up.000" and len(dep.trip_ids) == len(expected)
    # the phase to the reference trip is the same at every headway: half an interval plus the offset
    assert {t - ref[i] for t, i in zip(dep.departures_s, expected_refs)} == {0.5 * headway_s + 125}


def test_negative_offset_drops_trips_before_t0_and_keeps_the_references() -> None:
    scn = _load(_mini({"service": "main_up", "every": 2, "offset_s": -250}))
    dep = scn.service("br_up")
    # main_up departs 0, 120, ... 1200; every 2nd from trip 0: 0, 240, 480, ...; -250 drops trips 0 and 2
    assert dep.departures_after.reference_trips == (4, 6, 8, 10)
    assert dep.departures_s == (230.0, 470.0, 710.0, 950.0)


def test_pairs_formation_pairs_each_dependent_trip_with_its_reference() -> None:
    raw = _mini({"service": "main_up", "every": 4, "first_trip": 1, "offset_s": 125}, pairs=True)
    for h, refs in ((120, [1, 5, 9]), (240, [1, 5])):
        scn = _load(raw, {"services[0].departures.headway_s": h})
        assert [f.id for f in scn.formations] == [f"pair{k}" for k in range(len(refs))]
        assert [f.leader.trip for f in scn.formations] == refs
        assert [f.follower.trip for f in scn.formations] == list(range(len(refs)))
        assert all(f.leader.service == "main_up" and f.follower.service == "br_up" for f in scn.formations)
        # the resolved scenario lists the expanded formations and loads back to the same scenario
        again = scenario.loads(scenario.resolved_yaml(scn), "resolved.yaml", base_dir=MINI.parent)
        assert again == scn


@pytest.mark.parametrize(
    "after, field, needle",
    [
        ({"service": "main_upp"}, "services[1].departures.after.service", "did you mean"),
        ({"service": "br_down"}, "services[1].departures.after.service", "expected a service timetabled"),
        ({"service": "main_up", "every": 0}, "services[1].departures.after.every", "an integer >= 1"),
        ({"service": "main_up", "phase": 1.0}, "services[1].departures.after.phase", "in [0, 1)"),
        ({"service": "main_up", "first_trip": 99}, "services[1].departures.after.first_trip", "trip index"),
        ({"service": "main_up", "offset_s": -1e6}, "services[1].departures.after.offset_s", "before t = 0"),
        ({"service": "main_up", "offest_s": 3}, "services[1].departures.after", "offest_s"),
    ],
)
def test_bad_relative_departures_name_the_field(after: dict[str, Any], field: str, needle: str) -> None:
    raw = _mini(after)
    for svc in raw["services"]:  # a reference that is itself relative is refused too
        if svc["id"] == "br_down":
            svc["departures"] = {"after": {"service": "main_down"}}
    with pytest.raises(ConfigError) as err:
        _load(raw)
    text = str(err.value)
    assert text.startswith("mini.yaml: ") and field in text and needle in text, text


def test_pairs_needs_a_follower_timed_after_the_leader() -> None:
    raw = _mini({"service": "main_up"}, pairs=True)
    raw["formations"][0]["pairs"] = {"leader": "main_down", "follower": "br_up"}
    with pytest.raises(ConfigError, match=r"formations\[0\]\.pairs\.follower: expected a service whose departures"):
        _load(raw)


def test_line3_twins_differ_only_in_their_formations() -> None:
    mb = yaml.safe_load((ROOT / "scenarios" / "chongqing_line3_peak_mb.yaml").read_text())
    vc = yaml.safe_load((ROOT / "scenarios" / "chongqing_line3_peak_vc.yaml").read_text())
    for key in set(mb) | set(vc):
        if key not in ("name", "description", "formations"):
            assert mb.get(key) == vc.get(key), key
    assert mb["formations"] == [] and len(vc["formations"]) == 1
    # at the demo's 150 s the twins run the demo's Jurenba up timetable: every 4th Airport unit's Liugongli departure
    scn = scenario.load(ROOT / "scenarios" / "chongqing_line3_peak_vc.yaml")
    assert [f.leader.trip for f in scn.formations] == [0, 4, 8, 12, 16, 20, 24]
    assert scn.service("jurenba_up").departures_s == tuple(600.0 * k + 1659.5 for k in range(7))
