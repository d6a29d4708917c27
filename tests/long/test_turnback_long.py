"""Turnbacks and rotations in SUMO: a unit reverses and runs its next trip.

Here: the tests of it that take minutes; the others are in ``tests/sumo/test_turnback.py``.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.sumo.test_external_net import _COMMON, _write
from tests.sumo.test_turnback import build_tail_track


def _terminal_scenarios(folder: Path) -> dict[str, Path]:
    """Aston -> Bury every h, Bury -> Aston every h 300 s later, on the turnback-track net; with and without units."""
    net, stops = build_tail_track(folder)

    def svc(sid: str, a: str, b: str, first: float, last: float) -> dict:
        dep = {"first": first, "last": last, "headway_s": 120}
        return {"id": sid, "from": a, "to": b, "vehicle": "cq6", "departures": dep, "dwell_s": 30}

    out = {}
    for name, rotations in (("units", {"units": "auto", "turnback_min_s": 60}), ("trains", None)):
        raw = {
            "name": f"terminal_{name}",
            "world": {"net": str(net), "additional": [str(stops)]},
            **_COMMON,
            "services": [svc("out", "Aston", "Bury", 0, 1200), svc("back", "Bury", "Aston", 300, 1500)],
        }
        raw["simulation"] = {**raw["simulation"], "duration_s": 3600}  # type: ignore[dict-item]
        if rotations:
            raw["rotations"] = rotations
        out[name] = _write(folder, f"{name}.yaml", yaml.safe_dump(raw, sort_keys=False))
    return out


def test_min_headway_where_the_terminal_not_the_line_sets_it(tmp_path: Path) -> None:
    """The line (moving block, 3 km) runs every 40 s when each trip is its own train; when units must turn back
    through the one turnback track, the track's cycle (in, reverse, out) sets the headway: shorter headways pile up
    knock-on delay at the terminal."""
    from railsim.studies.headway import find_min_headway

    scns = _terminal_scenarios(tmp_path)
    paths = ["services[0].departures.headway_s", "services[1].departures.headway_s"]
    line = find_min_headway(scns["trains"], paths, 40, 100, tol_s=10, confirm_seeds=[], progress=False)
    assert line.min_headway_s == 40 and line.at_lower_bound
    terminal = find_min_headway(scns["units"], paths, 40, 100, tol_s=10, confirm_seeds=[], progress=False)
    assert terminal.min_headway_s is not None and terminal.min_headway_s >= 60
    worst = max((p for p in terminal.probes if not p.feasible), key=lambda p: p.headway_s)
    assert "delay" in worst.reason  # the knock-on through the turnback track, not a collision or a stall
