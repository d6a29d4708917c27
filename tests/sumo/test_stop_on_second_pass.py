"""A stop meant for the second pass of its edge is made there, not on the first pass.

A unit's turnback path at Jena's Winzerla starts on the departure platform's edge, runs out along the line to a
reversal and comes back round onto the same edge: SUMO matched the origin stop to the first pass (the edge the
unit stood on), so when the unit came back to the platform no stop was pending, SUMO never registered the halt and
the trams behind it queued until the run stalled (3,398 s). The bridge now hands a stop over only once SUMO would
make it on the pass it is meant for (``StopSpec.route_index``, :mod:`railsim.engine.stop_passes`).

Generated world: a ring of four 1.26 km quarter arcs (``build_ring``), a train started on arc 0 whose route runs
round the ring and on to arc 1 again, with a platform on arc 1 meant for the second pass. SUMO drives the train
itself (uncontrolled), so it is SUMO's stop that brakes it: the test reads where it registers the halt.
"""

from __future__ import annotations

import json
from pathlib import Path

from tests.helpers import run_python
from tests.sumo.test_external_net import build_ring

_CODE = r"""
import json, sys
from railsim.engine.sumo import SumoBridge, SumoConfig, StopSpec, VTypeSpec
net, stops_file, route_index = sys.argv[1], sys.argv[2], sys.argv[3]
cfg = SumoConfig(net_file=net, additional_files=[stops_file], step_s=0.5, vtypes=[VTypeSpec("t", 60.0, 22.0)])
route = ["q0", "q1", "q2", "q3", "q0", "q1", "q2"]
with SumoBridge(cfg) as br:
    import libsumo
    br.add_route("r", route)
    stop = StopSpec("s1", duration_s=20.0, route_index=None if route_index == "none" else int(route_index))
    br.add_train("x", "r", "t", 10.0, stops=[stop], controlled=False)
    halts = []
    for _ in range(2400):
        br.step()
        if "x" not in libsumo.vehicle.getIDList():
            break
        if libsumo.vehicle.getStopState("x") & 1 and (not halts or halts[-1][0] != libsumo.vehicle.getRouteIndex("x")):
            halts.append((libsumo.vehicle.getRouteIndex("x"), round(libsumo.vehicle.getLanePosition("x"), 2)))
print(json.dumps({"halts": halts}))
"""


def _halts(net: Path, stops: Path, route_index: str) -> list[list[float]]:
    res = run_python(
        _CODE.replace("sys.argv[1], sys.argv[2], sys.argv[3]", f"{str(net)!r}, {str(stops)!r}, {route_index!r}")
    )
    assert res.returncode == 0, res.stderr
    return json.loads(res.stdout.strip().splitlines()[-1])["halts"]


def test_a_stop_meant_for_the_second_pass_of_its_edge_is_made_there(tmp_path: Path) -> None:
    net, stops = build_ring(tmp_path)
    # SUMO on its own: the stop goes on the first pass of arc 1 (route index 1), whatever pass was meant
    assert [h[0] for h in _halts(net, stops, "none")] == [1]
    # the second pass named: the train runs through the platform the first time and halts there the second time
    halts = _halts(net, stops, "5")
    assert [h[0] for h in halts] == [5], halts
    assert 500.0 + 60.0 - 1.0 <= halts[0][1] <= 800.0 + 1e-6  # whole train on the platform (s1: 500-800 m)
