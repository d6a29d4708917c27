"""Why the bridge hands SUMO every train's speed at every step (docs/performance.md, "SUMO's side").

A speed set through libsumo holds for every later step while the vehicle has no stop to make; with a stop pending
(even kilometres ahead) SUMO applies it for one step and then drives the train by its own car-following model. A
railsim train always has a stop pending until it arrives (its destination), so a speed left unsent would be
SUMO's, not ours. This pins that behaviour of the SUMO in use: if an upgrade changes it, sending speeds only when
they change becomes worth measuring again.
"""

from __future__ import annotations

import json

from tests.helpers import run_python

CHILD = r"""
import json, network
from railsim.engine.sumo import SumoBridge, SumoConfig, StopSpec, VTypeSpec
b = network.build("straight_corridor")
route = next(iter(b.routes.values()))
out = {}
for case, stops in (("no_stop", ()), ("stop_ahead", (StopSpec("s2.up", duration_s=20.0),))):
    cfg = SumoConfig(net_file=b.net_file, additional_files=[b.stops_file], step_s=0.5,
                     vtypes=[VTypeSpec("t", 90.0, 30.0)])
    with SumoBridge(cfg) as br:
        br.add_route("r", route.edges)
        br.add_train("x", "r", "t", 200.0, stops=stops)
        br.step()  # inserted at standstill
        br.set_speeds(["x"], [10.0])  # once
        speeds = []
        for _ in range(20):
            br.step()
            speeds.append(float(br.read(["x"]).speed_mps[0]))
        out[case] = speeds
print(json.dumps(out))
"""


def test_a_set_speed_holds_only_while_no_stop_is_pending() -> None:
    res = run_python(CHILD)
    assert res.returncode == 0, res.stderr
    speeds = json.loads(res.stdout.strip().splitlines()[-1])
    assert speeds["no_stop"] == [10.0] * 20  # held: SUMO's docs ("setSpeed persists") hold here
    assert speeds["stop_ahead"][0] == 10.0  # applied for the next step ...
    assert speeds["stop_ahead"][1] > 10.0  # ... then SUMO's own model accelerates the train (stop 14 km ahead)
