"""A formation that couples on departure behind a leader, its follower's unit coming out of a depot: it couples,
or the run says why (an event and a summary line) — never a silent drop.

World: ``mini_y`` with one depot lead. From a depot between ``a`` and ``b`` the follower's unit (``br_up``, from
``b``) runs straight onto its departure platform at ``b`` before its leader (``main_up.001``) gets there: it
stands ahead of its leader and cannot come out behind it. From a depot between ``b`` and ``c`` it reaches the
opposite platform, turns back there and waits for its leader like any follower across a turnback: it couples.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import DATA, read_csv, read_summary, run_railsim


def _run(tmp_path: Path, depot: str) -> tuple[Path, object]:
    text = (DATA / "lines" / "mini_y.yaml").read_text(encoding="utf-8")
    line = tmp_path / "line.yaml"
    line.write_text(text.replace("branches:\n", f"depots: [{depot}]\nbranches:\n", 1), encoding="utf-8")
    raw = yaml.safe_load((DATA / "scenarios" / "mini_line.yaml").read_text(encoding="utf-8"))
    raw["world"] = {"line": str(line)}
    raw["simulation"]["duration_s"] = 3600
    for svc in raw["services"]:  # late enough for every depot-out run to reach its platform in time
        svc["departures"]["times"] = [t + 900.0 for t in svc["departures"]["times"]]
    raw["rotations"] = {"units": "auto", "turnback_min_s": 120, "depots": "auto"}
    scn = tmp_path / "scenario.yaml"
    scn.write_text(yaml.safe_dump(raw, sort_keys=False), encoding="utf-8")
    out = tmp_path / "out"
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], cache_dir=tmp_path / "c", timeout=600)
    return out, res


def test_depot_run_onto_the_departure_platform_says_why_the_pair_cannot_couple(tmp_path: Path) -> None:
    out, res = _run(tmp_path, "{id: west, between: [a, b]}")
    assert res.returncode == 0, res.stderr
    [formation] = read_csv(out / "formations.csv")
    if int(formation["couple_successes"]) > 0:
        return  # it coupled: nothing to explain
    events = [r for r in read_csv(out / "events.csv") if r["kind"] == "couple_not_possible"]
    assert [e["subject"] for e in events] == ["pair"]
    assert "unit04.depot_out" in events[0]["detail"] and "'b'" in events[0]["detail"]
    assert "pair" in read_summary(out)["formations_not_coupling"]
    assert "formation pair cannot couple on departure" in res.stdout


def test_depot_run_to_the_opposite_platform_couples(tmp_path: Path) -> None:
    out, res = _run(tmp_path, "{id: yard, between: [b, c]}")
    assert res.returncode == 0, res.stderr
    [formation] = read_csv(out / "formations.csv")
    assert int(formation["couple_successes"]) == 1, formation
    assert "formations_not_coupling" not in read_summary(out)
