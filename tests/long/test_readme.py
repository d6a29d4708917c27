"""Docs that are true: every shell command block of README.md and of every page of docs/guide/ (and
docs/performance.md) runs, in order, and succeeds.

The pages are found by :func:`doc_pages`: README.md, every ``docs/guide/*.md`` (a new page is picked up without
touching this file) and ``docs/performance.md``. Each page's ```` ```bash ```` blocks run as bash scripts
(``set -euo pipefail``) in a fresh folder of their own outside the clone, with the venv's ``bin`` first on
``PATH`` (``railsim``, ``python``, ``sumo``, ``sumo-gui``) and a world cache shared by the pages — so the commands
are also checked from a working directory that is not the clone, and a page never leans on another page's
outputs. The README's Python block runs there too. Other shell fences (``sh``, ``shell``, ``console``) are
refused, and only the README may hold a Python block, so no command escapes the check.

Every command must have an entry in :data:`PLAN` (one entry per distinct command; the same command on two pages
shares it); a command added to a page without one fails :func:`test_every_doc_command_is_planned` until someone
decides how the suite runs it, and an entry no page uses any more fails too. Where a full run would take minutes to
hours, the plan runs a smaller version — what changes and why:

* ``scenarios/`` in the folder is a copy of the clone's, with **small horizons**: in ``chongqing_line3_peak.yaml``
  (and the sweep base ``sweeps/line3_short.yaml``, the days ``chongqing_line3_day.yaml`` and
  ``chongqing_line3_day_depots.yaml``) every service's last departure is its first + 5 min (the days: + 20 min), and
  the peaks keep only the formations whose trips still exist; the sweep ``line3_headway_coupling.yaml`` keeps one
  headway (150 s) and one seed. Same commands, same flags.
* ``my_line.yaml`` and ``nets/my.net.xml`` + ``nets/stops.add.xml`` ("your own" files) are the test line
  ``tests/data/lines/mini_y.yaml`` and the passing-loop net of ``tests/sumo/test_external_net.py``.
* ``make demo``/``make test`` run as ``make -n`` (a dry run: the demo's two commands are in the next block; the
  test suite would run this test again).
* ``railsim study vc-vs-mb`` (about 50 min; tested in ``tests/long/test_study.py``), ``railsim robustness`` with 200
  runs, ``railsim reproduce`` of papers 000, 001 and 004 (minutes to hours) and four benchmarks
  (``optimizers_000``, ``controllers_000``, ``junction_planner``: minutes each; ``ab``: two trees under valgrind)
  run with ``--help``;
  ``benchmarks/engine.py`` gets the small peak as its scenario (one repetition), ``benchmarks/scale.py`` 8 and 16
  trains for 20 s, ``benchmarks/controllers_001.py`` a 500 m section, ``benchmarks/service_day.py`` 3 minutes,
  ``benchmarks/city_coupling.py`` one run of one formation; the Potsdam timetables 07:00-07:10.
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
GUIDE = ROOT / "docs" / "guide"
PERFORMANCE = ROOT / "docs" / "performance.md"
GUI = shutil.which("xvfb-run") is not None
GUI_ARGS = "--start --quit-on-end"
HELP = "--help"
SHELL_FENCES = ("sh", "shell", "console", "zsh", "shell-session")  # refused: write ```bash so the block is run


def doc_pages() -> list[Path]:
    """Every page whose shell blocks must run: the README, each guide page (found, not listed), performance."""
    return [README, *sorted(GUIDE.glob("*.md")), PERFORMANCE]


# command (comment stripped) -> the shell text the test runs instead (None: exactly the page's)
PLAN: dict[str, str | None] = {
    "make demo": f"make -n -C {ROOT} demo",
    "make test": f"make -n -C {ROOT} test",
    "railsim network build chongqing_line3 --out nets/": None,
    "railsim network show y_junction": None,
    "railsim network build my_line.yaml --out nets/": None,
    "railsim network show nets/my.net.xml -a nets/stops.add.xml": None,
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
    # line studies
    "railsim validate scenarios/sweeps/line3_headway_coupling.yaml": None,
    "railsim sweep scenarios/sweeps/line3_headway_coupling.yaml --out out/sweep --workers 2": None,
    "railsim report out/sweep": None,
    "railsim export out/sweep --format csv": None,
    (
        'railsim min-headway scenarios/chongqing_line3_peak.yaml --path "services[0].departures.headway_s" '
        '--lo 60 --hi 240 --set "formations=[]"'
    ): None,
    "railsim study vc-vs-mb --out out/study --workers 2": f"railsim study vc-vs-mb {HELP}",
    (
        "railsim study vc-vs-mb --out out/study_up --services airport_up --bisect --no-control --sensitivity "
        "--workers 2"
    ): f"railsim study vc-vs-mb {HELP}",
    # robustness
    (
        "railsim robustness scenarios/chongqing_line3_peak.yaml --disturbances scenarios/disturbances/line3_peak.yaml "
        "--runs 2 --headways 150 --services airport_up,airport_down --out out/rob_small --workers 2"
    ): None,
    "railsim robustness SCENARIO --runs 200 --headways 110,130,150 --out out/rob --workers 2": (
        f"railsim robustness {HELP}"
    ),
    (
        "railsim study vc-vs-mb --out out/study --disturbances scenarios/disturbances/line3_peak.yaml --runs 200 "
        "--robust-headways 110,130,150 --workers 2"
    ): f"railsim study vc-vs-mb {HELP}",
    # a service day
    "railsim run scenarios/chongqing_line3_day.yaml --out out/day": None,
    "railsim plot out/day --kind time-distance": None,
    "railsim run scenarios/chongqing_line3_day_depots.yaml --out out/depots": None,
    "railsim report out/depots": None,
    # paper experiments
    "railsim run scenarios/paper002_topology_switch.yaml --out out/paper002_run": None,
    "railsim plot out/ca_arrival --out fig/ca_arrival/": None,
    "railsim reproduce paper002 --out out/paper002": None,
    "railsim run scenarios/paper003_ca_arrival.yaml --out out/ca_arrival": None,
    "railsim reproduce paper000 --out out/paper000 --seeds 5": f"railsim reproduce {HELP}",
    "railsim reproduce paper001 --out out/paper001 --scenario B": f"railsim reproduce {HELP}",
    "railsim reproduce paper004 --out out/paper004 --workers 2": f"railsim reproduce {HELP}",
    # open data (the committed extracts and feed; a 20-minute window instead of the 2-hour peak; the Cologne import,
    # about 80 s, and a 20-run study only check their options)
    "railsim network import tests/data/osm/sao_paulo_centre_rail.osm.gz --out worlds/spo": (
        f"railsim network import {DATA}/osm/sao_paulo_centre_rail.osm.gz --out worlds/spo"
    ),
    (
        "railsim timetable import tests/data/gtfs/sao_paulo_rail_cut.zip --world worlds/spo --date 2019-10-01 "
        '--from 07:00 --to 09:00 --routes "METRÔ L2,METRÔ L3,METRÔ L4" --out spo_peak.yaml'
    ): (
        f"railsim timetable import {DATA}/gtfs/sao_paulo_rail_cut.zip --world worlds/spo --date 2019-10-01 "
        '--from 07:00 --to 07:20 --routes "METRÔ L2,METRÔ L3,METRÔ L4" --out spo_peak.yaml'
    ),
    "railsim run spo_peak.yaml --out out/spo_peak": None,
    "railsim plot out/spo_peak --kind time-distance --out fig/": None,
    (
        "railsim robustness spo_peak.yaml --runs 20 --disturbances scenarios/disturbances/generic_peak.yaml "
        "--out study/spo"
    ): f"railsim robustness {HELP}",
    "railsim network import tests/data/osm/jena_tram_2014.osm.gz --out worlds/jena": (
        f"railsim network import {DATA}/osm/jena_tram_2014.osm.gz --out worlds/jena"
    ),
    (
        "railsim timetable import --from-lines --headway-s 600 --world worlds/jena --from 07:00 --to 09:00 "
        "--out jena.yaml"
    ): (
        "railsim timetable import --from-lines --headway-s 600 --world worlds/jena --from 07:00 --to 07:20 "
        "--out jena.yaml && railsim validate jena.yaml"
    ),
    (
        "railsim network import tests/data/osm/cologne_stadtbahn.osm.gz --out worlds/koeln --light-rail-as-tram"
    ): f"railsim network import {HELP}",
    "railsim network import tests/data/osm/potsdam_tram_2025.osm.gz --out worlds/potsdam": (
        f"railsim network import {DATA}/osm/potsdam_tram_2025.osm.gz --out worlds/potsdam"
    ),
    (
        "railsim timetable import --from-lines --headway-s 720 --lines 91,93,94,99 --world worlds/potsdam "
        "--from 07:00 --to 09:00 --out potsdam.yaml"
    ): (
        "railsim timetable import --from-lines --headway-s 720 --lines 91,93,94,99 --world worlds/potsdam "
        "--from 07:00 --to 07:10 --out potsdam.yaml"
    ),
    "railsim run potsdam.yaml --out out/potsdam": None,
    "railsim network import tests/data/osm/dresden_tram_2025.osm.gz --out worlds/dresden": (
        f"railsim network import {DATA}/osm/dresden_tram_2025.osm.gz --out worlds/dresden"
    ),
    (
        "railsim timetable import --from-lines --headway-s 360 --world worlds/dresden --from 07:00 --to 09:00 "
        "--out dresden.yaml"
    ): (
        "railsim timetable import --from-lines --headway-s 360 --lines 10 --world worlds/dresden "
        "--from 07:00 --to 07:06 --out dresden.yaml"
    ),
    "railsim run dresden.yaml --out out/dresden": None,
    # coupling places on an imported city
    (
        ".venv/bin/python benchmarks/city_coupling.py --osm tests/data/osm/potsdam_tram_2025.osm.gz --runs 16 "
        "--out out/city_coupling"
    ): (
        f"python benchmarks/city_coupling.py --osm {DATA}/osm/potsdam_tram_2025.osm.gz --runs 1 --pairs 1 "
        "--out out/city_coupling"
    ),
    "railsim network import tests/data/osm/potsdam_tram_2025.osm.gz --out worlds/potsdam70 --platform-m 70": (
        f"railsim network import {DATA}/osm/potsdam_tram_2025.osm.gz --out worlds/potsdam70 --platform-m 70"
    ),
    (
        "railsim timetable import --from-lines --headway-s 720 --lines 91,93,94,99 --world worlds/potsdam70 "
        "--from 07:00 --to 09:00 --out potsdam_trunk.yaml"
    ): (
        "railsim timetable import --from-lines --headway-s 720 --lines 91,93,94,99 --world worlds/potsdam70 "
        "--from 07:00 --to 07:10 --out potsdam_trunk.yaml"
    ),
    "railsim run potsdam_trunk.yaml --out out/potsdam_trunk": None,
    # run folders
    "railsim run scenarios/chongqing_line3_peak.yaml --out out/peak": None,
    (
        'python -c \'import hashlib, json, pathlib; d = pathlib.Path("out/peak"); [print("ok " if '
        'hashlib.sha256((d / e["name"]).read_bytes()).hexdigest() == e["sha256"] else "BAD", e["name"]) '
        'for e in json.loads((d / ".railsim/manifest.json").read_text())["files"]]\''
    ): None,
    # benchmarks
    ".venv/bin/python benchmarks/engine.py": "python benchmarks/engine.py scenarios/chongqing_line3_peak.yaml --reps 1",
    ".venv/bin/python benchmarks/scale.py": "python benchmarks/scale.py --sizes 8,16 --horizon-s 20",
    ".venv/bin/python benchmarks/controllers_001.py": "python benchmarks/controllers_001.py 500",
    ".venv/bin/python benchmarks/optimizers_000.py": f"python benchmarks/optimizers_000.py {HELP}",
    ".venv/bin/python benchmarks/controllers_000.py": f"python benchmarks/controllers_000.py {HELP}",
    ".venv/bin/python benchmarks/junction_planner.py": f"python benchmarks/junction_planner.py {HELP}",
    ".venv/bin/python benchmarks/service_day.py": "python benchmarks/service_day.py --hours 0.05",
    ".venv/bin/python benchmarks/ab.py HEAD~1": f"python benchmarks/ab.py {HELP}",
}

# what a page's blocks must leave behind in its folder (pages not named here: only that every block succeeds)
PROMISED: dict[str, list[str]] = {
    "README.md": [
        "out/peak/summary.json",
        "out/peak/report.html",
        "out/peak/time-distance.png",
        "out/peak/speed.png",
        "out/sweep/cases.csv",
        "out/paper002",
    ],
    "run.md": ["out/peak/report.html", "fig/time-distance.png", "out/peak/export", "out/peak/time-distance.png"],
    "sumo-files-and-gui.md": ["out/peak/sumo_run.sumocfg", "out/fcd/sumo_fcd.xml"],
    "line-studies.md": ["out/sweep/cases.csv", "out/sweep/report.md"],
    "service-day.md": ["out/day/trips.csv", "out/day/time-distance.png", "out/depots/trips.csv"],
    "robustness.md": ["out/rob_small/robustness.md"],
    "open-data.md": ["worlds/spo", "spo_peak.yaml", "out/spo_peak/summary.json", "fig/time-distance.png", "jena.yaml"],
    "run-folders.md": ["out/peak/.railsim/manifest.json"],
    "paper-experiments.md": ["out/paper002_run/summary.json", "out/ca_arrival/summary.json", "fig/ca_arrival/gaps.png"],
}

_COMMENT = re.compile(r"\s+#\s.*$")


def fenced_blocks(path: Path, lang: str) -> list[list[str]]:
    """The page's fenced ``lang`` blocks; for shell blocks each line without its trailing comment."""
    blocks: list[list[str]] = []
    current: list[str] | None = None
    for line in path.read_text(encoding="utf-8").splitlines():
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


