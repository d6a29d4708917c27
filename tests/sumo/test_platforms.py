"""Platforms on other people's nets: short platforms, platforms at the very end of a route.

Nets made with SUMO's tools often have platforms shorter than our trains (``tools/game/rail``: ``startPos="10"
endPos="-10"`` on short edges) and platforms that end a metre before the end of their edge (the last edge of a
route). Both used to go wrong: a train aimed past a platform it could not fit on (a missed stop, 1–3 m
overrun), and the end of movement authority at the route's end, minus the ATO's margin, stopped a train 4 m
short of its mark.

The net here is one straight line A–B–C–D (built with netconvert): a 60 m edge B–C holds a 40 m platform
(``endPos="-10"``, shorter than the 89.4 m train) and the destination platform ends 1 m before D.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tests.helpers import read_csv, read_summary, run_railsim
from tests.sumo.test_external_net import _COMMON, _edge, _netconvert, _service, _write

TRAIN_M = 89.4  # cq3_6car


def build_short_platform_line(folder: Path) -> tuple[Path, Path]:
    nodes = (
        '<node id="A" x="0" y="0"/>\n<node id="B" x="1500" y="0"/>\n<node id="C" x="1560" y="0"/>\n'
        '<node id="D" x="3060" y="0"/>'
    )
    edges = [_edge("AB", "A", "B"), _edge("BC", "B", "C"), _edge("CD", "C", "D")]
    net = _netconvert(folder, "shortplat", nodes, "\n".join(edges))
    stops = _write(
        folder,
        "shortplat.stops.add.xml",
        """<additional>
  <trainStop id="a" lane="AB_0" startPos="100" endPos="400" name="Aston"/>
  <trainStop id="b" lane="BC_0" startPos="10" endPos="-10" name="Halt"/>
  <trainStop id="d" lane="CD_0" startPos="1200" endPos="-1" name="Dale"/>
</additional>""",
    )
    return net, stops


def test_short_platform_served_with_the_front_at_its_end_and_last_platform_reached(tmp_path: Path) -> None:
    net, stops = build_short_platform_line(tmp_path)
    raw = {
        "name": "shortplat",
        "world": {"net": str(net), "additional": [str(stops)]},
        **_COMMON,
        "services": [_service("s", "aston", "dale", 0)],
    }
    scn = _write(tmp_path, "shortplat.yaml", yaml.safe_dump(raw, sort_keys=False))
    out = tmp_path / "out"
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], timeout=300)
    assert res.returncode == 0, res.stderr + res.stdout
    s = read_summary(out)
    assert s["n_arrived"] == 1 and s["n_stops_missed"] == 0 and s["collisions"] == 0 and s["sumo_collisions"] == 0
    rows = {r["station"]: r for r in read_csv(out / "stops.csv")}
    assert rows["halt"]["missed"] == "False" and float(rows["halt"]["dwell_s"]) > 0
    # the route's chainage: AB + its internal lane + BC; the short platform ends 10 m before C
    from network.external import load_net

    route = load_net(net, [stops]).route_between("aston", "dale")
    halt = route.stop("halt")
    assert halt.end_m - halt.start_m == pytest.approx(40.0, abs=0.1)  # shorter than the train (89.4 m)
    # the front halts at the platform end (the last 2 m of it), within the ATO's 0.5 m of the 1 m mark
    assert abs(float(rows["halt"]["stopping_error_m"])) <= 0.5
    (ev,) = [e for e in read_csv(out / "events.csv") if e["kind"] == "stop_short_platform"]
    detail = yaml.safe_load(ev["detail"])
    assert ev["subject"] == "s.000" and detail["station"] == "halt"
    assert detail["platform_m"] == pytest.approx(40.0, abs=0.1) and detail["train_m"] == TRAIN_M
    # the destination platform ends 1 m before the route's end: the train reaches its mark, not 4 m short
    dale = route.stop("dale")
    assert route.length_m - dale.end_m == pytest.approx(1.0, abs=0.05)
    assert abs(float(rows["dale"]["stopping_error_m"])) <= 0.5
