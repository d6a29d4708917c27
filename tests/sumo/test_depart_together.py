"""A formation that departs together (``formations[].depart_together: true``) leaves every station both units
serve as one: the leader waits for its coupled follower's dwell there, at most one coupling timeout.

Real SUMO runs of the mini line (:file:`tests/data/scenarios/mini_line.yaml`): the pair ``main_up.001`` ←
``br_up.000`` couples on departure at B and runs coupled to C, the last stop before the branch switch. An incident
holds the *follower* 90 s at C. Without the option the leader leaves C on its own dwell and the pair comes apart;
with it the leader leaves C when the follower's dwell there ends (within a step) — the pair's dwell is the longer
of the two, as one coupled train's would be; with a 40 s coupling timeout the leader stops waiting after 40 s.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from tests.helpers import ROOT, read_csv, read_summary, run_railsim

DATA = ROOT / "tests" / "data"
DT_S = 0.5
HOLD_S = 90.0


def _scenario(tmp_path: Path, name: str, **formation: Any) -> Path:
    data = yaml.safe_load((DATA / "scenarios" / "mini_line.yaml").read_text(encoding="utf-8"))
    data["world"] = {"line": str(DATA / "lines" / "mini_y.yaml")}
    data["formations"][0].update(formation)
    data["disturbances"] = {"incidents": [{"trip": "br_up.000", "station": "c", "hold_s": HOLD_S}]}
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def _run(tmp_path: Path, name: str, **formation: Any) -> tuple[dict[str, dict[str, str]], list[dict[str, str]]]:
    out = tmp_path / name
    res = run_railsim(["run", str(_scenario(tmp_path, name, **formation)), "--out", str(out), "--no-progress"])
    assert res.returncode == 0, res.stderr
    summary = read_summary(out)
    assert summary["collisions"] == 0 and summary["n_arrived"] == summary["n_trains"]
    at_c = {r["trip_id"]: r for r in read_csv(out / "stops.csv") if r["station"] == "c"}
    return at_c, read_csv(out / "events.csv")


def _dep(row: dict[str, str]) -> float:
    return float(row["departure_s"])


def test_the_leader_waits_for_its_followers_dwell_only_when_asked(tmp_path: Path) -> None:
    own, own_events = _run(tmp_path, "own")
    together, events = _run(tmp_path, "together", depart_together=True)
    lead, fol = "main_up.001", "br_up.000"
    # each unit on its own dwell: the leader leaves C long before its held follower
    assert _dep(own[fol]) - _dep(own[lead]) > HOLD_S - 30.0
    assert not any(e["kind"] == "departure_held_for_follower" and e["subject"] == lead for e in own_events)
    # together: the leader leaves C when the follower's dwell there ends (the same step or the next)
    assert 0.0 <= _dep(together[lead]) - _dep(together[fol]) <= DT_S
    assert float(together[fol]["dwell_s"]) >= HOLD_S
    held = [e for e in events if e["kind"] == "departure_held_for_follower" and e["subject"] == lead]
    assert len(held) == 1 and json.loads(held[0]["detail"])["station"] == "c"
    # it held at C only: the arrival at C is the same run until then
    assert together[lead]["arrival_s"] == own[lead]["arrival_s"]


def test_the_leader_waits_at_most_one_coupling_timeout(tmp_path: Path) -> None:
    timeout_s = 40.0
    at_c, _ = _run(tmp_path, "bounded", depart_together=True, coupling_timeout_s=timeout_s)
    lead, fol = "main_up.001", "br_up.000"
    own_dwell_end_s = float(at_c[lead]["arrival_s"]) + 20.0  # its planned 20 s dwell (registration adds ~1 s)
    assert _dep(at_c[lead]) < _dep(at_c[fol]) - 20.0  # it did not wait for the whole hold
    assert _dep(at_c[lead]) <= own_dwell_end_s + timeout_s + 3.0
    assert _dep(at_c[lead]) >= own_dwell_end_s + timeout_s - 3.0
