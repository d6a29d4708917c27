"""``railsim sweep``: expansion and validation of sweep files, real sweeps (2 local workers, interrupted and resumed,
a failing case, a Dask LocalCluster) on the small corridor scenario (scenarios/sweeps/corridor_small.yaml, ~1 s a
case). Every simulation runs in a child process (railsim.studies.sweep.run_case), never in the test process."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import time
from pathlib import Path

import pandas as pd
import pytest
import yaml

from railsim.studies import sweep
from tests.helpers import ROOT, railsim_cmd, run_railsim

BASE = ROOT / "scenarios" / "sweeps" / "corridor_small.yaml"
UP_HW = "services[0].departures.headway_s"
DOWN_HW = "services[1].departures.headway_s"
LAST_DEPARTURE_S = 600.0  # corridor_small: departures 0 .. 600 s in both directions


def write_sweep(folder: Path, body: dict, name: str = "sweep.yaml") -> Path:
    path = folder / name
    path.write_text(yaml.safe_dump({"base": str(BASE), **body}, sort_keys=False), encoding="utf-8")
    return path


# A small real sweep: 2 cases x 2 headways (5 cases with the extra seed), ~1-3 s each.
SMALL = {
    "name": "small",
    "cases": [{"label": {"margin": "wide"}}, {"label": {"margin": "narrow"}, "controllers.sep.params.margin_m": 20}],
    "grid": {UP_HW: [90, 150]},
    "link": {DOWN_HW: UP_HW},
    "seeds": [3],
}


def metric_frame(out: Path) -> pd.DataFrame:
    frame = pd.read_parquet(out / "cases.parquet")
    return frame.drop(columns=[c for c in sweep.WALL_CLOCK_COLUMNS if c in frame.columns]).reset_index(drop=True)


# ------------------------------------------------------------------------------------------------- no SUMO


@pytest.mark.parametrize(
    ("body", "words"),
    [
        # a case whose scenario is invalid: found before anything runs, naming the case and the scenario field
        ({"grid": {UP_HW: [90, -5]}}, ["case 1 (", f"{UP_HW}=-5", f"{UP_HW}: expected a number > 0"]),
        ({"cases": [{}, {"services[5].dwell_s": 20}]}, ["case 1 (", "services[5].dwell_s", "out of range"]),
        ({"cases": [{"services[0].to": "s9"}]}, ["case 0 (", "services[0].to", "expected a station id"]),
    ],
)
def test_cli_validates_every_case_before_running_exit_2(tmp_path: Path, body: dict, words: list[str]) -> None:
    path = write_sweep(tmp_path, body)
    res = run_railsim(["sweep", str(path), "--out", str(tmp_path / "out"), "--workers", "2"], timeout=120)
    assert res.returncode == 2, res.stderr
    line = res.stderr.strip()
    assert "\n" not in line and "Traceback" not in line and line.startswith(f"railsim: error: {path}: ")
    for w in words:
        assert w in line
    assert not (tmp_path / "out" / "rows").exists()  # nothing ran


# ------------------------------------------------------------------------------------------------- real sweeps


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The SMALL sweep run once, uninterrupted, with 2 local workers and --keep-runs: (sweep file, folder)."""
    folder = tmp_path_factory.mktemp("sweep_ref")
    path = write_sweep(folder, SMALL)
    res = run_railsim(["sweep", str(path), "--out", str(folder / "out"), "--workers", "2", "--keep-runs"], timeout=300)
    assert res.returncode == 0, res.stderr
    assert "4 cases, 4 ok, 0 failed (4 run now, 0 already done)" in res.stdout
    return path, folder / "out"


