"""A stop a train cannot make is a missed stop, never a halt SUMO imposes.

Here: the tests of it that run SUMO or a railsim child process; the others are in ``tests/unit/test_stop_overrun.py``.
"""

from __future__ import annotations

from pathlib import Path

from tests.helpers import ROOT, read_csv, read_summary, run_mapping

DATA = ROOT / "tests" / "data"


def _run(tmp_path: Path, offset_m: float) -> tuple[int, Path]:
    data = {
        "name": "overrun",
        "world": {"line": str(DATA / "lines" / "mini_y.yaml")},
        "simulation": {"step_s": 0.2, "duration_s": 200, "seed": 1, "step_method": "euler"},
        "vehicles": {"cq6": {"preset": "cq3_6car"}},
        "controllers": {"ato": {"type": "ato"}, "sep": {"type": "separation"}},
        "roles": {"ato": "ato", "separation": "sep"},
        "services": [
            {
                "id": "s",
                "from": "a",
                "to": "c",
                "vehicle": "cq6",
                "departures": {"times": [0]},
                "dwell_s": 20,
                "start": {"offset_m": offset_m, "speed_kmh": 54},
            }
        ],  # fmt: skip
        "outputs": {"trace_stride_s": 0.2, "sumo": [], "formats": ["csv"]},
    }
    res, out = run_mapping(tmp_path, data, "overrun")
    return res.returncode, out


def test_a_train_that_cannot_make_its_stop_misses_it_and_never_stops_faster_than_its_brakes(tmp_path: Path) -> None:
    rc, out = _run(tmp_path, 1450.0)  # 50 m before B's mark (B at km 1.5) at 15 m/s
    assert rc == 0
    s = read_summary(out)
    assert s["n_stops_missed"] == 1 and s["n_stops_served"] == 1 and s["n_arrived"] == 1
    events = read_csv(out / "events.csv")
    missed = [e for e in events if e["kind"] == "stop_missed"]
    assert len(missed) == 1 and '"station":"b"' in missed[0]["detail"] and "least_overrun_m" in missed[0]["detail"]
    assert float(missed[0]["t_s"]) <= 0.4  # at once: it could not stop from its first step
    assert not any(e["kind"] == "desync" for e in events)
    rows = [r for r in read_csv(out / "trace.csv") if r["train"] == "s.000"]
    worst = max(
        (float(a["speed_mps"]) - float(b["speed_mps"])) / (float(b["t_s"]) - float(a["t_s"]))
        for a, b in zip(rows, rows[1:])
    )
    assert worst <= 1.25 + 0.3  # the emergency brake plus drag: no step to 0 from speed
