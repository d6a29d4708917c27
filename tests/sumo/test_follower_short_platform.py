"""A follower that couples on departure at a station its leader calls at, where the platform's edge is too short
to put it on behind the standing leader, is refused before the run with the reason.

Built here with netconvert: Mid's platform is the first 90 m of its edge; the 89.4 m leader stands at its end and
the follower would start 30 m behind the leader's rear, i.e. 20 m before its route begins. It used to wait there
for the whole run (``departure_held``: no valid position, then ``never_inserted`` and exit 3 at the end).
"""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import run_railsim
from tests.sumo.test_external_net import _COMMON, _edge, _netconvert, _service, _write


def test_follower_that_cannot_be_put_on_behind_its_leader_is_refused_at_once(tmp_path: Path) -> None:
    nodes = '<node id="A" x="0" y="0"/>\n<node id="X" x="2000" y="0"/>\n<node id="B" x="4000" y="0"/>'
    net = _netconvert(tmp_path, "fol", nodes, "\n".join([_edge("AX", "A", "X"), _edge("XB", "X", "B")]))
    rows = [
        '<trainStop id="a" lane="AX_0" startPos="100" endPos="400" name="Alpha"/>',
        '<trainStop id="m" lane="XB_0" startPos="10" endPos="100" name="Mid"/>',
        '<trainStop id="b" lane="XB_0" startPos="1500" endPos="1800" name="Bravo"/>',
    ]
    stops = _write(tmp_path, "fol.add.xml", "<additional>\n" + "\n".join(rows) + "\n</additional>")
    raw = {"name": "fol", "world": {"net": str(net), "additional": [str(stops)]}, **_COMMON}
    raw["services"] = [_service("lead", "alpha", "bravo", 0), _service("follow", "mid", "bravo", 60)]
    raw["formations"] = [
        {
            "id": "pair",
            "leader": {"service": "lead", "trip": 0},
            "follower": {"service": "follow", "trip": 0},
            "target_gap_m": 30,
            "couple": {"on_departure": True},
        }
    ]
    scn = _write(tmp_path, "fol.yaml", yaml.safe_dump(raw, sort_keys=False))
    res = run_railsim(["run", str(scn), "--out", str(tmp_path / "out"), "--no-progress"], cache_dir=tmp_path / "c")
    assert res.returncode == 2, res.stderr
    (line,) = res.stderr.strip().splitlines()
    assert line.startswith(f"railsim: error: {scn}: formations: formation 'pair': follower follow.000 cannot be put on")
    assert "standing at 'mid'" in line and "20.4 m before the start of its route" in line