def test_two_worker_sweep_gives_one_tidy_row_per_case(reference: tuple[Path, Path]) -> None:
    path, out = reference
    spec = sweep.load_sweep(path)
    table = pd.read_parquet(out / "cases.parquet")
    csv_table = pd.read_csv(out / "cases.csv", dtype={"case_id": str})
    assert list(table["case_id"]) == [c.case_id for c in spec.cases] == list(csv_table["case_id"])
    assert list(table.columns[:8]) == [
        "case_id",
        "status",
        "error",
        "seed",
        "margin",
        "controllers.sep.params.margin_m",
        UP_HW,
        DOWN_HW,
    ]
    assert set(table["status"]) == {"ok"} and set(table["error"].fillna("")) == {""}
    assert set(table["run_status"]) == {"completed"}  # the run's own status never overwrites the row's
    assert list(table["margin"]) == ["wide", "wide", "narrow", "narrow"]
    for _, row in table.iterrows():
        h = row[UP_HW]
        # closed form: departures 0, h, 2h, ... <= 600 s in each of the two directions
        assert row["n_trains"] == 2 * (math.floor(LAST_DEPARTURE_S / h) + 1)
        assert row[DOWN_HW] == h and row["n_arrived"] == row["n_trains"] and row["collisions"] == 0
        # the row is the kept run's summary.json, flattened
        summary = json.loads((out / "runs" / row["case_id"] / "summary.json").read_text(encoding="utf-8"))
        assert row["n_stops_served"] == summary["n_stops_served"] and row["min_gap_m"] == summary["min_gap_m"]
        assert row["mean_running_time_s.up"] == summary["mean_running_time_s"]["up"]
        assert row["engine_wall_s"] == summary["wall_s"] and row["wall_s"] > row["engine_wall_s"]
        trips = pd.read_csv(out / "runs" / row["case_id"] / "trips.csv")
        assert row["trips.arrival_delay_max_s"] == pytest.approx(trips["delay_s"].max())
        assert row["trips.energy_kwh_total"] == pytest.approx(trips["energy_kwh"].sum())
    assert sorted(p.stem for p in (out / "rows").glob("*.json")) == sorted(table["case_id"])
    stored = yaml.safe_load((out / "sweep.yaml").read_text(encoding="utf-8"))
    assert stored["n_cases"] == 4 and stored["base"] == str(BASE.resolve()) and len(stored["base_sha256"]) == 64


def test_rerun_skips_finished_cases(reference: tuple[Path, Path]) -> None:
    path, out = reference
    before = (out / "cases.parquet").read_bytes()
    res = run_railsim(["sweep", str(path), "--out", str(out), "--workers", "2"], timeout=120)
    assert res.returncode == 0, res.stderr
    assert "(0 run now, 4 already done)" in res.stdout
    assert (out / "cases.parquet").read_bytes() == before


def _children(pid: int) -> set[int]:
    """Pids of the live case processes of the coordinator ``pid`` (Linux /proc): its descendants that lead their own
    session (each case does; a fork server or resource tracker between them and the coordinator does not)."""
    parent: dict[int, int] = {}
    leads_session: set[int] = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if fields[0] == "Z":
            continue
        me = int(stat.parent.name)
        parent[me] = int(fields[1])
        if int(fields[3]) == me:
            leads_session.add(me)

    def descends(p: int) -> bool:
        seen = set()
        while p in parent and p not in seen:
            seen.add(p)
            p = parent[p]
            if p == pid:
                return True
        return False

    return {p for p in leads_session if descends(p)}


def _gone(pids: set[int], limit_s: float = 15.0) -> bool:
    t0 = time.monotonic()
    while time.monotonic() - t0 < limit_s:
        if not any(Path(f"/proc/{p}").exists() and "Z" not in _state(p) for p in pids):
            return True
        time.sleep(0.1)
    return False


def _state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return "Z"


def _wait_for_rows(out: Path, n: int, proc: subprocess.Popen, limit_s: float = 120.0) -> int:
    t0 = time.monotonic()
    while time.monotonic() - t0 < limit_s:
        rows = len(list((out / "rows").glob("*.json"))) if (out / "rows").is_dir() else 0
        if rows >= n:
            return rows
        assert proc.poll() is None, "the sweep finished before it could be interrupted"
        time.sleep(0.05)
    raise AssertionError("no rows appeared")


