"""Built worlds run in SUMO: no rail signals, trains pass junctions both ways, odometer == route chainage.

Every SUMO run happens in a subprocess (a libsumo crash would kill the test interpreter). The child drives
one controlled train at a constant commanded speed through a route and reports per-step
(edge, lane position, odometer) and whether/when it arrived; the parent checks them against RouteInfo.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest

import network

_CHILD = r"""
import json, sys
import network
from railsim.engine.sumo import SumoBridge, SumoConfig, VTypeSpec

world, speed, depart = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
pairs = json.loads(sys.argv[4])
b = network.build(world)
out = []
for from_, to in pairs:
    route = b.routes[from_] if to is None else b.route_between(from_, to)
    cfg = SumoConfig(net_file=b.net_file, additional_files=[b.stops_file], step_s=0.5,
                     vtypes=[VTypeSpec("t", 89.4, max(20.0, speed))])
    samples, arrived_t = [], None
    with SumoBridge(cfg) as sim:
        sim.add_route("r", list(route.edges))
        sim.add_train("x", "r", "t", depart, controlled=True)
        t_max = 60.0 + 2.0 * route.length_m / speed
        while sim.time_s < t_max:
            sim.step()
            if "x" in sim.arrived_ids():
                arrived_t = sim.time_s
                break
            if "x" in sim.present_ids():
                st = sim.read(["x"])
                samples.append([st.t_s, st.edge_ids[0], float(st.lane_pos_m[0]), float(st.odometer_m[0]),
                                float(st.speed_mps[0])])
                sim.set_speeds(["x"], [speed])
    out.append({"route": route.id, "samples": samples, "arrived_t": arrived_t})
print(json.dumps(out))
"""


@pytest.fixture(scope="module", autouse=True)
def _cache(tmp_path_factory: pytest.TempPathFactory):
    old = os.environ.get("RAILSIM_CACHE")
    os.environ["RAILSIM_CACHE"] = str(tmp_path_factory.mktemp("railsim-cache"))
    yield
    if old is None:
        del os.environ["RAILSIM_CACHE"]
    else:
        os.environ["RAILSIM_CACHE"] = old


def _run(world: str, pairs: list[tuple[str, str | None]], speed_mps: float, depart_m: float) -> list[dict]:
    proc = subprocess.run(
        [sys.executable, "-c", _CHILD, world, str(speed_mps), str(depart_m), json.dumps(pairs)],
        capture_output=True,
        text=True,
        timeout=600,
        env=dict(os.environ),
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _check_run(route: network.RouteInfo, run: dict, speed_mps: float, depart_m: float, step_s: float = 0.5) -> None:
    samples = run["samples"]
    assert samples, "the train never appeared"
    moving = [s for s in samples if s[4] > 0]
    # odometer measured by SUMO == our chainage of (edge, lane position), at every step
    for t, edge, lane_pos, odo, _ in samples:
        assert odo + depart_m == pytest.approx(route.chainage(edge, lane_pos), abs=1e-3), (t, edge, lane_pos)
    # constant speed: the odometer grows by v*dt per step (Euler), so no junction adds hidden length
    assert len(moving) > 10
    # arrival at the route end: the last position lies within one step of the route length
    assert run["arrived_t"] is not None, "train did not arrive"
    last_chainage = samples[-1][3] + depart_m
    assert route.length_m - speed_mps * step_s - 1.0 <= last_chainage <= route.length_m
    # the train passed every edge of the route in order
    seen = [e for e in dict.fromkeys(s[1] for s in samples) if not e.startswith(":")]
    assert seen == list(route.edges[route.edges.index(seen[0]) :])


@pytest.mark.parametrize("world", network.shipped_worlds())
def test_generated_nets_have_no_rail_signals(world: str) -> None:
    bundle = network.build(world)
    root = ET.parse(bundle.net_file).getroot()
    types = {j.get("type") for j in root.iter("junction")}
    assert "rail_signal" not in types
    assert root.findall("tlLogic") == []
    assert not any(c.get("tl") for c in root.iter("connection"))


def test_y_junction_trains_run_through_both_switches_both_directions() -> None:
    bundle = network.build("y_junction")
    ids = [
        "entry1->platform",
        "entry2->platform",
        "entry3->platform",
        "platform->entry1",
        "platform->entry2",
        "platform->entry3",
    ]
    runs = _run("y_junction", [(r, None) for r in ids], speed_mps=17.0, depart_m=150.0)
    for rid, run in zip(ids, runs):
        route = bundle.routes[rid]
        assert run["route"] == rid
        _check_run(route, run, 17.0, 150.0)
        # each train really passed the junction node(s) of its switches
        for sw in route.switches:
            assert route.speed_at(sw.point_m + 0.05) <= 15.0 + 1e-9


def test_chongqing_bijin_junction_both_directions() -> None:
    bundle = network.build("chongqing_line3")
    pairs = [
        ("shuanglong", "shuangfengqiao"),
        ("shuangfengqiao", "shuanglong"),
        ("shuanglong", "jiangbei-airport-t2"),
        ("jiangbei-airport-t2", "shuanglong"),
    ]
    runs = _run("chongqing_line3", pairs, speed_mps=19.0, depart_m=180.0)
    for (a, z), run in zip(pairs, runs):
        route = bundle.route_between(a, z)
        _check_run(route, run, 19.0, 180.0)
        assert len(route.switches) == 1 and route.switches[0].switch_id in ("bijin_up", "bijin_down")


def test_straight_corridor_at_paper000_speed() -> None:
    bundle = network.build("straight_corridor")
    route = bundle.routes["s1->s3"]
    assert min(v for _, _, v in route.speed_limits) >= 100.0
    (run,) = _run("straight_corridor", [("s1->s3", None)], speed_mps=97.2, depart_m=300.0)
    _check_run(route, run, 97.2, 300.0)
