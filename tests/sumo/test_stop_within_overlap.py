"""A stop a few metres before points or a single-track section: the train halts at its mark and asks for the
resource from there.

OSM nets put platforms close to the points. Here the platform at Mid ends 22 m before a node: the toe of a
diverge (first case) or the entry of a single-track section an opposing train holds (second case). The overlap is
20 m and the ATO stops 5 m before its authority end, so with the authority ending the overlap before the node the
train halted 2 m short of its mark: outside the 91 m platform's window for an 89.4 m train (front in the last 1.6
m), SUMO never registered the stop and the stall watchdog ended the run (exit 3). Now the authority reaches the
mark; the train halts there (stopping error < 0.1 m), dwells, and the switch or section is requested at the halt.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import read_csv, read_summary, run_railsim
from tests.sumo.test_external_net import _COMMON, _edge, _netconvert, _service, _write

GAP_M = 22.0  # platform end to the node
PLATFORM_M = 91.0  # cq3_6car is 89.4 m long


def _edge_length(net: Path, edge: str) -> float:
    import sumolib

    return float(sumolib.net.readNet(str(net)).getEdge(edge).getLength())


def _stop(sid: str, lane: str, start: float, end: float, name: str) -> str:
    return f'<trainStop id="{sid}" lane="{lane}" startPos="{start:.2f}" endPos="{end:.2f}" name="{name}"/>'


def build_points(folder: Path, gap_m: float = GAP_M) -> tuple[Path, Path]:
    """A 2 km approach to a diverge (main on, branch off) with Mid's platform ending ``gap_m`` before the points."""
    nodes = '<node id="A" x="0" y="0"/>\n<node id="J" x="2000" y="0"/>\n<node id="B" x="4000" y="0"/>\n'
    nodes += '<node id="C" x="3800" y="600"/>'
    edges = [_edge("AJ", "A", "J"), _edge("JB", "J", "B"), _edge("JC", "J", "C", 16.0, shape="2000,0 2400,60 3800,600")]
    net = _netconvert(folder, "pts", nodes, "\n".join(edges))
    end = _edge_length(net, "AJ") - gap_m
    rows = [
        _stop("a", "AJ_0", 100, 400, "Alpha"),
        _stop("m", "AJ_0", end - PLATFORM_M, end, "Mid"),
        _stop("b", "JB_0", 1500, 1800, "Bravo"),
    ]
    return net, _write(folder, "pts.add.xml", "<additional>\n" + "\n".join(rows) + "\n</additional>")


def build_single_track(folder: Path) -> tuple[Path, Path]:
    """Double track Alpha–J, single (bidi) track J–Bravo; Mid's eastbound platform ends GAP_M before J."""
    nodes = '<node id="A" x="0" y="0"/>\n<node id="J" x="2000" y="0"/>\n<node id="B" x="4000" y="0"/>'
    edges = [
        _edge("AJ", "A", "J", spread="right"),
        _edge("JA", "J", "A", spread="right"),
        _edge("JB", "J", "B"),
        _edge("-JB", "B", "J"),
    ]
    net = _netconvert(folder, "st", nodes, "\n".join(edges))
    end = _edge_length(net, "AJ") - GAP_M
    rows = [
        _stop("a", "AJ_0", 100, 400, "Alpha"),
        _stop("m", "AJ_0", end - PLATFORM_M, end, "Mid"),
        _stop("b", "JB_0", 1500, 1800, "Bravo"),
        _stop("bw", "-JB_0", 100, 400, "Bravo"),
        _stop("mw", "JA_0", 100, 300, "Mid"),
        _stop("aw", "JA_0", 1600, 1900, "Alpha"),
    ]
    return net, _write(folder, "st.add.xml", "<additional>\n" + "\n".join(rows) + "\n</additional>")


def _run(folder: Path, net: Path, stops: Path, services: list[dict]) -> tuple[Path, dict]:
    raw = {"name": "overlap", "world": {"net": str(net), "additional": [str(stops)]}, **_COMMON, "services": services}
    scn = _write(folder, "overlap.yaml", yaml.safe_dump(raw, sort_keys=False))
    out = folder / "out"
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], cache_dir=folder / "c", timeout=600)
    assert res.returncode == 0, res.stderr + res.stdout
    return out, read_summary(out)


def test_stop_22_m_before_points_is_reached(tmp_path: Path) -> None:
    net, stops = build_points(tmp_path)
    out, s = _run(tmp_path, net, stops, [_service("s", "alpha", "bravo", 0)])
    assert s["n_arrived"] == 1 and s["n_stops_missed"] == 0 and s["max_stopping_error_m"] < 0.1
    events = read_csv(out / "events.csv")
    halted = next(float(e["t_s"]) for e in events if e["kind"] == "stop_registered" and "mid" in e["detail"])
    requested = next(float(e["t_s"]) for e in events if e["kind"] == "lock_requested")
    assert requested >= halted  # the points are asked for at the halt, not on the approach
    assert s["switch_violations"] == 0 and s["collisions"] == 0