def test_interrupted_sweeps_resume_without_lost_or_duplicated_rows(
    reference: tuple[Path, Path], tmp_path: Path
) -> None:
    path, ref_out = reference
    out = tmp_path / "out"
    cmd = railsim_cmd() + ["sweep", str(path), "--out", str(out), "--workers", "1"]
    # 1) SIGTERM (like Ctrl-C) after the first row: exit 130, children killed, the table holds the finished rows
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    _wait_for_rows(out, 1, proc)
    while not (kids := _children(proc.pid)):  # the next case has started
        assert proc.poll() is None, "the sweep finished before it could be interrupted"
        time.sleep(0.02)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    done = len(list((out / "rows").glob("*.json")))
    assert 1 <= done < 4
    assert len(pd.read_csv(out / "cases.csv")) == done
    assert _gone(kids), "a case process outlived the interrupted sweep"
    # 2) resume, then SIGKILL (no chance to clean up) while a case is running
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    while not (kids := _children(proc.pid)):  # a case process has started
        assert proc.poll() is None, "the sweep finished before it could be interrupted"
        time.sleep(0.02)
    proc.kill()
    proc.communicate(timeout=60)
    assert _gone(kids), "a case process outlived its killed coordinator"  # it watches its parent
    # 3) resume to the end
    res = run_railsim(["sweep", str(path), "--out", str(out), "--workers", "1"], timeout=300)
    assert res.returncode == 0, res.stderr
    table = pd.read_parquet(out / "cases.parquet")
    assert len(table) == 4 and table["case_id"].is_unique
    pd.testing.assert_frame_equal(metric_frame(out), metric_frame(ref_out))


def test_a_failing_case_is_recorded_and_the_sweep_goes_on(tmp_path: Path) -> None:
    # a case that passes every check and fails when it runs: its kept run folder cannot be written (the path is
    # taken by a file), an environment error of that case alone. (A case that validate refuses stops the sweep
    # before anything runs: tests/sumo/test_study_checks.py.)
    path = write_sweep(
        tmp_path,
        {
            "cases": [{"label": "good"}, {"label": "bad", "simulation.seed": 4}],
            "grid": {UP_HW: [150]},
            "link": {DOWN_HW: UP_HW},
        },
    )
    bad_id = sweep.load_sweep(path).cases[1].case_id
    (tmp_path / "out" / "runs").mkdir(parents=True)
    (tmp_path / "out" / "runs" / bad_id).write_text("not a folder", encoding="utf-8")
    args = ["sweep", str(path), "--out", str(tmp_path / "out"), "--workers", "2", "--keep-runs"]
    res = run_railsim(args, timeout=300)
    assert res.returncode == 1, res.stderr
    assert "2 cases, 1 ok, 1 failed" in res.stdout
    table = pd.read_csv(tmp_path / "out" / "cases.csv", keep_default_na=False)
    good, failed = table.iloc[0], table.iloc[1]
    assert good["status"] == "ok" and good["error"] == "" and int(good["n_arrived"]) == 10
    assert failed["status"] == "failed" and failed["label"] == "bad"
    assert "RunFolderError" in failed["error"] and "expected a folder" in failed["error"]
    assert failed["n_trains"] == ""  # no metrics for a failed case
    # --retry-failed runs it again (it fails again, still one row per case)
    res = run_railsim([*args, "--retry-failed"], timeout=300)
    assert res.returncode == 1 and "(1 run now, 1 already done)" in res.stdout
    assert len(pd.read_csv(tmp_path / "out" / "cases.csv")) == 2


def test_timeout_marks_the_case_failed() -> None:
    row = sweep.run_case(BASE, {UP_HW: 60}, 3, timeout_s=0.2)
    assert row["status"] == "failed" and row["error"] == "timed out after 0.2 s" and row[UP_HW] == 60
    assert row["wall_s"] < 30


def test_dask_local_cluster_gives_identical_metrics(reference: tuple[Path, Path], tmp_path: Path) -> None:
    from distributed import LocalCluster

    path, ref_out = reference
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        result = sweep.run_sweep(path, tmp_path / "dask", dask_address=cluster.scheduler_address, progress=False)
    assert (result.n_cases, result.n_ok, result.n_run) == (4, 4, 4)
    pd.testing.assert_frame_equal(metric_frame(tmp_path / "dask"), metric_frame(ref_out))


def test_bad_dask_address_is_a_config_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from railsim.cli import main as cli
    from railsim.studies.sweep import parallel

    monkeypatch.setattr(parallel, "DASK_CONNECT_TIMEOUT_S", 1.0)
    path = write_sweep(tmp_path, SMALL)
    code = cli.main(["sweep", str(path), "--out", str(tmp_path / "o"), "--dask", "tcp://127.0.0.1:9"])
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("railsim: error: --dask: cannot connect to the Dask scheduler"), err
    assert not (tmp_path / "o" / "rows").exists()
