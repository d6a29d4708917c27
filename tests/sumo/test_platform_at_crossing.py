"""A tram stopping at a platform that ends at a flat crossing another movement holds keeps its front out of it.

The tram line runs W-X-Y-E; a north-south line crosses it at grade at X, and a branch leaves it at Y, 85 m past
X. Pee's platform ends at X. A tram stands behind a tram dwelling at Pee (its separation controller keeps the
margin behind it); that tram leaves for the branch, and the tram behind accelerates after it until it turns off
at Y: the ATO takes over 36 m before Pee's mark at 6.4 m/s with the actuator still accelerating, as at Potsdam's
Platz der Einheit/West, where a tram halted 1.12 m past its mark, 0.12 m past the platform end, inside crossing
``1137879547`` while the other movement held it (a collision counted by railsim). Here a north-south tram holds
the crossing meanwhile. With the authority carried to the mark (1 m before the crossing) plus the ATO's margin,
the tram ran 0.5 m past its mark, halted under an emergency brake 0.48 m short of the crossing and missed its
stop. The authority carried to a stop now keeps the ATO's aim ``STOP_OVERRUN_ALLOWANCE_M`` (1.5 m) before a
resource the train does not hold: it brakes in time and serves the stop."""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import read_csv, read_summary, run_railsim
from tests.sumo.test_external_net import _COMMON, _edge, _netconvert, _write
from tests.sumo.test_stop_within_overlap import _edge_length, _stop

TRAM = {"preset": "cq3_6car", "length_m": 27.0, "max_speed_kmh": 70.0}
BRANCH_M = 85.0  # Y lies this far past X: the tram in front leaves the route when the one behind is 36 m from Pee


def build(folder: Path) -> tuple[Path, Path, float]:
    """The net, its stops and where Pee's platform (and the crossing at X) begins on the tram's route."""
    y = 1000.0 + BRANCH_M
    nodes = '<node id="W" x="0" y="0"/>\n<node id="X" x="1000" y="0"/>\n<node id="E" x="2500" y="0"/>\n'
    nodes += f'<node id="Y" x="{y}" y="0"/>\n<node id="B" x="{y + 600}" y="-600"/>\n'
    nodes += '<node id="N" x="1000" y="800"/>\n<node id="S" x="1000" y="-800"/>'
    edges = [_edge("WX", "W", "X"), _edge("XY", "X", "Y"), _edge("YE", "Y", "E"), _edge("YB", "Y", "B")]
    edges += [_edge("NX", "N", "X"), _edge("XS", "X", "S")]
    net = _netconvert(folder, "pxc", nodes, "\n".join(edges))
    end = _edge_length(net, "WX")
    rows = [
        _stop("a", "WX_0", 100, 200, "Alpha"),
        _stop("p", "WX_0", end - 60, end, "Pee"),
        _stop("e", "YE_0", 800, 900, "East"),
        _stop("b", "YB_0", 500, 600, "Branch"),
        _stop("n", "NX_0", 100, 200, "North"),
        _stop("s", "XS_0", 600, 700, "South"),
    ]
    return net, _write(folder, "pxc.add.xml", "<additional>\n" + "\n".join(rows) + "\n</additional>"), end


def _service(sid: str, a: str, b: str, times: list[float], dwell_s: float, **extra: object) -> dict:
    return {
        "id": sid,
        "from": a,
        "to": b,
        "vehicle": "tram",
        "departures": {"times": times},
        "dwell_s": dwell_s,
        **extra,
    }


def test_a_tram_handed_to_its_ato_close_before_a_platform_at_a_held_crossing_serves_it_short_of_the_crossing(
    tmp_path: Path,
) -> None:
    net, stops, crossing_m = build(tmp_path)
    services = [
        _service("lead", "alpha", "branch", [0], 60, via=["pee"]),
        _service("follow", "alpha", "east", [40], 20, via=["pee"]),
        _service("cross", "north", "south", [60, 90, 120, 150], 20),
    ]
    raw = {
        "name": "pxc",
        "world": {"net": str(net), "additional": [str(stops)]},
        **_COMMON,
        "vehicles": {"tram": TRAM},
        "services": services,
    }
    scn = _write(tmp_path, "pxc.yaml", yaml.safe_dump(raw, sort_keys=False))
    out = tmp_path / "out"
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], cache_dir=tmp_path / "c", timeout=600)
    assert res.returncode == 0, res.stderr + res.stdout
    s = read_summary(out)
    assert (s["n_arrived"], s["n_stops_missed"]) == (6, 0)
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0 and s["switch_violations"] == 0
    events = read_csv(out / "events.csv")
    # the dangerous moment happened: the north-south tram held the crossing while the tram came in to Pee
    held = [(float(e["t_s"]), e["kind"]) for e in events if e["subject"] == "crossing:X" and "cross.000" in e["detail"]]
    start_s = next(t for t, kind in held if kind == "section_reserved")
    end_s = next(t for t, kind in held if kind == "section_released")
    trace = [r for r in read_csv(out / "trace.csv") if r["train"] == "follow.000"]
    while_held = [r for r in trace if start_s <= float(r["t_s"]) <= end_s]
    assert any(float(r["chainage_m"]) > crossing_m - 3.0 for r in while_held), "it never came up to the crossing"
    inside = [r for r in while_held if float(r["chainage_m"]) > crossing_m]
    assert inside == [], f"front inside the crossing another tram held: {inside[:1]}"
    braked = [e for e in events if e["kind"] == "emergency_brake_on" and e["subject"] == "follow.000"]
    assert braked == [], "the tram needed its emergency brake to stay out of the crossing"
