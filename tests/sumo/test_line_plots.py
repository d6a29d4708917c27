"""Line plots of a real run (mini Y line, start 07:30): train graph, speed, coupled gap, headways.

What is pinned: the train graph has one line per trip in each direction (directions worked out here from the line
description's station km), station names on the distance axis, every dwell drawn at its station's km, clock
time on the time axis, the coupled band only inside the formation's coupled interval (events.csv); the speed,
gap and headway figures hold one line per trip / formation and one dot per achieved headway; every kind writes a
valid PNG and SVG; ``railsim plot --kind ...`` works and its mistakes exit 2.
"""

from __future__ import annotations

import copy
import xml.etree.ElementTree as ET
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest
import yaml

from railsim.analysis import sections
from railsim.cli import plot as plot_command
from railsim.cli.main import main as cli_main
from railsim.errors import ConfigError
from railsim.report.plots import line
from tests.helpers import DATA, read_csv, run_railsim

MINI = DATA / "scenarios" / "mini_line.yaml"
LINE = DATA / "lines" / "mini_y.yaml"
START_S = 7.5 * 3600.0


def _run(tmp: Path, name: str, **changes: object) -> Path:
    raw = copy.deepcopy(yaml.safe_load(MINI.read_text()))
    raw["world"] = {"line": str(LINE.resolve())}
    raw["simulation"]["start_time"] = "07:30"
    raw.update(changes)
    scn = tmp / f"{name}.yaml"
    scn.write_text(yaml.safe_dump(raw, sort_keys=False))
    out = tmp / name
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"])
    assert res.returncode == 0, res.stderr + res.stdout
    return out


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _run(tmp_path_factory.mktemp("plots"), "mini")


@pytest.fixture(scope="module")
def loaded(run_dir: Path) -> line.LineRun:
    return line.load_line_run(run_dir)


@pytest.fixture(scope="module")
def stations() -> dict[str, tuple[str, float]]:
    """station id -> (name, km) straight from the line description."""
    desc = yaml.safe_load(LINE.read_text())
    out = {s["id"]: (s["name"], float(s["km"])) for s in desc["stations"]}
    for br in desc["branches"]:
        out.update({s["id"]: (s["name"], float(s["km"])) for s in br["stations"]})
    return out


@pytest.fixture(scope="module")
def directions(run_dir: Path, stations: dict[str, tuple[str, float]]) -> dict[str, str]:
    """trip id -> up/down, from the km of its origin and destination."""
    return {
        t["trip_id"]: ("up" if stations[t["destination"]][1] > stations[t["origin"]][1] else "down")
        for t in read_csv(run_dir / "trips.csv")
    }


def _train_lines(ax: object) -> dict[str, object]:
    return {ln.get_gid(): ln for ln in ax.get_lines() if ln.get_gid()}  # type: ignore[attr-defined]


def _axes(fig: object) -> dict[str, object]:
    return {ax.get_gid(): ax for ax in fig.axes if ax.get_gid()}  # type: ignore[attr-defined]


# ---------------------------------------------------------------------------------------------------- time-distance
def test_one_line_per_trip_in_each_direction(loaded: line.LineRun, directions: dict[str, str]) -> None:
    fig = line.time_distance_figure(loaded)
    try:
        axes = _axes(fig)
        assert set(axes) == {"up", "down"}
        for d, ax in axes.items():
            expected = {tid for tid, dd in directions.items() if dd == d}
            assert set(_train_lines(ax)) == expected and len(expected) >= 3
    finally:
        plt.close(fig)


def test_station_names_on_the_distance_axis(loaded: line.LineRun, stations: dict[str, tuple[str, float]]) -> None:
    fig = line.time_distance_figure(loaded)
    try:
        for ax in fig.axes:
            texts = [t.get_text() for t in ax.texts]
            for name, km in stations.values():
                assert any(name in t and f"{km:.1f}" in t for t in texts), name
            # grid line of every station at its km
            ys = {
                round(float(ln.get_ydata()[0]), 6)
                for ln in ax.get_lines()
                if not ln.get_gid() and len(set(ln.get_ydata())) == 1
            }
            assert {round(km, 6) for _, km in stations.values()} <= ys
    finally:
        plt.close(fig)


