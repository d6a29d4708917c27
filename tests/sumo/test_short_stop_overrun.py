"""A sub-metre overrun of a short stop is served, never dropped; a stop the plan runs past keeps the later ones.

* SUMO: a 25 m stop (an OSM-style platform, shorter than the 89.4 m train) in the middle of a 2 km edge; a
  constant actuator bias of +0.115 m/s2 while the train brakes for it makes it halt past the platform's end by a
  fraction of a metre. The stop used to be dropped (``stop_missed``, the stop not served); it is served now with
  its stopping error and a ``stop_overrun_served`` event, because a short platform's SUMO stop reaches 1 m past
  its end (``TripStop.overrun_m``).
* Free run (the plan): a stop the planned run passes without halting used to leave every later stop, the
  destination included, without a planned time (the loop waited for that stop until its time limit); now it is
  passed and the later stops keep theirs — in the reference loop and in the compiled one alike.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import yaml

from tests.helpers import read_csv, read_summary, run_railsim
from tests.sumo.test_external_net import _COMMON, _edge, _netconvert, _service, _write

BIAS_MPS2 = 0.115


def build_short_stop(folder: Path) -> tuple[Path, Path]:
    nodes = '<node id="A" x="0" y="0"/>\n<node id="J" x="2000" y="0"/>\n<node id="B" x="4000" y="0"/>'
    net = _netconvert(folder, "short", nodes, "\n".join([_edge("AJ", "A", "J"), _edge("JB", "J", "B")]))
    rows = [
        '<trainStop id="a" lane="AJ_0" startPos="100" endPos="400" name="Alpha"/>',
        '<trainStop id="m" lane="AJ_0" startPos="1175" endPos="1200" name="Mid"/>',
        '<trainStop id="b" lane="JB_0" startPos="1500" endPos="1800" name="Bravo"/>',
    ]
    return net, _write(folder, "short.add.xml", "<additional>\n" + "\n".join(rows) + "\n</additional>")


def test_sub_metre_overrun_of_a_25_m_stop_is_served(tmp_path: Path) -> None:
    net, stops = build_short_stop(tmp_path)
    raw = {"name": "short", "world": {"net": str(net), "additional": [str(stops)]}, **_COMMON}
    raw["services"] = [_service("s", "alpha", "bravo", 0)]
    raw["faults"] = {
        **_COMMON["faults"],
        "actuator_bias": [{"train": "s.000", "accel_mps2": BIAS_MPS2, "from_s": 40, "until_s": 90}],
    }
    scn = _write(tmp_path, "short.yaml", yaml.safe_dump(raw, sort_keys=False))
    out = tmp_path / "out"
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], cache_dir=tmp_path / "c", timeout=600)
    assert res.returncode == 0, res.stderr + res.stdout
    s = read_summary(out)
    assert s["n_stops_served"] == s["n_stops_scheduled"] == 2 and s["n_stops_missed"] == 0
    events = read_csv(out / "events.csv")
    assert not [e for e in events if e["kind"] == "stop_missed"]
    (over,) = [yaml.safe_load(e["detail"]) for e in events if e["kind"] == "stop_overrun_served"]
    assert 0.0 < over["overrun_m"] < 1.0 and over["station"] == "mid"
    mid = next(r for r in read_csv(out / "stops.csv") if r["station"] == "mid")
    assert mid["missed"] == "False" and float(mid["stopping_error_m"]) == pytest.approx(
        1.0 + over["overrun_m"], abs=0.01
    )


def test_a_stop_the_plan_runs_past_keeps_the_later_planned_times(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from network.external import load_net
    from railsim.engine import trips as trips_mod
    from railsim.physics.vehicle import preset

    monkeypatch.setenv("RAILSIM_CACHE", str(tmp_path / "cache"))
    net, stops = build_short_stop(tmp_path)
    bundle = load_net(net, [stops])
    route = bundle.route_between("alpha", "bravo", ("mid",))
    vehicle = preset("cq3_6car")
    made = trips_mod.make_stops(route, vehicle.length_m, (), 30.0, {}, "alpha", "bravo")
    assert made[1].short_platform
    # Mid's window moved behind the origin: the planned run can never halt in it and must pass it
    behind = dataclasses.replace(made[1], mark_m=10.0, window_start_m=5.0, window_end_m=12.0)
    trip = trips_mod.Trip(
        trip_id="s.000",
        service_id="s",
        index=0,
        vehicle_name="cq6",
        vehicle=vehicle,
        route=route,
        stops=(made[0], behind, made[2]),
        depart_s=0.0,
        roles={"ato": "ato"},
    )
    from controllers.ato import Ato, AtoParams
    from railsim.engine import free_run_kernel
    from tests.helpers import interpreted

    for loop in (interpreted(free_run_kernel).free_run, free_run_kernel.free_run):
        arrivals, _ = trips_mod.free_run(trip, Ato(AtoParams(), vehicle), 0.5, "euler", 3600.0, loop=loop)
        assert "mid" not in arrivals and 100.0 < arrivals["bravo"] < 600.0