def test_stop_22_m_before_a_held_single_track_is_reached(tmp_path: Path) -> None:
    net, stops = build_single_track(tmp_path)
    out, s = _run(tmp_path, net, stops, [_service("e", "alpha", "bravo", 0), _service("w", "bw", "aw", 60)])
    assert s["n_arrived"] == 2 and s["n_stops_missed"] == 0 and s["max_stopping_error_m"] < 0.1
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0
    events = read_csv(out / "events.csv")
    halted = next(float(e["t_s"]) for e in events if e["kind"] == "stop_registered" and "e.000" == e["subject"])
    asked = next(float(e["t_s"]) for e in events if e["kind"] == "section_requested" and "e.000" in e["detail"])
    released = next(float(e["t_s"]) for e in events if e["kind"] == "section_released" and "w.000" in e["detail"])
    assert halted <= asked < released  # it stood at Mid while the westbound train held the single track


def build_two_stops_before_merge(folder: Path) -> tuple[Path, Path]:
    """Double track Alpha–J; at J a branch from C joins and the single (bidi) track to Bravo begins: J is a merge
    and the entry of a single-track section. Two eastbound platforms lie one behind the other before J: Near ends
    GAP_M before J, Far ends 10 m before Near begins."""
    nodes = '<node id="A" x="0" y="0"/>\n<node id="J" x="2000" y="0"/>\n<node id="B" x="4000" y="0"/>\n'
    nodes += '<node id="C" x="200" y="600"/>'
    edges = [
        _edge("AJ", "A", "J", spread="right"),
        _edge("JA", "J", "A", spread="right"),
        _edge("JB", "J", "B"),
        _edge("-JB", "B", "J"),
        _edge("CJ", "C", "J", 16.0, shape="200,600 1600,60 2000,0"),
    ]
    net = _netconvert(folder, "mrg", nodes, "\n".join(edges))
    end = _edge_length(net, "AJ") - GAP_M
    rows = [
        _stop("a", "AJ_0", 100, 400, "Alpha"),
        _stop("f", "AJ_0", end - 2 * PLATFORM_M - 10, end - PLATFORM_M - 10, "Far"),
        _stop("n", "AJ_0", end - PLATFORM_M, end, "Near"),
        _stop("b", "JB_0", 1500, 1800, "Bravo"),
        _stop("bw", "-JB_0", 100, 400, "Bravo"),
        _stop("aw", "JA_0", 1600, 1900, "Alpha"),
    ]
    return net, _write(folder, "mrg.add.xml", "<additional>\n" + "\n".join(rows) + "\n</additional>")


def test_a_train_leaves_a_platform_for_the_next_one_within_the_merge_margin(tmp_path: Path) -> None:
    """Leaving Far, the train needs an authority reaching Near. Near lies within the margin kept before the
    merge at J, and the merge is asked for only with the single-track section behind it, at Near: the authority
    ended at the margin, short of Near, and the train stood at Far until the stall watchdog ended the run
    (Potsdam, Platz der Einheit/Bildungsforum). The authority of a train standing at a platform reaches the
    next platform's mark when that lies before the resource, as it does for the platform it runs to."""
    net, stops = build_two_stops_before_merge(tmp_path)
    services = [_service("e", "alpha", "bravo", 0, via=["far", "near"]), _service("w", "bw", "aw", 900)]
    out, s = _run(tmp_path, net, stops, services)
    assert s["n_arrived"] == 2 and s["n_stops_missed"] == 0 and s["max_stopping_error_m"] < 0.1
    assert s["switch_violations"] == 0 and s["collisions"] == 0 and s["sumo_collisions"] == 0


def test_a_halt_just_past_a_platform_ending_at_a_junction_is_served(tmp_path: Path) -> None:
    """Mid's platform ends where its edge ends, at the points. A faulty actuator (+0.42 m/s² while the train
    brakes into Mid) makes the train halt 1.36 m past its mark: 0.36 m past the platform end, within the 0.5 m
    missed-stop tolerance, its front on the junction. SUMO never registers that trainStop, the engine did not
    count the stop missed, and the train stood there until the stall watchdog ended the run (exit 3; Potsdam,
    Platz der Einheit/West). Now the engine registers the halt: served, the overrun recorded, the dwell kept."""
    net, stops = build_points(tmp_path, gap_m=0.0)
    faults = dict(_COMMON["faults"])
    faults["actuator_bias"] = [{"train": "s.000", "accel_mps2": 0.42, "from_s": 103, "until_s": 108}]
    raw = {"name": "overrun", "world": {"net": str(net), "additional": [str(stops)]}, **_COMMON, "faults": faults}
    raw["services"] = [_service("s", "alpha", "bravo", 0)]
    scn = _write(tmp_path, "overrun.yaml", yaml.safe_dump(raw, sort_keys=False))
    out = tmp_path / "out"
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], cache_dir=tmp_path / "c", timeout=600)
    assert res.returncode == 0, res.stderr + res.stdout
    s = read_summary(out)
    assert s["n_arrived"] == 1 and s["n_stops_served"] == s["n_stops_scheduled"] == 2 and s["n_stops_missed"] == 0
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0 and s["switch_violations"] == 0
    events = read_csv(out / "events.csv")
    overrun = [e for e in events if e["kind"] == "stop_overrun_served"]
    assert len(overrun) == 1 and "mid" in overrun[0]["detail"]
    mid = next(r for r in read_csv(out / "stops.csv") if r["station"] == "mid")
    assert 1.0 < float(mid["stopping_error_m"]) <= 1.5 and float(mid["dwell_s"]) >= 30.0  # its dwell, kept
