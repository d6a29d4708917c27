"""A flat crossing right before a single-track section is granted only to a train that holds that section.

East of X the line is single track (bidi), west of it double track; a north-south line crosses it at grade at
X. An eastbound train's platform ends at X, so it reserved the crossing on its approach and then stood at the
platform waiting for the single track, which a westbound train held; that train, at the end of the single
track, needed the crossing: neither could move (Potsdam, Platz der Einheit/West: the crossing
``crossing:1137879547`` and the single-track piece behind it). A train cannot stop between the crossing and the
section (no room for it there), so it asks for the crossing only once the section is its own."""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import read_csv, read_summary, run_railsim
from tests.sumo.test_external_net import _COMMON, _edge, _netconvert, _service, _write
from tests.sumo.test_stop_within_overlap import _edge_length, _stop


def build(folder: Path) -> tuple[Path, Path]:
    nodes = '<node id="W" x="0" y="0"/>\n<node id="X" x="1000" y="0"/>\n<node id="E" x="2000" y="0"/>\n'
    nodes += '<node id="N" x="1000" y="800"/>\n<node id="S" x="1000" y="-800"/>'
    edges = [
        _edge("WX", "W", "X", spread="right"),
        _edge("XW", "X", "W", spread="right"),
        _edge("XE", "X", "E"),
        _edge("-XE", "E", "X"),
        _edge("NX", "N", "X"),
        _edge("XS", "X", "S"),
    ]
    net = _netconvert(folder, "xst", nodes, "\n".join(edges))
    end = _edge_length(net, "WX")
    rows = [
        _stop("a", "WX_0", 100, 200, "Alpha"),
        _stop("p", "WX_0", end - 100, end, "Pee"),
        _stop("e", "XE_0", 800, 900, "East"),
        _stop("ew", "-XE_0", 100, 200, "East"),
        _stop("aw", "XW_0", 800, 900, "Alpha"),
    ]
    return net, _write(folder, "xst.add.xml", "<additional>\n" + "\n".join(rows) + "\n</additional>")


def test_a_train_at_a_platform_before_a_crossing_and_single_track_does_not_block_the_opposing_train(
    tmp_path: Path,
) -> None:
    net, stops = build(tmp_path)
    services = [_service("e", "alpha", "east", 0, via=["pee"]), _service("w", "ew", "aw", 0)]
    raw = {"name": "xst", "world": {"net": str(net), "additional": [str(stops)]}, **_COMMON, "services": services}
    scn = _write(tmp_path, "xst.yaml", yaml.safe_dump(raw, sort_keys=False))
    out = tmp_path / "out"
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], cache_dir=tmp_path / "c", timeout=600)
    assert res.returncode == 0, res.stderr + res.stdout
    s = read_summary(out)
    assert s["n_arrived"] == 2 and s["n_stops_missed"] == 0
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0 and s["switch_violations"] == 0
    events = read_csv(out / "events.csv")
    crossing = [e for e in events if e["kind"] == "section_reserved" and e["subject"].startswith("crossing:")]
    assert [("w.000" in e["detail"], "e.000" in e["detail"]) for e in crossing][:1] == [(True, False)]
