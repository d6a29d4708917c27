"""Issue 21, "a README that is true": every shell command block of README.md runs, in order, and succeeds.

The blocks run as bash scripts (``set -euo pipefail``) in a fresh folder outside the clone, with the venv's
``bin`` first on ``PATH`` (``railsim``, ``python``, ``sumo``, ``sumo-gui``) and a shared world cache — so the
commands are also checked from a working directory that is not the clone. The Python block runs there too.

Every README command must have an entry in :data:`PLAN`; a command added to the README without one fails
:func:`test_every_readme_command_is_planned` until someone decides how the suite runs it. Where a full run would
take minutes to hours, the plan runs a smaller version — what changes and why:

* ``scenarios/`` in the folder is a copy of the clone's, with **small horizons**: in ``chongqing_line3_peak.yaml``
  (and the sweep base ``sweeps/line3_short.yaml``, the day ``chongqing_line3_day.yaml``) every service's last
  departure is its first + 5 min (the day: + 20 min), and the peaks keep only the formations whose trips still
  exist; the sweep ``line3_headway_coupling.yaml`` keeps one headway (150 s) and one seed. Same commands, same
  flags.
* ``my_line.yaml`` and ``nets/my.net.xml`` + ``nets/stops.add.xml`` ("your own" files) are the test line
  ``tests/data/lines/mini_y.yaml`` and the passing-loop net of ``tests/sumo/test_external_net.py``.
* ``make demo``/``make test`` run as ``make -n`` (a dry run: the demo's two commands are in the next block; the
  test suite would run this test again).
* ``railsim study vc-vs-mb`` (about 50 min; tested in ``tests/long/test_study.py``) and three benchmarks
  (``optimizers_000``, ``controllers_000``, ``junction_planner``: minutes each) run with ``--help``;
  ``benchmarks/engine.py`` gets the small peak as its scenario (one repetition), ``benchmarks/scale.py`` 8 and 16
  trains for 20 s, ``benchmarks/controllers_001.py`` a 500 m section.
* sumo-gui commands run under ``xvfb-run`` (a virtual display; apt: xvfb) and quit at the end; where there is
  no ``xvfb-run`` they only check that ``sumo-gui`` is on the PATH. The replay command replays a 600 s run
  of the small peak's Airport units with ``outputs.sumo: [fcd]`` made just before it.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

from railsim.scenario import format_clock, parse_clock
from tests.helpers import DATA, ROOT

README = ROOT / "README.md"
GUI = shutil.which("xvfb-run") is not None
GUI_ARGS = "--start --quit-on-end"
SUMO_GUI = "xvfb-run -a sumo-gui" if GUI else None
HELP = "--help"

# README command (comment stripped) -> the shell text the test runs instead (None: exactly the README's)
PLAN: dict[str, str | None] = {
    "make demo": f"make -n -C {ROOT} demo",
    "make test": f"make -n -C {ROOT} test",
    "railsim network build chongqing_line3 --out nets/": None,
    "railsim network show y_junction": None,
    "railsim network build my_line.yaml --out nets/": None,
    "railsim validate scenarios/chongqing_line3_peak.yaml": None,
    "railsim run scenarios/chongqing_line3_peak.yaml --out out/peak --seed 7": None,
    "railsim run scenarios/chongqing_line3_peak.yaml --out out/peak_gui --gui": (
        "xvfb-run -a railsim run scenarios/chongqing_line3_peak.yaml --out out/peak_gui --gui"
        if GUI
        else "command -v sumo-gui"
    ),
    "sumo-gui -c out/peak/sumo_run.sumocfg": (
        f"xvfb-run -a sumo-gui -c out/peak/sumo_run.sumocfg {GUI_ARGS}" if GUI else "command -v sumo-gui"
    ),
    "export SUMO_HOME=\"$(python -c 'import sumo; print(sumo.SUMO_HOME)')\"": None,
    'python "$SUMO_HOME/tools/fcdReplay.py" -k out/fcd/sumo_replay.sumocfg -f out/fcd/sumo_fcd.xml': (
        "railsim run scenarios/peak_fcd.yaml --out out/fcd && "
        + (
            'xvfb-run -a python "$SUMO_HOME/tools/fcdReplay.py" -k out/fcd/sumo_replay.sumocfg '
            f"-f out/fcd/sumo_fcd.xml {GUI_ARGS}"
            if GUI
            else 'test -f "$SUMO_HOME/tools/fcdReplay.py" -a -f out/fcd/sumo_replay.sumocfg -a -f out/fcd/sumo_fcd.xml'
        )
    ),
    "railsim plot out/peak": None,
    "railsim plot out/peak --kind time-distance --out fig/": None,
    "railsim export out/peak --format parquet": None,
    "railsim report out/peak --format html": None,
    "railsim sweep scenarios/sweeps/line3_headway_coupling.yaml --out out/sweep --workers 2": None,
    (
        'railsim min-headway scenarios/chongqing_line3_peak.yaml --path "services[0].departures.headway_s" '
        '--lo 60 --hi 240 --set "formations=[]"'
    ): None,
    "railsim study vc-vs-mb --out out/study --workers 2": f"railsim study vc-vs-mb {HELP}",
    (
        "railsim study vc-vs-mb --out out/study_up --services airport_up --bisect --no-control --sensitivity "
        "--workers 2"
    ): f"railsim study vc-vs-mb {HELP}",
    "railsim report out/sweep": None,
    "railsim robustness SCENARIO --runs 200 --headways 110,130,150 --out out/rob --workers 2": (
        f"railsim robustness {HELP}"
    ),
    (
        "railsim study vc-vs-mb --out out/study --disturbances scenarios/disturbances/line3_peak.yaml --runs 200 "
        "--robust-headways 110,130,150 --workers 2"
    ): f"railsim study vc-vs-mb {HELP}",
    "railsim network show nets/my.net.xml -a nets/stops.add.xml": None,
    "railsim run scenarios/chongqing_line3_day.yaml --out out/day": None,
    ".venv/bin/python benchmarks/engine.py": "python benchmarks/engine.py scenarios/chongqing_line3_peak.yaml --reps 1",
    ".venv/bin/python benchmarks/scale.py": "python benchmarks/scale.py --sizes 8,16 --horizon-s 20",
    ".venv/bin/python benchmarks/controllers_001.py": "python benchmarks/controllers_001.py 500",
    ".venv/bin/python benchmarks/optimizers_000.py": f"python benchmarks/optimizers_000.py {HELP}",
    ".venv/bin/python benchmarks/controllers_000.py": f"python benchmarks/controllers_000.py {HELP}",
    ".venv/bin/python benchmarks/junction_planner.py": f"python benchmarks/junction_planner.py {HELP}",
    ".venv/bin/python benchmarks/service_day.py": "python benchmarks/service_day.py --hours 0.05",
}

_COMMENT = re.compile(r"\s+#\s.*$")


def readme_blocks(lang: str) -> list[list[str]]:
    """The README's fenced ``lang`` blocks; for shell blocks each line without its trailing comment."""
    blocks, current = [], None
    for line in README.read_text(encoding="utf-8").splitlines():
        if current is None and line.strip() == f"```{lang}":
            current = []
        elif current is not None and line.strip() == "```":
            blocks.append(current)
            current = None
        elif current is not None:
            text = _COMMENT.sub("", line).strip() if lang == "bash" else line
            if text:
                current.append(text)
    return blocks


