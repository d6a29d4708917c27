"""The line studies, ``network show``, ``validate`` and the refusal of a road net on a user's SUMO net.

The nets are the netconvert-built ones of :mod:`tests.sumo.test_external_net` (a double-track line X1–X2–Y1 with a
single-track branch to Zed, and a single-track line with a passing loop).

* **Line chainage** (:func:`network.chainage.line_chainage`): stations get km along the route through the
  most stations, the branch station km from the station it branches from.
* **Studies on a run**: a short ``railsim run`` (child process) on the junction net, then the section table,
  UIC 406 capacity, the train graph (``railsim plot --kind time-distance``) and ``railsim report`` on its folder.
* **``network show``** prints route distances from the first stop to the last, not the sum of whole edges.
* **``validate``** rejects what ``run`` rejects (no route, a needed reversal, a bad coupling station) with the
  same one-line message and exit code 2; a road-only net is refused by name.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tests.helpers import read_summary, run_railsim
from tests.sumo.test_external_net import (
    SCENARIOS,
    _edge,
    _netconvert,
    _scenario,
    _write,
    build_junction,
    build_passing_loop,
)


@pytest.fixture(scope="module")
def cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("extstudiescache")


@pytest.fixture(scope="module")
def nets(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, Path]]:
    folder = tmp_path_factory.mktemp("extstudynets")
    return {"junction": build_junction(folder), "passing": build_passing_loop(folder)}


@pytest.fixture()
def use_cache(cache: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("RAILSIM_CACHE", str(cache))
    return cache


def test_line_chainage_main_line_and_branch(nets: dict, use_cache: Path) -> None:
    from network.external import load_net

    b = load_net(nets["junction"][0], [nets["junction"][1]])
    km = {sid: (st.line, st.km) for sid, st in b.stations.items()}
    assert km["x1"] == ("main", 0.0)
    assert km["x2"] == ("main", pytest.approx(1.3))  # platform centres 350 m and 1650 m on U1
    assert km["y1"][0] == "main" and km["y1"][1] > km["x2"][1]
    # the branch station: placed from X2 (the nearest placed station on the route X1 -> Zed)
    x1_zed = b.route_between("x1", "zed")
    centre = {s.station_id: 0.5 * (s.start_m + s.end_m) for s in x1_zed.stops}
    assert km["zed"] == ("branch1", pytest.approx(1.3 + (centre["zed"] - centre["x2"]) / 1000.0, abs=1e-6))
    passing = load_net(nets["passing"][0], [nets["passing"][1]])
    order = sorted(passing.stations.values(), key=lambda st: st.km)
    assert [st.id for st in order] == ["portal", "alpha", "mid", "bravo"] and order[0].km == 0.0


def test_sections_capacity_train_graph_and_report_on_a_user_net(nets: dict, cache: Path, tmp_path: Path) -> None:
    scn = _scenario(tmp_path, "junction", *nets["junction"])
    out = tmp_path / "out"
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], cache_dir=cache, timeout=300)
    assert res.returncode == 0, res.stderr + res.stdout
    assert read_summary(out)["n_arrived"] == len(SCENARIOS["junction"][0])

    from railsim.analysis import capacity, sections

    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("RAILSIM_CACHE", str(cache))
        frame = sections.LineFrame.from_run(out)
        table = sections.section_table(out, frame)
        report = capacity.analyse_run(out, frame=frame)
    # lead X1 -> X2 -> Y1 runs up the main line; follow X2 -> Zed up the branch; ato Zed -> X2 -> X1 down
    assert frame.services["lead"].stations == ["x1", "x2", "y1"]
    assert frame.services["lead"].direction == "up" and frame.services["ato"].direction == "down"
    lead_km = [frame.services["lead"].km[s] for s in frame.services["lead"].stations]
    assert lead_km == sorted(lead_km) and lead_km[0] == 0.0
    rows = {(r.service, r.from_station, r.to_station): r for r in table.itertuples(index=False)}
    assert set(rows) == {
        ("lead", "x1", "x2"),
        ("lead", "x2", "y1"),
        ("follow", "x2", "zed"),
        ("ato", "zed", "x2"),
        ("ato", "x2", "x1"),
    }
    up = rows[("lead", "x2", "y1")]
    assert (
        up.to_km > up.from_km
        and up.running_time_s > 0
        and up.length_m == pytest.approx(1000.0 * (up.to_km - up.from_km), rel=0.01)
    )
    # coupled from X2 to the decouple before J, but the leader ran X2 -> Y1: not one section, so no formation
    assert rows[("follow", "x2", "zed")].formation == ""
    down = rows[("ato", "x2", "x1")]
    assert down.direction == "down" and down.to_km < down.from_km
    assert not report.tables["uic406"].empty and not report.tables["junction"].empty

    res = run_railsim(["plot", str(out), "--kind", "time-distance", "--out", str(tmp_path / "fig")], cache_dir=cache)
    assert res.returncode == 0, res.stderr
    png = tmp_path / "fig" / "time-distance.png"
    assert png.stat().st_size > 10_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    res = run_railsim(["report", str(out)], cache_dir=cache)
    assert res.returncode == 0, res.stderr
    text = (out / "report.md").read_text(encoding="utf-8")
    assert "Train graph" in text and "X2" in text


def test_network_show_prints_stop_to_stop_distances(nets: dict, cache: Path) -> None:
    from network.external import load_net

    net, stops = nets["junction"]
    res = run_railsim(["network", "show", str(net), "-a", str(stops)], cache_dir=cache)
    assert res.returncode == 0, res.stderr
    x2 = next(ln for ln in res.stdout.splitlines() if ln.strip().startswith("x2 "))
    assert "main     km   1.300" in x2  # the line chainage
    line = next(ln for ln in res.stdout.splitlines() if ln.strip().startswith("x1->x2 "))
    # X1 and X2 are 1.3 km apart on the 6 km edge U1: the route is 1.3 km, its whole edges 6 km
    assert " 1.300 km" in line
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("RAILSIM_CACHE", str(cache))
        assert load_net(net, [stops]).route_between("x1", "x2").length_m > 5000.0


def _error(args: list[str], cache: Path) -> str:
    res = run_railsim(args, cache_dir=cache)
    assert res.returncode == 2, res.stdout + res.stderr
    assert "Traceback" not in res.stderr and len(res.stderr.strip().splitlines()) == 1
    return res.stderr.strip()


def test_road_only_net_is_refused(cache: Path, tmp_path: Path) -> None:
    road = _netconvert(
        tmp_path,
        "road",
        '<node id="a" x="0" y="0"/><node id="b" x="500" y="0"/>',
        _edge("r", "a", "b", allow="passenger bus"),
    )
    msg = _error(["network", "show", str(road)], cache)
    assert msg.startswith(f"railsim: error: {road}: no rail edges (vClass rail_urban/subway/rail/")
    assert "the lanes allow: bus, passenger" in msg
    # a street open to every class but pedestrians (SUMO's default permissions; OSM street types that forget
    # subway) is a road too, not track
    street = _netconvert(
        tmp_path,
        "street",
        '<node id="a" x="0" y="0"/><node id="b" x="500" y="0"/>',
        '<edge id="s" from="a" to="b" numLanes="1" speed="13.9" disallow="pedestrian"/>',
    )
    assert _error(["network", "show", str(street)], cache).startswith(f"railsim: error: {street}: no rail edges (")


def test_validate_rejects_what_run_rejects(nets: dict, cache: Path, tmp_path: Path) -> None:
    base = yaml.safe_load(_scenario(tmp_path, "junction", *nets["junction"]).read_text())
    services = base["services"]
    bad = {
        # Y1 has a platform on the up track only: back to X1 needs a reversal
        "reversal": {**base, "services": [*services, {**services[0], "id": "back", "from": "y1", "to": "x1"}]},
        # Zed -> Y1: the branch joins the line towards X only
        "no_route": {**base, "services": [*services, {**services[0], "id": "nowhere", "from": "zed", "to": "y1"}]},
        # couple on departure at X2, but the leader now starts at X2's neighbour Y1... leader lead runs X1 -> Y1,
        # the follower starts at Zed, where the leader never stops
        "coupling": {
            **base,
            "services": [services[0], {**services[1], "from": "zed", "to": "x1"}, services[2]],
        },
    }
    for name, raw in bad.items():
        path = _write(tmp_path, f"{name}.yaml", yaml.safe_dump(raw, sort_keys=False))
        validate = _error(["validate", str(path)], cache)
        run = _error(["run", str(path), "--out", str(tmp_path / f"o_{name}")], cache)
        assert validate == run, name
        assert validate.startswith(f"railsim: error: {path}: "), validate
        if name != "coupling":
            assert "no route" in validate
        else:
            assert "formations[0]" in validate
