"""Every run folder opens in SUMO's own tools; ``railsim run --gui`` is the same run.

A real run of the mini Y line (child process) with ``outputs.sumo: [fcd]`` must leave ``sumo_vtypes.rou.xml``,
``sumo_routes.rou.xml`` (every inserted train), ``sumo_run.sumocfg`` and ``sumo_replay.sumocfg``; headless
``sumo`` (the eclipse-sumo binary) loads each config and runs 10 s (and the run config to the end) without an
error. Under a virtual X server (``xvfb-run``; skipped where there is none) ``--gui`` runs the scenario in
sumo-gui through traci and writes the same files, byte for byte, as the libsumo run.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml

from railsim.engine import sumo_files
from tests.helpers import DATA, ROOT, railsim_cmd, read_summary, run_railsim


def _scenario(tmp_path: Path) -> Path:
    raw = yaml.safe_load((DATA / "scenarios" / "mini_line.yaml").read_text())
    raw["world"] = {"line": str(DATA / "lines" / "mini_y.yaml")}
    raw["outputs"]["sumo"] = ["fcd"]
    path = tmp_path / "mini_fcd.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def _sumo_binary() -> str:
    import sumo  # the eclipse-sumo wheel

    return str(Path(sumo.SUMO_HOME) / "bin" / "sumo")


def test_the_run_folder_loads_in_headless_sumo(tmp_path: Path) -> None:
    out = tmp_path / "out"
    res = run_railsim(["run", str(_scenario(tmp_path)), "--out", str(out), "--no-progress"])
    assert res.returncode == 0, res.stderr[-2000:]
    for name in (sumo_files.VTYPES_FILE, sumo_files.ROUTES_FILE, sumo_files.RUN_CONFIG, sumo_files.REPLAY_CONFIG):
        assert (out / name).is_file(), name
    routes = (out / sumo_files.ROUTES_FILE).read_text()
    assert routes.count("<vehicle ") == read_summary(out)["n_inserted"] == 7
    for cfg, end in ((sumo_files.RUN_CONFIG, "10"), (sumo_files.REPLAY_CONFIG, "10"), (sumo_files.RUN_CONFIG, "-1")):
        run = subprocess.run(
            [_sumo_binary(), "-c", str(out / cfg), "--end", end, "--no-warnings", "false"],
            capture_output=True,
            text=True,
            timeout=120,
            cwd=tmp_path,  # relative file names resolve against the config, not the working directory
        )
        assert run.returncode == 0 and "Error" not in run.stderr + run.stdout, (cfg, run.stderr[-2000:])


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="no xvfb-run (apt: xvfb) for a virtual display")
def test_gui_run_is_the_same_run_in_sumo_gui(tmp_path: Path) -> None:
    scn = _scenario(tmp_path)
    env = dict(os.environ, RAILSIM_CACHE=str(tmp_path / "c"))
    outs = {}
    for mode, extra, prefix in (("lib", [], []), ("gui", ["--gui"], ["xvfb-run", "-a"])):
        outs[mode] = tmp_path / mode
        cmd = prefix + railsim_cmd() + ["run", str(scn), "--out", str(outs[mode]), "--no-progress", *extra]
        res = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=env, cwd=ROOT)
        assert res.returncode == 0, res.stderr[-2000:]
    for name in ("trips.csv", "stops.csv", "events.csv", "trace.csv", "formations.csv", sumo_files.ROUTES_FILE):
        assert (outs["gui"] / name).read_bytes() == (outs["lib"] / name).read_bytes(), name
