"""``railsim report``: one Markdown or self-contained HTML page for a run or a sweep, from real outputs.

Pinned: the run report holds the summary, running times per service (values checked against trips.csv with the
csv module), stops, formations and the capacity tables, and every figure it links exists and is a PNG/SVG; the
HTML page embeds every figure and links no file; a real two-case sweep gives its cases table, both case ids and
a metric-vs-parameter figure; mistakes exit 2 with one line.
"""

from __future__ import annotations

import re
import statistics
from pathlib import Path

import pandas as pd
import pytest
import yaml

from railsim.cli.main import main as cli_main
from railsim.report import document as report
from tests.helpers import DATA, ROOT, read_csv, run_railsim

MINI = DATA / "scenarios" / "mini_line.yaml"
CORRIDOR = ROOT / "scenarios" / "sweeps" / "corridor_small.yaml"
LINK_RE = re.compile(r"\]\(([^)]+)\)")


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("report") / "mini"
    res = run_railsim(["run", str(MINI), "--out", str(out), "--no-progress"])
    assert res.returncode == 0, res.stderr + res.stdout
    return out


@pytest.fixture(scope="module")
def run_md(run_dir: Path) -> str:
    path = report.write_report(run_dir, "md")
    assert path == run_dir / "report.md"
    return path.read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    tmp = tmp_path_factory.mktemp("report_sweep")
    spec = {
        "name": "report_test",
        "description": "two headways on the small corridor",
        "base": str(CORRIDOR),
        "cases": [{"services[0].departures.last": 240, "services[1].departures.last": 240}],  # short runs
        "grid": {"services[0].departures.headway_s": [60, 120]},
        "link": {"services[1].departures.headway_s": "services[0].departures.headway_s"},
    }
    (tmp / "sweep.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    out = tmp / "out"
    res = run_railsim(["sweep", str(tmp / "sweep.yaml"), "--out", str(out), "--workers", "1"])
    assert res.returncode == 0, res.stderr + res.stdout
    return out


def _section(md: str, heading: str) -> str:
    part = md.split(f"\n{heading}\n", 1)[1]
    return re.split(r"\n#{1,2} ", part, maxsplit=1)[0]


def _rows(table_md: str) -> list[list[str]]:
    lines = [ln for ln in table_md.splitlines() if ln.startswith("|")]
    return [[c.strip() for c in ln.strip().strip("|").split("|")] for ln in lines[2:]]


def test_run_report_has_the_key_tables(run_md: str, run_dir: Path) -> None:
    for heading in (
        "# Run report: mini_line",
        "## Summary",
        "## Running times per service",
        "## Stops",
        "## Formations (virtual coupling)",
        "## Figures",
        "## Capacity",
        "### UIC 406 occupancy per section",
    ):
        assert f"\n{heading}\n" in f"\n{run_md}"
    trips = read_csv(run_dir / "trips.csv")
    rows = {r[0]: r for r in _rows(_section(run_md, "## Running times per service"))}
    assert set(rows) == {t["service"] for t in trips}
    for svc, row in rows.items():
        mine = [float(t["travel_time_s"]) for t in trips if t["service"] == svc]
        assert row[1] == str(len(mine))
        assert row[3] == f"{statistics.mean(mine) / 60.0:.1f}"
        assert row[5] == f"{max(mine) / 60.0:.1f}"
    summary = _section(run_md, "## Summary")
    assert "| 7 / 7 / 7 |" in summary and "| collisions (SUMO's own check) | 0 (0) |" in summary
    formations = _rows(_section(run_md, "## Formations (virtual coupling)"))
    assert [r[:3] for r in formations] == [
        [f["formation"], f["leader"], f["follower"]] for f in read_csv(run_dir / "formations.csv")
    ]
    stops = _rows(_section(run_md, "## Stops").split("Per station (line order):")[1])
    assert [r[0] for r in stops] == ["A", "B", "C", "F", "D", "G", "E"]  # line km order, branch included
    assert sum(int(r[2]) for r in stops) == len(read_csv(run_dir / "stops.csv"))


def test_run_report_links_existing_figures(run_md: str, run_dir: Path) -> None:
    links = LINK_RE.findall(run_md)
    pngs = [ln for ln in links if ln.endswith(".png")]
    assert {Path(p).stem for p in pngs} == {"time-distance", "speed", "headway", "gap"}
    for rel in links:
        path = run_dir / rel
        assert path.is_file(), rel
        head = path.read_bytes()[:8]
        assert head == b"\x89PNG\r\n\x1a\n" if rel.endswith(".png") else b"<svg" in path.read_bytes()[:400]


def test_html_report_is_self_contained(run_dir: Path, run_md: str) -> None:
    assert cli_main(["report", str(run_dir), "--format", "html"]) == 0
    page = (run_dir / "report.html").read_text(encoding="utf-8")
    assert page.startswith("<!DOCTYPE html>") and page.rstrip().endswith("</html>")
    srcs = re.findall(r'src="([^"]+)"', page)
    assert len(srcs) == run_md.count("![") == 4
    assert all(s.startswith("data:image/png;base64,") for s in srcs)
    assert "href=" not in page  # no link to a file next to it
    assert page.count("<table>") == run_md.count("\n|---")
    assert "<h2>Running times per service</h2>" in page


def test_sweep_report(sweep_dir: Path) -> None:
    path = report.write_report(sweep_dir)
    md = path.read_text(encoding="utf-8")
    assert md.startswith("# Sweep report: report_test")
    cases = read_csv(sweep_dir / "cases.csv")
    rows = _rows(_section(md, "## Cases"))
    assert [r[0] for r in rows] == [c["case_id"] for c in cases] and len(rows) == 2
    header = _section(md, "## Cases").splitlines()
    assert "services[0].departures.headway_s" in next(ln for ln in header if ln.startswith("|"))
    # the linked down headway is the same parameter: one figure, against the up headway
    figures = [ln for ln in LINK_RE.findall(md) if ln.endswith(".png")]
    assert len(figures) == 1 and "headway_s" in figures[0]
    assert (sweep_dir / figures[0]).read_bytes()[:4] == b"\x89PNG"
    assert report.parameter_columns(pd.read_csv(sweep_dir / "cases.csv")) == [
        "services[0].departures.last",
        "services[1].departures.last",
        "services[0].departures.headway_s",
        "services[1].departures.headway_s",
    ]