def readme_blocks(lang: str) -> list[list[str]]:
    return fenced_blocks(README, lang)


def _commands(path: Path) -> list[str]:
    return [c for block in fenced_blocks(path, "bash") for c in block]


def test_every_doc_command_is_planned() -> None:
    pages = doc_pages()
    assert (GUIDE / "README.md").is_file() and len(pages) >= 8, pages
    by_page = {p.relative_to(ROOT).as_posix(): _commands(p) for p in pages}
    assert by_page["README.md"], "no ```bash block found in README.md"
    unplanned = [(page, c) for page, cmds in by_page.items() for c in cmds if c not in PLAN]
    assert not unplanned, f"doc commands without an entry in tests/long/test_readme.py PLAN: {unplanned}"
    used = {c for cmds in by_page.values() for c in cmds}
    stale = [c for c in PLAN if c not in used]
    assert not stale, f"PLAN entries no page uses any more: {stale}"


def test_docs_fence_shell_as_bash_and_python_only_in_the_readme() -> None:
    """A ```sh or ```console block would not be run; a Python block outside the README would not be either, but for
    the extension sketch of docs/architecture.md, which tests/unit/test_extensions.py runs."""
    for page in [*doc_pages(), *sorted((ROOT / "docs").glob("*.md"))]:
        fences = {line.strip()[3:] for line in page.read_text(encoding="utf-8").splitlines() if line.startswith("```")}
        assert not fences & set(SHELL_FENCES), f"{page}: use ```bash for shell commands (they are run), got {fences}"
        if page not in (README, ROOT / "docs" / "architecture.md"):
            assert "python" not in fences, f"{page}: a Python block here is not run; show it in README.md or as bash"


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
    _edit(work / "scenarios" / "chongqing_line3_day_depots.yaml", _small_day)
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


