"""A double-track junction crosses the opposite track at grade: the interlocking holds the crossing.

At a generated junction (``mini_y``'s branch at km 3.6, like Bijin on Line 3) all four tracks meet in one
SUMO node. The branch lies on the left of up trains, so an up train turning onto the branch crosses the main
*down* track inside that node: SUMO's foe matrix marks the two internal lanes as foes and SUMO reports a
junction collision when two trains overlap there. The two switches of the junction (``c_up``, ``c_down``) do
not protect it: each train locks only its own. The generator therefore lists such foe movements as a flat
crossing (``graph.graph["crossings"]``, :func:`network.topology.flat_crossings`), and the engine holds it as a
one-movement-at-a-time resource (:func:`railsim.engine.single_track.route_crossings`).

The SUMO cases time an up train to the branch (B -> G) and a down train on the main line (E -> A) to meet on
the crossing: with the crossing interlocked, the up train waits for it and nothing collides; with the crossing
taken out of the interlocking (the engine before this fix), SUMO reports the junction collision and the
summary counts it.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from tests.helpers import DATA, read_csv, read_summary, run_python, run_railsim

UP_MOVE = ("main_up_2", "br_up_0")  # up trunk -> branch (diverging at c_up)
DOWN_MOVE = ("main_down_3", "main_down_2")  # down main line through the junction (normal leg of c_down)
JUNCTION_NODE = "main_n3"  # both switches' point, where the four tracks meet
UP_DEPARTS_S = 28.0  # measured: the two fronts then reach the junction node 2 s apart (195.5 s and 193.5 s)


def test_the_generated_junction_is_a_flat_crossing(tmp_path: Path) -> None:
    from network.build import build
    from network.generator import generate
    from network.line import load_description
    from railsim.engine.single_track import route_crossings

    fresh = generate(load_description(DATA / "lines" / "mini_y.yaml")[0], tmp_path / "g")
    cached = build(DATA / "lines" / "mini_y.yaml")  # what a run uses: read back from the topology JSON
    node = fresh.switches["c_up"].sumo_node
    assert node == JUNCTION_NODE
    for bundle in (fresh, cached):
        crossings = bundle.graph.graph["crossings"]
        assert crossings == {node: {UP_MOVE: [DOWN_MOVE], DOWN_MOVE: [UP_MOVE]}}
        # the same node is both switches' point: diverge and merge share track, so they are not crossings
        assert bundle.switches["c_down"].sumo_node == node
        up = route_crossings(bundle.route_between("b", "g"), bundle.graph)
        down = route_crossings(bundle.route_between("e", "a"), bundle.graph)
        assert [x.section_id for x in up] == [x.section_id for x in down] == [f"crossing:{node}"]
        assert up[0].direction != down[0].direction  # different movements: one at a time
        (sw,) = [s for s in bundle.route_between("b", "g").switches if s.switch_id == "c_up"]
        assert up[0].guard_m == sw.point_m  # locked before the switch behind it (locking.py's order)
        # the main line straight through crosses nothing
        assert route_crossings(bundle.route_between("a", "e"), bundle.graph) == []
    topo = json.loads(fresh.topology_file.read_text(encoding="utf-8"))
    assert topo["graph"]["graph"]["crossings"] == {node: [[*UP_MOVE, [list(DOWN_MOVE)]], [*DOWN_MOVE, [list(UP_MOVE)]]]}


def _scenario(folder: Path) -> Path:
    raw = yaml.safe_load((DATA / "scenarios" / "mini_line.yaml").read_text(encoding="utf-8"))
    raw["world"] = {"line": str(DATA / "lines" / "mini_y.yaml")}
    raw["services"] = [
        {"id": "up", "from": "b", "to": "g", "vehicle": "cq6", "departures": {"times": [UP_DEPARTS_S]}, "dwell_s": 20},
        {"id": "down", "from": "e", "to": "a", "vehicle": "cq6", "departures": {"times": [0]}, "dwell_s": 20},
    ]
    raw["formations"] = []
    raw["simulation"]["duration_s"] = 900
    folder.mkdir(parents=True, exist_ok=True)
    scn = folder / "scenario.yaml"
    scn.write_text(yaml.safe_dump(raw, sort_keys=False), encoding="utf-8")
    return scn


def _events(out: Path) -> list[dict[str, Any]]:
    return [{**e, "detail": yaml.safe_load(e["detail"]) if e["detail"] else {}} for e in read_csv(out / "events.csv")]


def test_trains_timed_to_meet_on_the_crossing_take_turns(tmp_path: Path) -> None:
    scn = _scenario(tmp_path)
    out = tmp_path / "out"
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], timeout=600)
    assert res.returncode == 0, res.stderr + res.stdout
    s = read_summary(out)
    assert s["n_arrived"] == 2 and s["collisions"] == 0 and s["sumo_collisions"] == 0 and s["switch_violations"] == 0
    events = _events(out)
    crossing = [e for e in events if e["subject"].startswith("crossing:")]
    kinds = [(e["kind"], e["detail"]["trains"][0]) for e in crossing]
    assert kinds == [
        ("section_requested", "down.000"),
        ("section_reserved", "down.000"),
        ("section_requested", "up.000"),
        ("section_released", "down.000"),
        ("section_reserved", "up.000"),
        ("section_released", "up.000"),
    ]
    t = {(k, tr): float(e["t_s"]) for e, (k, tr) in zip(crossing, kinds)}
    # it really waited: from its request (SECTION_REQUEST_LEAD_S before leaving its stop) until the down train
    # released the crossing, and it got the crossing the moment the down train let go of it
    assert t[("section_reserved", "up.000")] == t[("section_released", "down.000")]
    assert t[("section_reserved", "up.000")] - t[("section_requested", "up.000")] > 30.0
    # the up train asks for its switch only once it holds the crossing (crossing first, then the points)
    (c_up,) = [e for e in events if e["kind"] == "lock_requested" and e["subject"] == "c_up"]
    assert float(c_up["t_s"]) >= t[("section_reserved", "up.000")]


def test_without_the_crossing_lock_sumo_sees_the_collision_and_the_summary_counts_it(tmp_path: Path) -> None:
    """The engine before the fix (no crossing resource): the two trains meet inside the junction node."""
    scn = _scenario(tmp_path)
    out = tmp_path / "out"
    code = (
        "import sys\n"
        "import railsim.engine.section_requests as section_requests\n"
        "section_requests.route_crossings = lambda route, graph: []  # the crossing is not interlocked\n"
        "from railsim.cli.main import main\n"
        f"sys.exit(main(['run', {str(scn)!r}, '--out', {str(out)!r}, '--no-progress']))\n"
    )
    res = run_python(code, timeout=600, reference=True)  # a patched module function: the interpreted modules
    assert res.returncode != 0  # a collision is a failed run
    s = read_summary(out)
    assert s["sumo_collisions"] >= 1 and s["collisions"] >= s["sumo_collisions"]
    events = _events(out)
    (hit,) = [e for e in events if e["kind"] == "sumo_collision"]
    assert {hit["subject"], hit["detail"]["victim"]} == {"up.000", "down.000"} and hit["detail"]["type"] == "junction"
    # railsim's own truth check sees it too (both bodies span the crossing node on foe movements), no later
    (own,) = [e for e in events if e["kind"] == "collision"]
    assert {own["subject"], own["detail"]["leader"]} == {"up.000", "down.000"}
    assert own["detail"]["crossing"] == JUNCTION_NODE and float(own["t_s"]) <= float(hit["t_s"])
    assert s["collisions_railsim"] == 1 and s["collisions"] == s["collisions_railsim"] + s["sumo_collisions"]
    assert not any(e["subject"].startswith("crossing:") for e in events)
