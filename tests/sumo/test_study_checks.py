"""Studies check every case as ``railsim validate`` does before the first run, naming the user's file and field."""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import DATA, mini_line, run_railsim


def test_a_sweep_with_a_case_validate_refuses_runs_nothing(tmp_path: Path) -> None:
    base = tmp_path / "mini.yaml"
    base.write_text(yaml.safe_dump(mini_line()), encoding="utf-8")
    sweep = tmp_path / "sweep.yaml"
    bad = {"formations[0].follower": {"service": "main_down", "trip": 0}}  # scenario.load accepts it; run does not
    sweep.write_text(yaml.safe_dump({"base": str(base), "cases": [{}, bad], "seeds": [1]}), encoding="utf-8")
    out = tmp_path / "out"
    res = run_railsim(
        ["sweep", str(sweep), "--out", str(out), "--workers", "1", "--no-progress"], cache_dir=tmp_path / "c"
    )
    assert res.returncode == 2, (res.returncode, res.stdout, res.stderr)
    line = res.stderr.strip()
    assert len(line.splitlines()) == 1 and "Traceback" not in line
    assert line.startswith(f"railsim: error: {sweep}: case 1") and "formations[0].couple" in line, line
    assert not (out / "rows").exists() or not any((out / "rows").iterdir()), "a case ran before the check"


def test_robustness_reports_a_bad_disturbances_file_against_that_file(tmp_path: Path) -> None:
    dist = tmp_path / "my_disturbances.yaml"
    dist.write_text(
        yaml.safe_dump({"disturbances": {"incidents": [{"trip": "a.000", "station": "nowhere", "hold_s": 60}]}}),
        encoding="utf-8",
    )
    scenario = DATA / "scenarios" / "disturbed_line.yaml"
    res = run_railsim(
        ["robustness", str(scenario), "--runs", "2", "--disturbances", str(dist), "--out", str(tmp_path / "out")],
        cache_dir=tmp_path / "c",
    )
    assert res.returncode == 2, (res.returncode, res.stderr)
    line = res.stderr.strip()
    assert len(line.splitlines()) == 1
    assert line.startswith(f"railsim: error: {dist}: disturbances.incidents[0].station"), line
    assert "robustness_sweep" not in line


def test_vc_vs_mb_checks_its_disturbances_file_before_the_capacity_search(tmp_path: Path) -> None:
    dist = tmp_path / "study_disturbances.yaml"
    dist.write_text(yaml.safe_dump({"disturbances": {"running_time": {"low": 2.0, "high": 1.0}}}), encoding="utf-8")
    out = tmp_path / "out"
    res = run_railsim(
        ["study", "vc-vs-mb", "--out", str(out), "--disturbances", str(dist), "--runs", "2", "--no-progress"],
        cache_dir=tmp_path / "c",
        timeout=900,
    )
    assert res.returncode == 2, (res.returncode, res.stderr[-800:])
    line = res.stderr.strip()
    assert len(line.splitlines()) == 1, line
    assert line.startswith(f"railsim: error: {dist}: disturbances.running_time.low"), line
    assert not (out / "mb").exists() and not (out / "vc").exists(), "the capacity search ran first"
