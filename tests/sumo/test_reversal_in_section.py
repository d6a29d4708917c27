"""A unit that turns back inside a single-track section while a second train of its arrival direction is in it.

The line: 4 km of single track (``bidi`` edges, one section) from Aston to Bury, a platform at each end on the
bidi track and a station Mead 3.5 km out, short of Bury. Trams (27 m): ``out`` runs Aston–Bury and its unit
turns back at Bury's platform (it reverses where it stands) to run ``back`` to Aston; ``short`` leaves Aston
behind ``out``, holding the section the same way, and ends its trip at Mead, where its unit leaves service.

The unit at Bury cannot take the section over in its new direction while ``short`` still runs towards it, so
the section is handed over only once ``short`` has left it. The engine used to release it at the arrival and
the unit, already inside the section, ran off towards Aston under no reservation at all: a head-on collision
SUMO reported and railsim's own check (trains on one track in the same direction) did not see. Now a train
standing inside a section it does not hold has no movement authority, and no authority reaches into track a
train facing the other way stands on: ``back`` waits at Bury until ``short`` has arrived and left the line.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import read_csv, read_summary, run_railsim
from tests.sumo.test_external_net import _COMMON, _edge, _netconvert, _stops, _write

TRAM = {"preset": "cq3_6car", "length_m": 27.0, "max_speed_kmh": 70.0}


def build_stub_line(folder: Path) -> tuple[Path, Path]:
    """Aston –(2 km)– M –(2 km)– Bury, all one bidi section; Mead at 3.5 km (eastbound only)."""
    nodes = '<node id="A" x="0" y="0"/>\n<node id="M" x="2000" y="0"/>\n<node id="B" x="4000" y="0"/>'
    edges = [_edge("AM", "A", "M"), _edge("-AM", "M", "A"), _edge("MB", "M", "B"), _edge("-MB", "B", "M")]
    net = _netconvert(folder, "stub", nodes, "\n".join(edges))
    stops = _stops(
        folder,
        "stub",
        [
            ("a_out", "AM_0", 100, 160, "Aston"),
            ("m_in", "MB_0", 1500, 1560, "Mead"),
            ("b_in", "MB_0", 1900, 1960, "Bury"),
            ("b_out", "-MB_0", 40, 100, "Bury"),
            ("a_in", "-AM_0", 1840, 1900, "Aston"),
        ],
    )
    return net, stops


def _service(sid: str, a: str, b: str, t: float) -> dict:
    return {"id": sid, "from": a, "to": b, "vehicle": "tram", "departures": {"times": [t]}, "dwell_s": 20}


def test_a_unit_turning_inside_a_section_waits_for_the_train_behind_it(tmp_path: Path) -> None:
    net, stops = build_stub_line(tmp_path)
    raw = {
        "name": "stub_turn",
        "world": {"net": str(net), "additional": [str(stops)]},
        **_COMMON,
        "vehicles": {"tram": TRAM},
        "services": [
            _service("out", "Aston", "Bury", 0.0),
            _service("short", "Aston", "Mead", 150.0),
            _service("back", "Bury", "Aston", 300.0),
        ],
        "rotations": {"units": {"u1": ["out.000", "back.000"]}, "turnback_min_s": 30},
    }
    scn = _write(tmp_path, "stub.yaml", yaml.safe_dump(raw, sort_keys=False))
    out = tmp_path / "out"
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], cache_dir=tmp_path / "c", timeout=600)
    summary = read_summary(out)
    assert summary["sumo_collisions"] == 0 and summary["collisions"] == 0, summary
    assert res.returncode == 0, res.stderr[-2000:] + res.stdout[-2000:]
    assert summary["n_arrived"] == summary["n_trains"] == 3
    trips = {r["trip_id"]: r for r in read_csv(out / "trips.csv")}
    events = read_csv(out / "events.csv")
    # the unit took the section in its new direction only after ``short`` had arrived (and left the line)
    granted = [
        float(e["t_s"])
        for e in events
        if e["kind"] in ("section_reserved", "section_handed_over") and "back.000" in e["detail"]
    ]
    assert granted and min(granted) >= float(trips["short.000"]["arrival_s"])
    assert float(trips["back.000"]["departure_s"]) >= float(trips["short.000"]["arrival_s"])