def test_dwells_sit_on_their_station_and_time_is_clock_time(
    loaded: line.LineRun, run_dir: Path, stations: dict[str, tuple[str, float]]
) -> None:
    fig = line.time_distance_figure(loaded)
    try:
        lines = {}
        for ax in fig.axes:
            lines.update(_train_lines(ax))
        first_t = {}
        for r in read_csv(run_dir / "trace.csv"):
            first_t.setdefault(r["train"], float(r["t_s"]))
        for tid, ln in lines.items():
            assert ln.get_xdata()[0] == pytest.approx(START_S + first_t[tid])
        checked = 0
        for s in read_csv(run_dir / "stops.csv"):
            if not s["departure_s"]:
                continue
            x, y = np.asarray(lines[s["trip_id"]].get_xdata()), np.asarray(lines[s["trip_id"]].get_ydata())
            at = (x >= START_S + float(s["arrival_s"])) & (x <= START_S + float(s["departure_s"]))
            assert at.any()
            # the front of a halted train stands within half a platform (110 m) of the platform centre
            assert np.abs(y[at] - stations[s["station"]][1]).max() < 0.12, s
            assert np.ptp(y[at]) < 1e-6  # dwell: a flat segment
            checked += 1
        assert checked >= 15
        assert line.clock_label(START_S) == "07:30" and line.clock_label(25 * 3600 + 59) == "25:01"
    finally:
        plt.close(fig)


def test_coupled_band_only_while_coupled(loaded: line.LineRun, run_dir: Path) -> None:
    events = read_csv(run_dir / "events.csv")
    t_on = min(float(e["t_s"]) for e in events if e["kind"] == "coupled")
    t_off = min(float(e["t_s"]) for e in events if e["kind"] in ("decouple_requested", "decoupled"))
    fig = line.time_distance_figure(loaded, "up")
    try:
        (ax,) = fig.axes
        bands = [ln for ln in ax.get_lines() if not ln.get_gid() and ln.get_color() == line.COUPLED_COLOUR]
        assert bands
        xs = np.concatenate([np.asarray(b.get_xdata()) for b in bands]) - START_S
        assert xs.min() >= t_on - 1.0 and xs.max() <= t_off + 1.0
        assert xs.max() - xs.min() > 0.5 * (t_off - t_on)
    finally:
        plt.close(fig)


def _check_files(paths: list[Path], trip_ids: list[str]) -> None:
    png, svg = paths
    assert png.suffix == ".png" and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    root = ET.parse(svg).getroot()
    assert root.tag.endswith("svg")
    text = svg.read_text(encoding="utf-8")
    for tid in trip_ids:
        assert f'id="{tid}"' in text


def test_time_distance_writes_png_and_svg(run_dir: Path, tmp_path: Path, directions: dict[str, str]) -> None:
    paths = line.time_distance(run_dir, tmp_path / "td")
    assert paths == [tmp_path / "td.png", tmp_path / "td.svg"]
    _check_files(paths, list(directions))


# ---------------------------------------------------------------------------------------------------- other kinds
def test_speed_one_line_per_trip_below_the_line_speed(
    loaded: line.LineRun, directions: dict[str, str], tmp_path: Path
) -> None:
    fig = line.speed_figure(loaded)
    try:
        for d, ax in _axes(fig).items():
            lines = _train_lines(ax)
            assert set(lines) == {tid for tid, dd in directions.items() if dd == d}
            vmax = max(float(np.nanmax(ln.get_ydata())) for ln in lines.values())
            assert 40.0 < vmax <= 70.0 + 0.5  # mini_y: line speed 70 km/h
    finally:
        plt.close(fig)
    _check_files(line.speed(loaded.run_dir, tmp_path / "speed"), list(directions))


