"""Inputs as they come from OSM imports and other people's nets (nets built here with netconvert).

* **mixed-class stops**: netconvert's ``--ptstop-output`` mixes tram, metro and train stops; the tram stops of a
  metro study are skipped with one warning line (the whole file used to be refused);
* **non-ASCII station names**: ``Colón`` is station ``colon`` (it used to be ``col-n``); name and stop id work too;
* **no lane permissions**: a net whose lanes allow every class has no rail edges by railsim's rule (a road is a
  lane cars may use); ``world.unrestricted_lanes: subway`` makes them track, and a train runs on it in SUMO;
* **a missing track is not a reversal**: a service between two lines that no track joins says so;
* **big nets**: ``railsim network show`` on a 40-station line lists its routes and line km (it used to list
  ``routes (0)`` and no km above 30 stations).
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tests.helpers import read_summary, run_railsim
from tests.sumo.test_external_net import _COMMON, _edge, _netconvert, _service, _write


def _stops_file(folder: Path, name: str, rows: list[tuple[str, str, float, float, str]]) -> Path:
    body = "\n".join(
        f'  <trainStop id="{s}" lane="{lane}" startPos="{a}" endPos="{b}" name="{n}"/>' for s, lane, a, b, n in rows
    )
    return _write(folder, f"{name}.add.xml", f"<additional>\n{body}\n</additional>")


def build_metro_and_tram(folder: Path) -> tuple[Path, Path]:
    """A subway line Alpha–Colón–Bravo and, beside it, a tram line with two tram stops."""
    nodes = (
        '<node id="A" x="0" y="0"/>\n<node id="B" x="3000" y="0"/>\n'
        '<node id="T0" x="0" y="200"/>\n<node id="T1" x="3000" y="200"/>'
    )
    edges = [
        _edge("M", "A", "B", spread="right", allow="subway"),
        _edge("-M", "B", "A", spread="right", allow="subway"),
        _edge("T", "T0", "T1", allow="tram"),
    ]
    net = _netconvert(folder, "mixed", nodes, "\n".join(edges))
    rows = [
        ("alpha", "M_0", 100, 400, "Alpha"),
        ("colon_e", "M_0", 1300, 1600, "Colón"),
        ("bravo", "M_0", 2600, 2900, "Bravo"),
        ("tram_1", "T_0", 100, 130, "Tram One"),
        ("tram_2", "T_0", 2000, 2030, "Tram Two"),
    ]
    return net, _stops_file(folder, "mixed", rows)


def test_tram_stops_in_a_metro_study_are_skipped_with_one_warning(tmp_path: Path) -> None:
    net, stops = build_metro_and_tram(tmp_path)
    res = run_railsim(["network", "show", str(net), "-a", str(stops), "--vclass", "subway"], cache_dir=tmp_path / "c")
    assert res.returncode == 0, res.stderr
    warnings = [ln for ln in res.stderr.splitlines() if "skipped" in ln]
    assert len(warnings) == 1 and "2 stops" in warnings[0] and "tram" in warnings[0], res.stderr
    assert "tram-one" not in res.stdout and "alpha" in res.stdout


def test_non_ascii_station_names_transliterate(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from network.external import load_net

    monkeypatch.setenv("RAILSIM_CACHE", str(tmp_path / "cache"))
    net, stops = build_metro_and_tram(tmp_path)
    b = load_net(net, [stops], vclass="subway")
    assert "colon" in b.stations and b.stations["colon"].name == "Colón"
    assert b.station_aliases["Colón"] == b.station_aliases["colon_e"] == "colon"


def build_no_permissions(folder: Path) -> tuple[Path, Path]:
    nodes = '<node id="A" x="0" y="0"/>\n<node id="B" x="3000" y="0"/>'
    edges = '<edge id="AB" from="A" to="B" numLanes="1" speed="22"/>'  # no allow: every class
    net = _netconvert(folder, "open", nodes, edges)
    rows = [("a", "AB_0", 100, 400, "Alpha"), ("b", "AB_0", 2500, 2800, "Bravo")]
    return net, _stops_file(folder, "open", rows)


def test_a_net_without_lane_permissions_runs_when_its_lanes_are_named_rail(tmp_path: Path) -> None:
    net, stops = build_no_permissions(tmp_path)
    raw = {"name": "open", "world": {"net": str(net), "additional": [str(stops)]}, **_COMMON}
    raw["services"] = [_service("s", "alpha", "bravo", 0)]
    plain = _write(tmp_path, "plain.yaml", yaml.safe_dump(raw, sort_keys=False))
    res = run_railsim(["run", str(plain), "--out", str(tmp_path / "o1"), "--no-progress"], cache_dir=tmp_path / "c")
    assert res.returncode == 2 and "no rail edges" in res.stderr, res.stderr
    raw["world"]["unrestricted_lanes"] = "subway"
    named = _write(tmp_path, "named.yaml", yaml.safe_dump(raw, sort_keys=False))
    out = tmp_path / "o2"
    res = run_railsim(["run", str(named), "--out", str(out), "--no-progress"], cache_dir=tmp_path / "c")
    assert res.returncode == 0, res.stderr
    s = read_summary(out)
    assert s["n_arrived"] == 1 and s["n_stops_served"] == 1 and s["collisions"] == 0


def test_the_refusal_of_a_net_without_permissions_names_the_way_past(tmp_path: Path) -> None:
    """The refusal says which world option makes open lanes track; ``network show`` takes it too."""
    net, stops = build_no_permissions(tmp_path)
    res = run_railsim(["network", "show", str(net), "-a", str(stops)], cache_dir=tmp_path / "c")
    assert res.returncode == 2 and "no rail edges" in res.stderr, res.stderr
    assert "lanes without permissions" in res.stderr and "unrestricted_lanes" in res.stderr, res.stderr
    res = run_railsim(
        ["network", "show", str(net), "-a", str(stops), "--unrestricted-lanes", "subway"], cache_dir=tmp_path / "c"
    )
    assert res.returncode == 0, res.stderr
    assert "rail vClass subway" in res.stdout and "alpha" in res.stdout.lower(), res.stdout


def test_a_missing_track_is_named_not_a_reversal(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from network.external import load_net

    monkeypatch.setenv("RAILSIM_CACHE", str(tmp_path / "cache"))
    nodes = (
        '<node id="A" x="0" y="0"/>\n<node id="B" x="3000" y="0"/>\n'
        '<node id="C" x="0" y="500"/>\n<node id="D" x="3000" y="500"/>'
    )
    edges = [_edge("AB", "A", "B", spread="right"), _edge("CD", "C", "D", spread="right")]
    net = _netconvert(tmp_path, "two", nodes, "\n".join(edges))
    stops = _stops_file(
        tmp_path,
        "two",
        [("a", "AB_0", 100, 400, "Alpha"), ("b", "AB_0", 2500, 2800, "Bravo"), ("c", "CD_0", 2500, 2800, "Charlie")],
    )
    b = load_net(net, [stops])
    with pytest.raises(ValueError, match="no track joins 'alpha' and 'charlie'") as info:
        b.route_between("alpha", "charlie")
    assert "revers" not in str(info.value).split("no track")[1].replace("not a question of reversing", "")
    with pytest.raises(ValueError, match="reversal"):
        b.route_between("bravo", "alpha")  # the track is there, only the other way: a reversal


def test_network_show_lists_routes_and_line_km_on_a_40_station_line(tmp_path: Path) -> None:
    nodes = '<node id="A" x="0" y="0"/>\n<node id="B" x="20500" y="0"/>'
    edges = [_edge("E", "A", "B", spread="right"), _edge("W", "B", "A", spread="right")]
    net = _netconvert(tmp_path, "long", nodes, "\n".join(edges))
    rows = []
    for k in range(40):
        x = 200.0 + 500.0 * k
        rows.append((f"s{k}_e", "E_0", x, x + 200.0, f"Stop {k}"))
        rows.append((f"s{k}_w", "W_0", 20300.0 - x - 200.0, 20300.0 - x, f"Stop {k}"))
    stops = _stops_file(tmp_path, "long", rows)
    res = run_railsim(["network", "show", str(net), "-a", str(stops)], cache_dir=tmp_path / "c", timeout=600)
    assert res.returncode == 0, res.stderr
    assert "routes (1560;" in res.stdout, res.stdout[-2000:]
    assert "no line km" not in res.stdout
    line = next(ln for ln in res.stdout.splitlines() if ln.strip().startswith("stop-39 "))
    assert "main" in line and "km  19.500" in line, line


def test_validate_warns_once_about_skipped_stops(tmp_path: Path) -> None:
    net, stops = build_metro_and_tram(tmp_path)
    raw = {"name": "mixed", "world": {"net": str(net), "additional": [str(stops)], "vclass": "subway"}, **_COMMON}
    raw["services"] = [_service("s", "alpha", "Colón", 0)]
    scn = _write(tmp_path, "mixed.yaml", yaml.safe_dump(raw, sort_keys=False, allow_unicode=True))
    res = run_railsim(["validate", str(scn)], cache_dir=tmp_path / "c")
    assert res.returncode == 0, res.stderr
    assert len([ln for ln in res.stderr.splitlines() if "skipped" in ln]) == 1, res.stderr
