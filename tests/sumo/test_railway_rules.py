"""Railway rules on any network: safe insertion, one collision truth, desync check, stall detection.

Each SUMO run is a child process on a small straight line built here with netconvert (two edges, four
platforms); a few simulated minutes each. Where a failure must be provoked (a train moved behind railsim's
back, a train that will not move) the child patches the SUMO bridge before running ``railsim run``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import yaml

from tests.helpers import read_csv, read_summary, run_python, run_railsim
from tests.sumo.test_external_net import _edge, _netconvert, _stops, _write

FOLLOWER_GAP_M = 30.0


@pytest.fixture(scope="module")
def line(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A 6 km straight line A–B–C; Tight's platform starts 10 m from the line's start (no room behind a train)."""
    folder = tmp_path_factory.mktemp("line")
    nodes = '<node id="A" x="0" y="0"/>\n<node id="B" x="3000" y="0"/>\n<node id="C" x="6000" y="0"/>'
    net = _netconvert(folder, "line", nodes, "\n".join([_edge("AB", "A", "B"), _edge("BC", "B", "C")]))
    stops = _stops(
        folder,
        "line",
        [
            ("tight", "AB_0", 10, 170, "Tight"),
            ("alpha", "AB_0", 600, 900, "Alpha"),
            ("bravo", "BC_0", 1000, 1300, "Bravo"),
        ],
    )
    return net, stops


@pytest.fixture(scope="module")
def cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("rulescache")


def _scenario(
    folder: Path,
    line: tuple[Path, Path],
    services: list[dict[str, Any]],
    formations: list[dict[str, Any]] | None = None,
    duration_s: float = 400,
) -> Path:
    net, stops = line
    raw = {
        "name": "rules",
        "world": {"net": str(net), "additional": [str(stops)]},
        "simulation": {"step_s": 0.5, "duration_s": duration_s, "seed": 3},
        "vehicles": {"cq6": {"preset": "cq3_6car"}},
        "controllers": {"ato": {"type": "ato"}, "sep": {"type": "separation"}, "vc": {"type": "cacc"}},
        "roles": {"ato": "ato", "separation": "sep", "coupled": "vc"},
        "services": services,
        "formations": formations or [],
    }
    return _write(folder, "rules.yaml", yaml.safe_dump(raw, sort_keys=False))


def _service(sid: str, a: str, b: str, t: float) -> dict[str, Any]:
    return {"id": sid, "from": a, "to": b, "vehicle": "cq6", "departures": {"times": [t]}, "dwell_s": 20}


def _pair() -> list[dict[str, Any]]:
    return [
        {
            "id": "pair",
            "leader": {"service": "lead", "trip": 0},
            "follower": {"service": "follow", "trip": 0},
            "target_gap_m": FOLLOWER_GAP_M,
            "couple": {"on_departure": True},
        }
    ]


def _events(out: Path, kind: str) -> list[dict[str, Any]]:
    rows = read_csv(out / "events.csv")
    return [{**e, "t_s": float(e["t_s"]), "detail": json.loads(e["detail"])} for e in rows if e["kind"] == kind]


def _run(scn: Path, out: Path, cache: Path) -> Any:
    return run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], cache_dir=cache, timeout=300)


def _run_patched(patch: str, scn: Path, out: Path, cache: Path) -> Any:
    """``railsim run`` in a child whose bridge/engine was patched by ``patch`` (Python source) first."""
    code = (
        "import sys\n"
        + patch
        + "\nfrom railsim.cli.main import main\n"
        + f"sys.exit(main(['run', {str(scn)!r}, '--out', {str(out)!r}, '--no-progress']))\n"
    )
    return run_python(code, cache_dir=cache, timeout=300, reference=True)


# ---- safe insertion ------------------------------------------------------------------------------------------


def test_follower_starting_where_its_leader_stands_is_inserted_behind_at_the_gap(
    line: tuple[Path, Path], cache: Path, tmp_path: Path
) -> None:
    services = [_service("lead", "alpha", "bravo", 0), _service("follow", "alpha", "bravo", 0)]
    scn = _scenario(tmp_path, line, services, _pair())
    out = tmp_path / "out"
    res = _run(scn, out, cache)
    assert res.returncode == 0, res.stdout + res.stderr  # a desync would exit 3: positions agree with SUMO
    s = read_summary(out)
    assert s["n_never_inserted"] == 0 and s["n_arrived"] == s["n_trains"] == 2
    assert s["collisions"] == s["collisions_railsim"] == s["sumo_collisions"] == 0
    inserted = {e["subject"]: e for e in _events(out, "train_inserted")}
    assert set(inserted) == {"lead.000", "follow.000"} and inserted["lead.000"]["t_s"] == inserted["follow.000"]["t_s"]
    from railsim.physics.vehicle import preset

    length_m = preset("cq3_6car").length_m
    lead_m = inserted["lead.000"]["detail"]["chainage_m"]
    assert inserted["follow.000"]["detail"]["chainage_m"] == pytest.approx(lead_m - length_m - FOLLOWER_GAP_M, abs=1e-3)
    assert not _events(out, "desync") and _events(out, "coupled")