@pytest.fixture(scope="session")
def world_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One world cache for every page of this worker: Line 3 is built once, not once per page."""
    return tmp_path_factory.mktemp("readme_cache")


def _env(cache: Path) -> dict[str, str]:
    bin_dir = str(Path(sys.executable).parent)
    return dict(os.environ, PATH=bin_dir + os.pathsep + os.environ.get("PATH", ""), RAILSIM_CACHE=str(cache))


def _page_id(page: Path) -> str:
    return page.relative_to(ROOT).as_posix()


@pytest.mark.timeout(3600)  # the README alone takes about 5 min on an idle 2-core machine; more under load
@pytest.mark.parametrize("page", [p for p in doc_pages() if _commands(p)], ids=_page_id)
def test_every_doc_block_runs_from_another_folder(page: Path, tmp_path: Path, world_cache: Path) -> None:
    work = _workdir(tmp_path)
    env = _env(world_cache)
    for n, block in enumerate(fenced_blocks(page, "bash")):
        script = "\n".join(["set -euo pipefail", *(PLAN[c] or c for c in block)])
        res = subprocess.run(["bash", "-c", script], cwd=work, env=env, capture_output=True, text=True, timeout=1200)
        assert res.returncode == 0, (
            f"{_page_id(page)} bash block {n} failed:\n{script}\n{res.stdout[-3000:]}\n{res.stderr[-3000:]}"
        )
        assert "Traceback" not in res.stderr, f"{_page_id(page)} block {n}:\n{res.stderr[-3000:]}"
    missing = [p for p in PROMISED.get(page.name, []) if not (work / p).exists()]
    assert not missing, f"{_page_id(page)}: its commands did not write {missing}"


def test_readme_python_block_runs_from_another_folder(tmp_path: Path, world_cache: Path) -> None:
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
        [sys.executable, "-c", code], cwd=work, env=_env(world_cache), capture_output=True, text=True, timeout=900
    )
    assert res.returncode == 0, res.stderr[-3000:]
    assert (work / "out" / "peak" / "summary.json").is_file()
