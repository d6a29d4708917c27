"""Paper C through the engine: the scenario file run in SUMO agrees with the numpy reference model.

``scenarios/paper002_topology_switch.yaml`` (six trains, T = 1 s, union topology, the spec's corrected
parameters, train 2 leaves and train 5 joins at k = 1000) is run by ``railsim run`` in a child process; every
position of every train at every step must equal :func:`controllers.distributed.reference.simulate` of
``zhang2024_fig1("union")`` to 1e-6 m (the trace keeps 6 decimals). The paper's step k is engine time k + 1.
A join that violates condition (13) is refused before any control acts on it: exit code 2, one line.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from controllers.distributed.reference import simulate
from controllers.distributed.scenarios import zhang2024_fig1
from tests.helpers import ROOT, read_csv, read_summary, run_railsim

SCENARIO = ROOT / "scenarios" / "paper002_topology_switch.yaml"


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("p2")
    res = run_railsim(["run", str(SCENARIO), "--out", str(out), "--no-progress"])
    assert res.returncode == 0, res.stderr[-2000:]
    return out


def test_sumo_positions_equal_the_numpy_model(run: Path) -> None:
    log = simulate(zhang2024_fig1("union"))
    rows = read_csv(run / "trace.csv")
    origin = next(float(r["chainage_m"]) for r in rows if r["train"] == "t6.000" and float(r["t_s"]) == 1.0)
    # train 6 starts at paper position 0: its first chainage is the origin of the paper frame
    worst, n = 0.0, 0
    for r in rows:
        k = int(round(float(r["t_s"]))) - 1
        if k > 2000:
            continue
        ref = float(log.x_m[k, log.col(r["train"][1])])
        assert not math.isnan(ref), (r["train"], k)  # present in SUMO exactly when present in the model
        worst = max(worst, abs(float(r["chainage_m"]) - origin - ref))
        n += 1
    assert n == 5 * 2001  # five trains on the track at every step
    assert worst <= 1e-6, worst
    assert {r["role"] for r in rows} == {"ato"}  # the graph law decided every command (separation never bound)


def test_topology_switch_happens_once_at_k_1000(run: Path) -> None:
    events = read_csv(run / "events.csv")
    changes = [float(e["t_s"]) for e in events if e["kind"] == "graph_changed"]
    assert changes == [1.0, 1001.0]
    left = [(float(e["t_s"]), e["subject"]) for e in events if e["kind"] == "train_left"]
    assert left == [(1001.0, "t2.000")]
    s = read_summary(run)
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0


def test_a_join_that_violates_condition_13_is_refused(tmp_path: Path) -> None:
    raw = yaml.safe_load(SCENARIO.read_text())
    for svc in raw["services"]:
        if svc["id"] == "t5":
            svc["start"]["offset_m"] = 90925.0  # 60.7 m behind train 4 (50 m long): x_45 + T·v_45 < 100 m
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    res = run_railsim(["run", str(path), "--out", str(tmp_path / "o"), "--no-progress"])
    assert res.returncode == 2, res.stderr[-2000:]
    assert "Traceback" not in res.stderr
    line = res.stderr.strip().splitlines()[-1]
    assert "at k = 1001" in line and "edges[" in line and "(13)" in line, line


def test_reproduce_command_writes_the_reference_run_and_figures(tmp_path: Path) -> None:
    res = run_railsim(["reproduce", "paper002", "--out", str(tmp_path)])
    assert res.returncode == 0, res.stderr
    assert "0 constraint violations" in res.stdout
    first = {r["train"]: float(r["u_mps2"]) for r in read_csv(tmp_path / "trains.csv") if r["k"] == "0"}
    assert first == pytest.approx(
        {"1": 0.193334, "2": -6.817011, "3": 4.179605, "4": -5.820395, "6": 9.163164}, abs=1e-6
    )  # spec 002 §7.2 item 10
    for name in ("fig3_positions", "fig4_position_differences", "fig5_speeds", "fig6_inputs"):
        assert (tmp_path / f"{name}.png").stat().st_size > 10_000
