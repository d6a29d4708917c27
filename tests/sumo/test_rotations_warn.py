"""``rotations: auto`` says where no unit can turn, instead of silently running one unit per trip.

The net (built here with netconvert) is a plain double-track line Alpha–Bravo: one one-way edge per track and
direction, no bidi edge, so there is no turnaround anywhere (both termini are dead ends). With rotations on, every
trip needs its own unit; the run says so with one warning line per terminus, naming it and the reason. Before, the
run was silent (0 turnbacks, as many units as trips, found only in ``summary.json``'s ``fleet``).

A second net, two parallel bidi tracks with a platform on each, has turnarounds at both ends but no crossover:
a unit arriving eastbound on the south track cannot reach the westbound platform on the north track. The warning
names that reason (different tracks, no turnaround between them).
"""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import read_summary, run_railsim
from tests.sumo.test_double_bidi_track import build_double_bidi
from tests.sumo.test_external_net import _COMMON, _edge, _netconvert, _service, _write


def build_dead_ends(folder: Path) -> tuple[Path, Path]:
    nodes = '<node id="A" x="0" y="0"/>\n<node id="B" x="3000" y="0"/>'
    edges = [_edge("AB", "A", "B", spread="right"), _edge("BA", "B", "A", spread="right")]
    net = _netconvert(folder, "dead", nodes, "\n".join(edges))
    rows = [
        '<trainStop id="a_e" lane="AB_0" startPos="100" endPos="400" name="Alpha"/>',
        '<trainStop id="b_e" lane="AB_0" startPos="2600" endPos="2900" name="Bravo"/>',
        '<trainStop id="b_w" lane="BA_0" startPos="100" endPos="400" name="Bravo"/>',
        '<trainStop id="a_w" lane="BA_0" startPos="2600" endPos="2900" name="Alpha"/>',
    ]
    return net, _write(folder, "dead.add.xml", "<additional>\n" + "\n".join(rows) + "\n</additional>")


def _run(folder: Path, net: Path, stops: Path, ends: tuple[str, str] = ("alpha", "bravo")) -> tuple[dict, list[str]]:
    raw = {"name": "rot", "world": {"net": str(net), "additional": [str(stops)]}, **_COMMON}
    raw["simulation"] = {**_COMMON["simulation"], "duration_s": 1500}
    raw["services"] = [
        {**_service("east", ends[0], ends[1], 0), "departures": {"times": [0, 600]}},
        {**_service("west", ends[1], ends[0], 300), "departures": {"times": [300, 900]}},
    ]
    raw["rotations"] = {"units": "auto", "turnback_min_s": 60}
    scn = _write(folder, "rot.yaml", yaml.safe_dump(raw, sort_keys=False))
    out = folder / "out"
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], cache_dir=folder / "c", timeout=600)
    assert res.returncode == 0, res.stderr + res.stdout
    lines = [ln for ln in res.stderr.splitlines() if "no unit can turn" in ln]
    return read_summary(out), lines


def test_dead_end_termini_are_named(tmp_path: Path) -> None:
    s, lines = _run(tmp_path, *build_dead_ends(tmp_path))
    assert s["n_arrived"] == 4 and s["fleet"]["units_used"] == 4
    assert len(lines) == 2, lines
    for station in ("alpha", "bravo"):
        (line,) = [ln for ln in lines if f"at {station}:" in ln]
        assert "dead end" in line and "no turnaround" in line, line


def test_platforms_on_tracks_without_a_way_between_are_named(tmp_path: Path) -> None:
    s, lines = _run(tmp_path, *build_double_bidi(tmp_path), ends=("aston", "bury"))
    assert s["n_arrived"] == 4 and s["fleet"]["units_used"] == 4
    assert len(lines) == 2, lines
    for line in lines:
        assert "different tracks" in line, line
