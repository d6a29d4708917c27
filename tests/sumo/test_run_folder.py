"""A run folder holds one run, written as a whole (railsim.record.run_folder), checked by running railsim.

Each test constructs the case that used to leave a folder lying: a re-run without disturbances beside an earlier
run's ``delays.csv``; a re-run that hits a file-size limit mid-write; two runs started into one folder.
"""

from __future__ import annotations

import hashlib
import json
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import yaml

from tests.helpers import DATA, ROOT, railsim_cmd, read_summary, run_railsim

DISTURBED = DATA / "scenarios" / "disturbed_line.yaml"


def _manifest_matches_folder(out: Path) -> dict:
    """The manifest lists exactly the folder's files, with their sizes and hashes."""
    manifest = json.loads((out / ".railsim" / "manifest.json").read_text(encoding="utf-8"))
    on_disk = sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.is_file() and ".railsim" not in p.parts)
    assert sorted(e["name"] for e in manifest["files"]) == on_disk
    for e in manifest["files"]:
        data = (out / e["name"]).read_bytes()
        assert len(data) == e["bytes"] and hashlib.sha256(data).hexdigest() == e["sha256"], e["name"]
    return manifest


def _undisturbed_copy(tmp_path: Path) -> Path:
    data = yaml.safe_load(DISTURBED.read_text(encoding="utf-8"))
    del data["disturbances"]
    path = tmp_path / "undisturbed.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def test_rerun_without_disturbances_does_not_read_the_earlier_runs_delays(tmp_path: Path) -> None:
    out, cache = tmp_path / "out", tmp_path / "cache"
    first = run_railsim(["run", str(DISTURBED), "--out", str(out), "--no-progress"], cache_dir=cache)
    assert first.returncode == 0, first.stderr
    assert "robustness" in read_summary(out) and (out / "delays.csv").is_file()
    second = run_railsim(["run", str(_undisturbed_copy(tmp_path)), "--out", str(out), "--no-progress"], cache_dir=cache)
    assert second.returncode == 0, second.stderr
    summary = read_summary(out)
    assert "robustness" not in summary, "the second run's summary holds the first run's punctuality"
    assert not (out / "delays.csv").exists(), "the first run's delays.csv is still in the folder"
    assert _manifest_matches_folder(out)["status"] == "completed"
    report = run_railsim(["report", str(out)], cache_dir=cache)
    assert report.returncode == 0, report.stderr
    assert (
        "Punctuality" not in (out / "report.md").read_text(encoding="utf-8") if (out / "report.md").exists() else True
    )
    assert not list(tmp_path.glob(".out.*")), "staging folder or lock left behind"


def _limit_file_size(limit_bytes: int):
    def preexec() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))

    return preexec


def test_file_size_limit_mid_write_is_exit_3_and_leaves_the_folder_as_it_was(tmp_path: Path) -> None:
    out, cache = tmp_path / "out", tmp_path / "cache"
    first = run_railsim(["run", str(DISTURBED), "--out", str(out), "--seed", "1", "--no-progress"], cache_dir=cache)
    assert first.returncode == 0, first.stderr
    before = _manifest_matches_folder(out)
    trace_bytes = (out / "trace.csv").stat().st_size
    assert trace_bytes > 100_000  # the limit below falls inside trace.csv's write
    env = dict(os.environ, RAILSIM_CACHE=str(cache))
    res = subprocess.run(
        [*railsim_cmd(), "run", str(DISTURBED), "--out", str(out), "--seed", "2", "--no-progress"],
        capture_output=True,
        text=True,
        timeout=600,
        env=env,
        cwd=ROOT,
        preexec_fn=_limit_file_size(64_000),
    )
    assert res.returncode == 3, (res.returncode, res.stderr)
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in res.stderr, res.stderr
    assert "trace.csv" in lines[0] and "File too large" in lines[0] and str(out) in lines[0], lines[0]
    assert read_summary(out)["seed"] == 1, "the folder no longer holds the first run"
    assert _manifest_matches_folder(out) == before
    assert not list(tmp_path.glob(".out.staging-*")), "the failed run's staging folder was left behind"


def _long_run(tmp_path: Path) -> Path:
    """The disturbed line with 30 trains: a run long enough (tens of seconds) to start another one inside it."""
    data = yaml.safe_load(DISTURBED.read_text(encoding="utf-8"))
    data["services"][0]["departures"] = {"times": [120.0 * k for k in range(30)]}
    data["simulation"]["duration_s"] = 6000
    path = tmp_path / "long.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def test_a_second_run_into_a_folder_in_use_is_refused(tmp_path: Path) -> None:
    out, cache = tmp_path / "out", tmp_path / "cache"
    long_run = _long_run(tmp_path)
    warm = run_railsim(["validate", str(long_run)], cache_dir=cache)  # build the world before timing anything
    assert warm.returncode == 0, warm.stderr
    env = dict(os.environ, RAILSIM_CACHE=str(cache))
    first = subprocess.Popen(
        [*railsim_cmd(), "run", str(long_run), "--out", str(out), "--seed", "1", "--no-progress"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        cwd=ROOT,
    )
    lock = tmp_path / ".out.lock"
    deadline = time.monotonic() + 120
    while not lock.exists() and first.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    assert lock.exists(), "the first run never took the folder's lock"
    second = run_railsim(["run", str(long_run), "--out", str(out), "--seed", "2", "--no-progress"], cache_dir=cache)
    assert first.poll() is None, "the first run ended before the second started: the case was not constructed"
    _, err = first.communicate(timeout=600)
    assert first.returncode == 0, err
    assert second.returncode == 3, second.stderr
    assert len(second.stderr.strip().splitlines()) == 1 and "in use" in second.stderr
    assert f"pid {first.pid}" in second.stderr
    assert read_summary(out)["seed"] == 1
    _manifest_matches_folder(out)
    assert not lock.exists()


def _interactive_sigint() -> None:
    """In the child before exec: SIGINT as an interactive shell leaves it (default). A test worker may run with
    SIGINT ignored, which a child inherits and railsim rightly keeps (as for a background job): the Ctrl-C then
    never came, and the run finished with 0."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_during_start_up_is_one_line_and_130(tmp_path: Path) -> None:
    """SIGINT at several moments of start-up (imports, scenario, world): never a traceback, always 130."""
    env = dict(os.environ, RAILSIM_CACHE=str(tmp_path / "cache"))
    finished_first: list[float] = []  # delays by which the whole run was over (a fast machine, warm caches)
    for delay_s in (0.15, 0.4, 0.8, 1.5, 3.0):
        proc = subprocess.Popen(
            [sys.executable, "-m", "railsim.cli", "run", str(DISTURBED), "--out", str(tmp_path / "o"), "--no-progress"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=env,
            cwd=ROOT,
            preexec_fn=_interactive_sigint,
        )
        time.sleep(delay_s)
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
        if proc.returncode == 0 and delay_s >= 1.5:  # the run ended before the signal came: nothing to interrupt
            finished_first.append(delay_s)
            continue
        assert "Traceback" not in err, (delay_s, err)
        assert proc.returncode == 130, (delay_s, proc.returncode, err)
        assert len(err.strip().splitlines()) == 1, (delay_s, err)
