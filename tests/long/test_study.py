"""``railsim study vc-vs-mb`` end to end on the mini Y line (a small probe budget), and its bad-input exits.

The regimes are the mini line's coupled pair (vc: the branch unit departs relative to the main line's and a
``pairs`` formation couples it to its reference unit), the same scenario without formations (mb) and the control
(vc with relative braking off). What is pinned: the command finishes, every regime is probed on the same grid
points, the minimum headways come from real probes, the control agrees with moving block (same answer, same
verdict at every probe, per-trip running times within a step), every answer has its analytic floor beside it and
the floor is below it, the report and the JSON agree, the regime with the formation carries more trains than paths
on the trunk, and mistakes exit 2 with one line naming the file and field.
"""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest
import yaml

from tests.helpers import DATA, run_railsim

MINI = DATA / "scenarios" / "mini_line.yaml"


def _scenarios(tmp: Path) -> tuple[Path, Path]:
    raw = yaml.safe_load(MINI.read_text())
    raw["world"] = {"line": str((MINI.parent / raw["world"]["line"]).resolve())}
    for svc in raw["services"]:  # a headway study needs first/last/headway_s timetables
        if svc["id"] == "main_up":
            svc["departures"] = {"first": 0, "last": 240, "headway_s": 120}
        if svc["id"] == "main_down":
            svc["departures"] = {"first": 30, "last": 150, "headway_s": 120}
        if svc["id"] == "br_up":  # due when main_up trip 1 is planned to leave b (its origin departure + 125.5 s)
            svc["departures"] = {"after": {"service": "main_up", "first_trip": 1, "every": 10, "offset_s": 125.5}}
    raw["formations"] = [
        {
            "id": "pair",
            "pairs": {"leader": "main_up", "follower": "br_up"},
            "target_gap_m": 30,
            "couple": {"on_departure": True},
            "decouple": {"before_switch": "c_up"},
        }
    ]
    vc = tmp / "mini_vc.yaml"
    vc.write_text(yaml.safe_dump(raw, sort_keys=False))
    mb_raw = copy.deepcopy(raw)
    mb_raw["formations"] = []
    mb_raw["name"] = "mini_mb"
    mb = tmp / "mini_mb.yaml"
    mb.write_text(yaml.safe_dump(mb_raw, sort_keys=False))
    return mb, vc


def test_vc_vs_mb_end_to_end(tmp_path: Path) -> None:
    mb, vc = _scenarios(tmp_path)
    out = tmp_path / "study"
    args = [
        "study",
        "vc-vs-mb",
        "--out",
        str(out),
        "--mb",
        str(mb),
        "--vc",
        str(vc),
        "--services",
        "main_up,main_down",
        "--lo",
        "60",
        "--hi",
        "120",
        "--tol",
        "30",
        "--no-confirm",
        "--workers",
        "2",
        "--no-progress",
    ]
    res = run_railsim(args, timeout=900)
    assert res.returncode == 0, res.stderr + res.stdout
    assert "Traceback" not in res.stderr
    data = json.loads((out / "vc_vs_mb.json").read_text())
    md = (out / "vc_vs_mb.md").read_text()
    for key in ("mb", "vc", "control"):
        r = data[key]
        probes = r["search"]["probes"]
        probed = {p["headway_s"] for p in probes}
        assert probed == {60.0, 90.0, 120.0}  # one grid, every point probed, for every regime
        assert r["headway_s"] in probed
        # the floor is sustained capacity: a run of a few trains may undercut it by holding them (≤ the threshold)
        assert 0.0 < r["floor"]["cycle_s"] <= r["floor"]["strict_s"] and r["floor"]["cycle_s"] < r["headway_s"] + 60
        assert r["floor"]["critical"]["station"] in {"a", "b", "c", "d", "e", "f", "g"}
        assert r["conditions"]["max_delay_s"] == 120.0 and "main_up" in r["conditions"]["offered_trains_per_h"]
        assert all(p["feasible"] for p in probes if p["headway_s"] >= r["headway_s"])
        m = r["metrics"]
        assert m["collisions"] == 0 and m["stops_missed"] == 0
        assert Path(r["run_dir"], "summary.json").is_file()
        assert "| minimum feasible headway [s] |" in md
    # the coupled branch unit rides on its leader's path on the trunk: more units than paths per hour
    assert data["vc"]["metrics"]["up.trains_per_h"] > data["vc"]["metrics"]["up.paths_per_h"]
    assert data["mb"]["metrics"]["up.trains_per_h"] == data["mb"]["metrics"]["up.paths_per_h"]
    assert data["vc"]["metrics"]["formations_coupled"] == "1/1"
    assert data["mb"]["metrics"]["formations_coupled"] == "0/0"
    # the control experiment: relative braking off reproduces moving block
    check = data["control_check"]
    assert check["same_headway"] and check["probes_differing"] == [] and check["probes_compared"] == 3
    assert check["trips_compared"] == data["mb"]["metrics"]["trains"] and check["trips_only_one_side"] == 0
    assert check["max_running_time_diff_s"] <= 0.5  # within a step (0.5 s)
    assert data["control"]["metrics"]["formations_coupled"] == "0/1"
    assert "(c) = (a)" in md and "## Analytic floors" in md and "## Conditions" in md
    # the Markdown table shows the JSON's numbers
    row = next(line for line in md.splitlines() if line.startswith("| minimum feasible headway"))
    assert row == (
        f"| minimum feasible headway [s] | {data['mb']['headway_s']:,.1f} | {data['vc']['headway_s']:,.1f} | "
        f"{data['control']['headway_s']:,.1f} |"
    )
    assert "UIC 406 occupancy per section" in md
    # a re-run finds every probe already done and gives the same answer
    again = run_railsim(args, timeout=900)
    assert again.returncode == 0, again.stderr
    assert json.loads((out / "vc_vs_mb.json").read_text())["vc"]["headway_s"] == data["vc"]["headway_s"]


@pytest.mark.parametrize(
    "extra, needle",
    [
        (["--mb", "no_such.yaml"], "no_such.yaml: expected a scenario file for --mb"),
        (["--services", "nope"], "services: expected a service 'nope'"),
        (["--workers", "0"], "argument --workers: expected an integer in [1,"),
        (["--headway", "-5"], "headway_s: expected a number of seconds > 0"),
    ],
)
def test_bad_input_exits_2_with_one_line(tmp_path: Path, extra: list[str], needle: str) -> None:
    mb, vc = _scenarios(tmp_path)
    args = ["study", "vc-vs-mb", "--out", str(tmp_path / "o"), "--mb", str(mb), "--vc", str(vc)] + extra
    if "--mb" in extra:
        args = ["study", "vc-vs-mb", "--out", str(tmp_path / "o"), "--vc", str(vc)] + extra
    res = run_railsim(args)
    assert res.returncode == 2, res.stderr + res.stdout
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], res.stderr