def test_every_readme_command_is_planned() -> None:
    commands = [c for block in readme_blocks("bash") for c in block]
    assert commands, "no ```bash block found in README.md"
    unplanned = [c for c in commands if c not in PLAN]
    assert not unplanned, f"README commands without an entry in tests/long/test_readme.py PLAN: {unplanned}"
    stale = [c for c in PLAN if c not in commands]
    assert not stale, f"PLAN entries no longer in README.md: {stale}"


# ------------------------------------------------------------------------------------------- the small copies
def _last_after_first(services: list[dict[str, Any]], minutes: float) -> None:
    for svc in services:
        dep = svc["departures"]
        if isinstance(dep, dict) and "first" in dep and "last" in dep:
            dep["last"] = format_clock(parse_clock(str(dep["first"])) + 60 * minutes)


def _edit(path: Path, change: Any) -> None:
    raw = yaml.safe_load(path.read_text(encoding="utf-8"))
    change(raw)
    path.write_text(yaml.safe_dump(raw, sort_keys=False, allow_unicode=True), encoding="utf-8")


def _small_peak(raw: dict[str, Any]) -> None:
    _last_after_first(raw["services"], 5)
    # the formations whose trips still exist: trip 0 of each service
    raw["formations"] = [f for f in raw.get("formations", []) if f["leader"]["trip"] == 0 == f["follower"]["trip"]]


def _small_day(raw: dict[str, Any]) -> None:
    """The day's first 20 minutes: the peak pairs (services timed after the Airport units' peak trips, and their
    formations) start later, so they go."""
    raw["services"] = [s for s in raw["services"] if "after" not in s["departures"]]
    raw.pop("formations", None)
    _last_after_first(raw["services"], 20)


