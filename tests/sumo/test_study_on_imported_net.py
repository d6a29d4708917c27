"""``railsim study vc-vs-mb`` on a world imported from OpenStreetMap (Potsdam's trunk shared by lines 91 and 99):
the analytic floors read the imported net (stations named as the import wrote them), and the capacity analysis
takes the sections only a follower ran (before its formation's merge) and a route that stops twice at one
station. Each of the three failed the study with an internal error."""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import ok_stdout, run_railsim

DATA = Path(__file__).resolve().parents[1] / "data"


def test_the_vc_vs_mb_study_runs_on_an_imported_city(tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    world = tmp_path / "potsdam"
    osm = DATA / "osm" / "potsdam_tram_2025.osm.gz"
    ok_stdout(run_railsim(["network", "import", str(osm), "--out", str(world), "--platform-m", "70"], cache_dir=cache))
    text = (DATA / "scenarios" / "potsdam_trunk_mb.yaml").read_text(encoding="utf-8").replace("WORLD", str(world))
    mb = yaml.safe_load(text)
    vc = {
        **mb,
        "name": "potsdam_trunk_vc",
        "formations": [
            {
                "id": "vc",
                "pairs": {"leader": "91_rehbrucke_pirschheide", "follower": "99_bisamkiez_fontanestrasse"},
                "target_gap_m": 10,
                "couple": {"at_station": "Waldstraße/Horstweg"},
                "decouple": {"at_station": "S Potsdam Hauptbahnhof"},
            }
        ],
    }
    for name, scn in (("mb", mb), ("vc", vc)):
        (tmp_path / f"{name}.yaml").write_text(yaml.safe_dump(scn, sort_keys=False, allow_unicode=True))
    args = ["study", "vc-vs-mb", "--mb", str(tmp_path / "mb.yaml"), "--vc", str(tmp_path / "vc.yaml")]
    args += ["--services", "91_rehbrucke_pirschheide", "--headway", "600", "--no-control", "--no-progress"]
    out = ok_stdout(run_railsim([*args, "--out", str(tmp_path / "study")], cache_dir=cache))
    assert "(a) moving block: minimum headway 600 s" in out and "(b) virtual coupling: minimum headway 600 s" in out
    report = (tmp_path / "study" / "vc_vs_mb.md").read_text(encoding="utf-8")
    assert "## Analytic floors" in report
    formations_row = next(line for line in report.splitlines() if line.startswith("| formations coupling"))
    assert "| 0 / – | 7 / 10 m |" in formations_row  # the 7 line-99 trams (07:00-08:00) each coupled to its leader
