"""``railsim study vc-vs-mb`` end to end on the mini Y line (a small probe budget), and its bad-input exits.

The two regimes are the mini line's coupled pair (vc) and the same scenario without formations (mb). What is
pinned: the command finishes, the minimum headways come from real probes on the search grid, the report and the
JSON agree, the regime with the formation carries more trains than paths on the trunk, and mistakes exit 2 with
one line naming the file and field.
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
    vc = tmp / "mini_vc.yaml"
    vc.write_text(yaml.safe_dump(raw, sort_keys=False))
    mb_raw = copy.deepcopy(raw)
    mb_raw["formations"] = []
    mb_raw["name"] = "mini_mb"
    mb = tmp / "mini_mb.yaml"
    mb.write_text(yaml.safe_dump(mb_raw, sort_keys=False))
    return mb, vc


@pytest.mark.sumo
@pytest.mark.slow
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
        "--mb-hi",
        "120",
        "--vc-hi",
        "120",
        "--tol",
        "30",
        "--no-confirm",
        "--workers",
        "2",
        "--no-progress",
    ]
    res = run_railsim(args, cache_dir=tmp_path / "cache", timeout=900)
    assert res.returncode == 0, res.stderr + res.stdout
    assert "Traceback" not in res.stderr
    data = json.loads((out / "vc_vs_mb.json").read_text())
    md = (out / "vc_vs_mb.md").read_text()
    for key in ("mb", "vc"):
        r = data[key]
        probes = r["search"]["probes"]
        probed = {p["headway_s"] for p in probes}
        assert r["headway_s"] in {60.0, 90.0, 120.0} and r["headway_s"] in probed
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
    # the Markdown table shows the JSON's numbers
    row = next(line for line in md.splitlines() if line.startswith("| minimum feasible headway"))
    assert row == (
        f"| minimum feasible headway [s] | {data['mb']['headway_s']:,.1f} | {data['vc']['headway_s']:,.1f} |"
    )
    assert "UIC 406 occupancy per section" in md
    # a re-run finds every probe already done and gives the same answer
    again = run_railsim(args, cache_dir=tmp_path / "cache", timeout=900)
    assert again.returncode == 0, again.stderr
    assert json.loads((out / "vc_vs_mb.json").read_text())["vc"]["headway_s"] == data["vc"]["headway_s"]


@pytest.mark.parametrize(
    "extra, needle",
    [
        (["--mb", "no_such.yaml"], "no_such.yaml: expected a scenario file for --mb"),
        (["--services", "nope"], "services: expected a service 'nope'"),
        (["--workers", "0"], "--workers: expected an integer >= 1"),
        (["--headway", "-5"], "headway_s: expected a number of seconds > 0"),
    ],
)
def test_bad_input_exits_2_with_one_line(tmp_path: Path, extra: list[str], needle: str) -> None:
    mb, vc = _scenarios(tmp_path)
    args = ["study", "vc-vs-mb", "--out", str(tmp_path / "o"), "--mb", str(mb), "--vc", str(vc)] + extra
    if "--mb" in extra:
        args = ["study", "vc-vs-mb", "--out", str(tmp_path / "o"), "--vc", str(vc)] + extra
    res = run_railsim(args, cache_dir=tmp_path / "cache")
    assert res.returncode == 2, res.stderr + res.stdout
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], res.stderr
