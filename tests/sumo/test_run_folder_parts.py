"""The run folder's lock, staging and manifest (railsim.record.run_folder), without running SUMO."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from railsim.analysis import punctuality
from railsim.errors import RunFolderError
from railsim.record import run_folder


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_a_stale_lock_of_a_dead_pid_is_taken_over(tmp_path: Path) -> None:
    out = tmp_path / "out"
    lock = run_folder.lock_path(out)
    lock.write_text(f"{_dead_pid()}\n", encoding="ascii")  # a killed run's lock file
    with run_folder.locked(out):
        assert lock.read_text(encoding="ascii").strip() == str(os.getpid())
    assert not lock.exists()


def test_a_lock_held_by_a_live_process_is_refused_naming_its_pid(tmp_path: Path) -> None:
    out = tmp_path / "out"
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time; from pathlib import Path; from railsim.record import run_folder\n"
            f"with run_folder.locked(Path({str(out)!r})):\n    print('held', flush=True); time.sleep(60)",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "held"
        t0 = time.perf_counter()
        with pytest.raises(RunFolderError) as err, run_folder.locked(out):
            pass
        assert time.perf_counter() - t0 < 1.0
        assert f"pid {holder.pid}" in str(err.value) and "in use" in str(err.value)
        assert "\n" not in str(err.value)
    finally:
        holder.kill()
        holder.wait()


def _fake_run(folder: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        (folder / name).write_text(text, encoding="utf-8")


def test_commit_replaces_the_previous_run_and_keeps_foreign_files(tmp_path: Path) -> None:
    out = tmp_path / "out"
    with run_folder.writing(out) as staging:
        _fake_run(staging.path, {"summary.json": "{}", "delays.csv": "trip_id\n", "trips.csv": "a\n"})
        staging.commit("completed")
    (out / "notes.txt").write_text("mine", encoding="utf-8")  # the user's own file in the folder
    with run_folder.writing(out) as staging:
        _fake_run(staging.path, {"summary.json": '{"n": 2}', "trips.csv": "b\n"})
        staging.commit("interrupted")
    assert sorted(p.name for p in out.iterdir() if p.is_file()) == ["notes.txt", "summary.json", "trips.csv"]
    manifest = run_folder.read_manifest(out)
    assert manifest is not None and manifest["status"] == "interrupted"
    assert [e["name"] for e in manifest["files"]] == ["summary.json", "trips.csv"]
    assert not list(tmp_path.glob(".out.*"))


def test_readers_skip_a_file_the_manifest_does_not_list(tmp_path: Path) -> None:
    out = tmp_path / "out"
    with run_folder.writing(out) as staging:
        _fake_run(staging.path, {"summary.json": "{}", "trips.csv": "a\n"})
        staging.commit("completed")
    (out / "delays.csv").write_text("trip_id,station,arrival_delay_s\nx,s,1\n", encoding="utf-8")  # not this run's
    assert run_folder.member(out, "delays.csv") is None
    assert punctuality.load(out) is None
    (out / "trips.csv").write_text("changed after the run\n", encoding="utf-8")
    assert run_folder.member(out, "trips.csv") is None
    assert run_folder.member(out, "summary.json") == out / "summary.json"


def test_an_oserror_in_the_run_discards_the_staging_folder_and_names_the_final_path(tmp_path: Path) -> None:
    out = tmp_path / "out"
    with pytest.raises(RunFolderError) as err, run_folder.writing(out) as staging:
        raise OSError(27, "File too large", str(staging.path / "trace.csv"))
    assert str(out / "trace.csv") in str(err.value) and "File too large" in str(err.value)
    assert not out.exists() and not list(tmp_path.iterdir())


def test_manifest_lists_name_bytes_and_sha256(tmp_path: Path) -> None:
    out = tmp_path / "out"
    with run_folder.writing(out) as staging:
        _fake_run(staging.path, {"trips.csv": "abc"})
        staging.commit("completed")
    data = json.loads((out / ".railsim" / "manifest.json").read_text(encoding="utf-8"))
    assert data["files"] == [
        {"name": "trips.csv", "bytes": 3, "sha256": "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"}
    ]


def test_a_folder_that_never_held_a_run_keeps_everything_of_its_own(tmp_path: Path) -> None:
    out = tmp_path / "project"
    (out / "export").mkdir(parents=True)
    (out / "export" / "mine.csv").write_text("x\n", encoding="utf-8")
    (out / "trips.csv").write_text("my own table\n", encoding="utf-8")
    with run_folder.writing(out) as staging:
        _fake_run(staging.path, {"summary.json": "{}"})
        staging.commit("completed")
    assert (out / "export" / "mine.csv").is_file() and (out / "trips.csv").read_text(
        encoding="utf-8"
    ) == "my own table\n"
    assert run_folder.member(out, "trips.csv") is None  # not this run's: readers do not take it