def _small_sweep(raw: dict[str, Any]) -> None:
    raw["grid"] = {path: [150] for path in raw["grid"]}
    raw["seeds"] = raw["seeds"][:1]


def _workdir(tmp: Path) -> Path:
    from tests.sumo.test_external_net import build_passing_loop

    work = tmp / "work"
    shutil.copytree(ROOT / "scenarios", work / "scenarios")
    _edit(work / "scenarios" / "chongqing_line3_peak.yaml", _small_peak)
    _edit(work / "scenarios" / "sweeps" / "line3_short.yaml", _small_peak)
    _edit(work / "scenarios" / "sweeps" / "line3_headway_coupling.yaml", _small_sweep)
    _edit(work / "scenarios" / "chongqing_line3_day.yaml", _small_day)
    fcd = yaml.safe_load((work / "scenarios" / "chongqing_line3_peak.yaml").read_text(encoding="utf-8"))
    fcd["simulation"]["duration_s"] = 600  # the Airport units only: all inserted by then (a Jurenba unit waits)
    fcd["services"], fcd["formations"] = fcd["services"][:2], []
    fcd["outputs"]["sumo"] = ["fcd"]
    (work / "scenarios" / "peak_fcd.yaml").write_text(yaml.safe_dump(fcd, sort_keys=False), encoding="utf-8")
    shutil.copy(DATA / "lines" / "mini_y.yaml", work / "my_line.yaml")
    (tmp / "loop").mkdir()
    net, stops = build_passing_loop(tmp / "loop")
    (work / "nets").mkdir()
    shutil.copy(net, work / "nets" / "my.net.xml")
    shutil.copy(stops, work / "nets" / "stops.add.xml")
    (work / "benchmarks").symlink_to(ROOT / "benchmarks")
    return work


def _env(tmp: Path) -> dict[str, str]:
    bin_dir = str(Path(sys.executable).parent)
    return dict(os.environ, PATH=bin_dir + os.pathsep + os.environ.get("PATH", ""), RAILSIM_CACHE=str(tmp / "cache"))


@pytest.mark.timeout(3600)  # about 5 min on an idle 2-core machine; the suite's 900 s is too tight under load
def test_every_readme_block_runs_from_another_folder(tmp_path: Path) -> None:
    work = _workdir(tmp_path)
    env = _env(tmp_path)
    for n, block in enumerate(readme_blocks("bash")):
        script = "\n".join(["set -euo pipefail", *(PLAN[c] or c for c in block)])
        res = subprocess.run(["bash", "-c", script], cwd=work, env=env, capture_output=True, text=True, timeout=1200)
        assert res.returncode == 0, (
            f"README bash block {n} failed:\n{script}\n{res.stdout[-3000:]}\n{res.stderr[-3000:]}"
        )
        assert "Traceback" not in res.stderr, f"block {n}:\n{res.stderr[-3000:]}"
    # what the blocks promise exists
    assert (work / "out" / "peak" / "summary.json").is_file() and (work / "out" / "peak" / "report.html").is_file()
    assert {p.name for p in (work / "out" / "peak").glob("*.png")} >= {"time-distance.png", "speed.png"}
    assert (work / "fig" / "time-distance.png").is_file()
    assert (work / "out" / "sweep" / "cases.csv").is_file() and (work / "out" / "day" / "trips.csv").is_file()


def test_readme_python_block_runs_from_another_folder(tmp_path: Path) -> None:
    (block,) = readme_blocks("python")
    code = "\n".join(block)
    original = 'scenario.load(scenario.shipped("chongqing_line3_peak"))'
    assert original in code
    # small horizon, as for the shell blocks: the first 5 minutes of departures, formation vc0 only
    small = (
        'scenario.load(scenario.shipped("chongqing_line3_peak"), {'
        '"services[0].departures.last": "07:35", "services[1].departures.last": "07:35", '
        '"services[2].departures.last": "07:35", "services[3].departures.last": "07:40", '
        '"formations": [scenario.load(scenario.shipped("chongqing_line3_peak")).raw["formations"][0]]})'
    )
    code = code.replace(original, small) + "\nassert summary['n_arrived'] == summary['n_trains'] > 0, summary\n"
    work = tmp_path / "elsewhere"
    work.mkdir()
    res = subprocess.run(
        [sys.executable, "-c", code], cwd=work, env=_env(tmp_path), capture_output=True, text=True, timeout=900
    )
    assert res.returncode == 0, res.stderr[-3000:]
    assert (work / "out" / "peak" / "summary.json").is_file()