def test_gap_one_panel_per_formation_with_target(loaded: line.LineRun, tmp_path: Path) -> None:
    fig = line.gap_figure(loaded)
    try:
        (ax,) = [a for a in fig.axes if a.get_visible()]
        assert ax.get_gid() == "pair"
        lines = _train_lines(ax)
        assert set(lines) == {"br_up.000"}
        flat = [ln for ln in ax.get_lines() if not ln.get_gid()]
        assert any(np.allclose(ln.get_ydata(), 30.0) for ln in flat)
        gaps = np.asarray(lines["br_up.000"].get_ydata(), dtype=float)
        assert np.nanmin(gaps) > 25.0  # coupled at ~30 m, never closer than a few metres below it
    finally:
        plt.close(fig)
    _check_files(line.gap(loaded.run_dir, tmp_path / "gap"), ["br_up.000"])


def test_headway_one_dot_per_achieved_headway(loaded: line.LineRun, run_dir: Path, tmp_path: Path) -> None:
    table = sections.section_table(run_dir)
    fig = line.headway_figure(loaded)
    try:
        for d, ax in _axes(fig).items():
            sub = table[(table["direction"] == d) & table["headway_s"].notna()]
            dots = sum(len(c.get_offsets()) for c in ax.collections)
            assert dots == len(sub) > 0
            xs = np.concatenate([np.asarray(c.get_offsets())[:, 0] for c in ax.collections if len(c.get_offsets())])
            assert sorted(xs) == pytest.approx(sorted(sub["headway_s"]))
            labels = [t.get_text() for t in ax.get_yticklabels()]
            assert len(labels) == sub.groupby(["from_station", "to_station"]).ngroups
    finally:
        plt.close(fig)
    png, svg = line.headway(run_dir, tmp_path / "hw")
    assert png.read_bytes()[:4] == b"\x89PNG" and ET.parse(svg).getroot().tag.endswith("svg")


# ---------------------------------------------------------------------------------------------------- CLI
def test_cli_writes_each_kind(run_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert plot_command.LINE_KINDS == line.KINDS and set(line.KINDS) <= set(plot_command.KINDS)
    out = tmp_path / "figs"  # --out is a folder: the figures are named after their kind
    for kind in line.KINDS:
        assert cli_main(["plot", str(run_dir), "--kind", kind, "--out", str(out), "--direction", "up"]) == 0
        assert (out / f"{kind}.png").is_file() and (out / f"{kind}.svg").is_file()
    printed = capsys.readouterr().out
    assert str(out / "speed.svg") in printed


def test_cli_auto_draws_every_line_figure_that_applies(
    run_dir: Path, tmp_path: Path, tmp_path_factory: pytest.TempPathFactory, capsys: pytest.CaptureFixture[str]
) -> None:
    """Without --kind a line run gets train graph, speed, gap and headway; a figure that does not apply is skipped."""
    out = tmp_path / "auto"
    assert cli_main(["plot", str(run_dir), "--out", str(out)]) == 0
    assert sorted(p.name for p in out.glob("*.png")) == sorted(f"{k}.png" for k in line.KINDS)
    lonely = _run(tmp_path_factory.mktemp("plots"), "no_formations_auto", formations=[])
    assert cli_main(["plot", str(lonely)]) == 0  # no --out: into the run's own folder
    assert (lonely / "time-distance.png").is_file() and not (lonely / "gap.png").exists()
    assert "gap skipped: no virtually coupled formation" in capsys.readouterr().out


def test_cli_mistakes_exit_2(
    run_dir: Path, tmp_path_factory: pytest.TempPathFactory, capsys: pytest.CaptureFixture[str]
) -> None:
    lonely = _run(tmp_path_factory.mktemp("plots"), "no_formations", formations=[])
    assert cli_main(["plot", str(lonely), "--kind", "gap", "--out", str(lonely / "g")]) == 2
    assert "no virtually coupled formation" in capsys.readouterr().err
    assert cli_main(["plot", str(run_dir.parent / "missing"), "--kind", "time-distance"]) == 2
    assert "missing" in capsys.readouterr().err
    (run_dir.parent / "not_a_run").mkdir(exist_ok=True)
    assert cli_main(["plot", str(run_dir.parent / "not_a_run"), "--kind", "speed"]) == 2
    with pytest.raises(SystemExit) as exc:
        cli_main(["plot", str(run_dir), "--kind", "time-distance", "--direction", "sideways"])
    assert exc.value.code == 2
    with pytest.raises(ConfigError, match="direction"):
        line.time_distance_figure(run_dir, "left")
