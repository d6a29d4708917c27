"""A short platform's stop on the lane that ends at the lane's end (within a rounding error) is accepted by SUMO.

A platform shorter than the train is handed to SUMO as a stop on its lane (``StopSpec.lane_stop_m``), computed in
route chainage. Where the platform (plus its 1 m overrun allowance) reaches the end of its edge, the window's end
came out as ``lane length + 2e-14`` on OpenStreetMap nets (the eclipse-sumo package's ``tools/game/DRT`` and
``bs3d`` nets), and SUMO refused the train at insertion ("stop ... has an invalid position", exit 3). The bridge
now clamps the window to the lane.
"""

from __future__ import annotations

import json

from tests.helpers import run_python


def test_a_lane_stop_ending_a_rounding_error_past_the_lane_is_accepted() -> None:
    code = r"""
import json, network
from railsim.physics.vehicle import preset
from railsim.engine.sumo import SumoBridge, SumoConfig, StopSpec, VTypeSpec
veh = preset("cq3_6car")
b = network.build("straight_corridor")
route = next(iter(b.routes.values()))
cfg = SumoConfig(net_file=b.net_file, additional_files=[b.stops_file], step_s=0.5,
                 vtypes=[VTypeSpec("t", veh.length_m, 100.0)])
with SumoBridge(cfg) as br:
    import libsumo
    stop_id = route.stops[-1].stop_id
    lane = libsumo.busstop.getLaneID(stop_id)
    length = libsumo.lane.getLength(lane)
    end = length + 1e-9  # the window's end a rounding error past the lane
    br.add_route("r", route.edges)
    br.add_train("x", "r", "t", 200.0, stops=[StopSpec(stop_id, duration_s=5.0, lane_stop_m=(length - 2.0, end))])
    br.step()
    (stop,) = libsumo.vehicle.getStops("x")
    print(json.dumps({"end": stop.endPos, "length": length, "lane": stop.lane}))
"""
    res = run_python(code)
    assert res.returncode == 0, res.stderr
    data = json.loads(res.stdout.strip().splitlines()[-1])
    assert data["end"] <= data["length"] and data["end"] > data["length"] - 1e-6