def test_a_formation_with_no_room_behind_the_leader_is_a_config_error(
    line: tuple[Path, Path], cache: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from railsim import scenario
    from railsim.engine import loop as engine
    from railsim.errors import ConfigError

    monkeypatch.setenv("RAILSIM_CACHE", str(cache))
    services = [_service("lead", "tight", "bravo", 0), _service("follow", "tight", "bravo", 0)]
    scn = _scenario(tmp_path, line, services, _pair())
    with pytest.raises(ConfigError) as info:
        engine.Simulation(scenario.load(scn), None)  # checked before SUMO starts
    msg = str(info.value)
    assert msg.startswith(f"{scn}: formations: formation 'pair': follower follow.000") and "no room" in msg


def test_a_departure_onto_occupied_track_is_held_with_a_reason(
    line: tuple[Path, Path], cache: Path, tmp_path: Path
) -> None:
    services = [_service("first", "alpha", "bravo", 0), _service("second", "alpha", "bravo", 2)]
    out = tmp_path / "out"
    res = _run(_scenario(tmp_path, line, services), out, cache)
    assert res.returncode == 0, res.stdout + res.stderr
    held = _events(out, "departure_held")
    assert held and held[0]["subject"] == "second.000"
    assert held[0]["detail"]["reason"] == "track occupied by first.000"
    s = read_summary(out)
    assert s["n_arrived"] == 2 and s["n_never_inserted"] == 0 and s["collisions"] == 0


def test_a_train_never_inserted_is_reported_and_exits_3(line: tuple[Path, Path], cache: Path, tmp_path: Path) -> None:
    services = [_service("first", "alpha", "bravo", 0), _service("second", "alpha", "bravo", 2)]
    out = tmp_path / "out"
    res = _run(_scenario(tmp_path, line, services, duration_s=8), out, cache)  # the first is still on the platform
    assert res.returncode == 3, res.stdout + res.stderr
    assert "never inserted: 1 train(s): second.000" in res.stdout
    never = _events(out, "never_inserted")
    assert [e["subject"] for e in never] == ["second.000"]
    assert never[0]["detail"]["reason"] == "track occupied by first.000"
    assert read_summary(out)["n_never_inserted"] == 1


# ---- desync and stall ----------------------------------------------------------------------------------------

_MOVE_BEHIND_OUR_BACK = """
import libsumo
from railsim.engine import sumo
_step = sumo.SumoBridge.step
def step(self):
    _step(self)
    if abs(self.time_s - 30.0) < 1e-6:  # SUMO moves the train 40 m on; railsim is not told
        lane = libsumo.vehicle.getLaneID("lead.000")
        libsumo.vehicle.moveTo("lead.000", lane, libsumo.vehicle.getLanePosition("lead.000") + 40.0)
sumo.SumoBridge.step = step
"""


_INSERTED_ELSEWHERE = """
from railsim.engine import sumo
_add = sumo.SumoBridge.add_train
def add_train(self, train_id, route_id, type_id, depart_pos_m, *args, **kwargs):  # SUMO puts it 40 m further on
    _add(self, train_id, route_id, type_id, depart_pos_m + 40.0, *args, **kwargs)
sumo.SumoBridge.add_train = add_train
"""


@pytest.mark.parametrize(
    ("patch", "first_s"), [(_MOVE_BEHIND_OUR_BACK, 30.0), (_INSERTED_ELSEWHERE, 0.5)], ids=["moveTo", "departPos"]
)
def test_a_train_moved_behind_railsims_back_is_a_desync_exit_3(
    patch: str, first_s: float, line: tuple[Path, Path], cache: Path, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    scn = _scenario(tmp_path, line, [_service("lead", "alpha", "bravo", 0)])
    res = _run_patched(patch, scn, out, cache)
    assert res.returncode == 3, res.stdout + res.stderr
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("railsim:")]
    assert len(lines) == 1 and "disagree" in lines[0] and "lead.000" in lines[0] and "Traceback" not in res.stderr
    desync = _events(out, "desync")  # the outputs were written before the run failed
    assert [e["subject"] for e in desync] == ["lead.000"] and desync[0]["t_s"] == pytest.approx(first_s, abs=0.6)
    d = desync[0]["detail"]
    assert d["sumo_m"] - d["railsim_m"] == pytest.approx(40.0, abs=1.0)
    assert read_summary(out)["failure"].startswith("railsim and SUMO disagree")


_NEVER_MOVES = """
from railsim.engine import sumo
_set = sumo.SumoBridge.set_speeds
def set_speeds(self, ids, speeds):  # SUMO holds lead.000 at 0 whatever railsim asks: it never moves
    _set(self, ids, [0.0 if i == "lead.000" else v for i, v in zip(ids, speeds)])
sumo.SumoBridge.set_speeds = set_speeds
"""
_SHORT_TIMEOUT = """
from railsim.engine import loop
from railsim.engine.settings import EngineSettings
loop.EngineSettings = lambda: EngineSettings(stall_timeout_s=40.0)
"""


@pytest.mark.parametrize(
    ("patch", "duration_s", "stall_s", "says"),
    [(_NEVER_MOVES + _SHORT_TIMEOUT, 300, 40.0, "stalled:"), (_NEVER_MOVES, 100, 100.0, "when the horizon ended")],
    ids=["timeout", "horizon"],
)
def test_a_train_that_never_moves_stalls_the_run_exit_3(
    patch: str, duration_s: float, stall_s: float, says: str, line: tuple[Path, Path], cache: Path, tmp_path: Path
) -> None:
    out = tmp_path / "out"
    scn = _scenario(tmp_path, line, [_service("lead", "alpha", "bravo", 0)], duration_s=duration_s)
    res = _run_patched(patch, scn, out, cache)
    assert res.returncode == 3, res.stdout + res.stderr
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("railsim:")]
    assert len(lines) == 1 and says in lines[0] and "lead.000" in lines[0]
    stalled = _events(out, "stalled")
    assert [e["subject"] for e in stalled] == ["lead.000"]
    assert stalled[0]["t_s"] == pytest.approx(stall_s, abs=1.0) and stalled[0]["detail"]["edge"] == "AB"
    assert read_summary(out)["sim_s"] <= stall_s + 1.0  # the run stopped there


# ---- one collision truth -------------------------------------------------------------------------------------
