"""Paper A's controllers drive coupled formations on a line, not only on the corridor.

A small slice of ``scenarios/chongqing_line3_dmpc.yaml`` (one Airport unit each way plus the coupled Jurenba unit)
runs in SUMO with the coupled role run by the DMPC: no collision, every stop served, the pair couples at
Liugongli, the DMPC decides while coupled (its solve times are in the trace), and the Paper A metrics are
computed with the scenario's own L^(s).
"""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import ROOT, read_csv, read_summary, run_railsim


def test_dmpc_drives_the_coupled_unit_on_line3(tmp_path: Path) -> None:
    raw = yaml.safe_load((ROOT / "scenarios" / "chongqing_line3_dmpc.yaml").read_text())
    for svc in raw["services"]:
        if svc["id"].startswith("airport"):
            svc["departures"] = {"times": ["07:30"]}
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False, allow_unicode=True))
    res = run_railsim(["run", str(path), "--out", str(tmp_path / "o"), "--no-progress"])
    assert res.returncode == 0, res.stderr[-2000:]
    s = read_summary(tmp_path / "o")
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0 and s["switch_violations"] == 0
    assert s["n_arrived"] == s["n_trains"] == 4 and s["n_stops_served"] == s["n_stops_scheduled"]
    forms = read_csv(tmp_path / "o" / "formations.csv")
    assert int(forms[0]["couple_successes"]) == 1 and float(forms[0]["min_gap_m"]) > 0.0
    follower = forms[0]["follower"]
    coupled_rows = [
        r
        for r in read_csv(tmp_path / "o" / "trace.csv")
        if r["train"] == follower and r["formation_state"] == "coupled"
    ]
    assert coupled_rows and all(r["solve_time_s"] for r in coupled_rows)  # the DMPC ran every coupled step
    assert follower in str(s["analyses"]["paper000"])  # Paper A's metrics for this follower are in the summary
    figs = run_railsim(["plot", str(tmp_path / "o"), "--out", str(tmp_path / "fig")])
    assert figs.returncode == 0, figs.stderr
    pngs = list((tmp_path / "fig").glob("*.png"))
    assert pngs and all(p.stat().st_size > 10_000 for p in pngs)
