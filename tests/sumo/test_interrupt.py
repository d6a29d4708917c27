"""Ctrl-C or SIGTERM on ``railsim run`` writes what the run has, then exits 130/143.

A real ``railsim run`` (child process, real SUMO) of a two-hour variant of the mini Y line gets the signal
shortly after its step loop starts (the ``-v`` log line "simulating …"). It must exit with ``128 + signal``,
and its folder must hold every table up to the simulated time reached and ``summary.json`` with
``status: interrupted``, the signal and that time. Output files follow the umask (0644 under umask 022).
"""

from __future__ import annotations

import os
import signal
import stat
import subprocess
import time
from pathlib import Path

import pytest
import yaml

from tests.helpers import DATA, ROOT, railsim_cmd, read_csv, read_summary

HORIZON_S = 7200


def _long_run(tmp_path: Path) -> Path:
    raw = yaml.safe_load((DATA / "scenarios" / "mini_line.yaml").read_text())
    raw["world"] = {"line": str(DATA / "lines" / "mini_y.yaml")}
    raw["simulation"]["duration_s"] = HORIZON_S
    raw["services"][0]["departures"] = {"times": list(range(0, HORIZON_S - 600, 120))}
    raw["services"][2]["departures"] = {"times": list(range(30, HORIZON_S - 600, 120))}
    path = tmp_path / "long.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


@pytest.mark.parametrize(("sig", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_signal_writes_partial_outputs_and_status_interrupted(tmp_path: Path, sig: int, code: int) -> None:
    out = tmp_path / "out"
    env = dict(os.environ, RAILSIM_CACHE=str(tmp_path / "cache"))
    cmd = railsim_cmd() + ["-v", "run", str(_long_run(tmp_path)), "--out", str(out), "--no-progress"]
    old_mask = os.umask(0o022)
    try:
        proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    finally:
        os.umask(old_mask)
    assert proc.stderr is not None
    seen = []
    for line in proc.stderr:  # wait until the step loop runs (the world is built by then)
        seen.append(line)
        if "simulating mini_line" in line:
            break
    else:
        pytest.fail("the run ended before its step loop started: " + "".join(seen)[-2000:])
    time.sleep(1.0)
    proc.send_signal(sig)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == code, "".join(seen) + stderr[-2000:]
    assert f"interrupted ({signal.Signals(sig).name})" in stdout
    assert "Traceback" not in stderr

    s = read_summary(out)
    assert s["status"] == "interrupted" and s["interrupted_by"] == signal.Signals(sig).name
    assert 0.0 < s["sim_s"] < HORIZON_S
    trips = read_csv(out / "trips.csv")
    assert len(trips) == s["n_trains"] == 2 * len(range(0, HORIZON_S - 600, 120)) + 2
    assert s["n_arrived"] == sum(1 for r in trips if r["status"] == "arrived")
    assert any(r["status"] == "scheduled" for r in trips)  # the run stopped before the last departures
    events = read_csv(out / "events.csv")
    assert events and max(float(e["t_s"]) for e in events) <= s["sim_s"]
    trace = read_csv(out / "trace.csv")
    assert trace and max(float(r["t_s"]) for r in trace) <= s["sim_s"]
    for f in ("trips.csv", "stops.csv", "formations.csv", "events.csv", "trace.csv", "summary.json"):
        assert stat.S_IMODE((out / f).stat().st_mode) == 0o644, f


def test_a_signal_after_the_last_step_stops_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The signal lands after the step loop has ended on its own (here: in the end-of-run checks, before the
    outputs are written). The run is complete, so it must say ``completed`` and exit as it ran, not claim an
    interruption that stopped nothing (that case once gave exit 130 without the line on stderr)."""
    from railsim import api, scenario
    from railsim.engine.interrupt import StopRequest
    from railsim.engine.watchdog import StallWatch

    stop = StopRequest()
    at_end = StallWatch.at_end

    def late_signal(self: StallWatch, t: float) -> None:
        stop.request(signal.SIGINT)  # as the handler does when the Ctrl-C comes
        at_end(self, t)

    monkeypatch.setattr(StallWatch, "at_end", late_signal)
    summary = api.run(scenario.load(DATA / "scenarios" / "mini_line.yaml"), tmp_path / "out", stop=stop)
    assert stop.signum == signal.SIGINT  # the signal did come
    assert summary["status"] == "completed" and summary["interrupted_by"] is None
    assert read_summary(tmp_path / "out")["status"] == "completed"
    assert summary["n_arrived"] == summary["n_trains"] > 0
