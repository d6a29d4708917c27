"""The room between two single-track sections counts the trains already standing there.

The line: double track at Alpha, single track S1 (2 km), 100 m of double track with a platform on each track
(Mid), single track S2 (2 km), double track at Bravo; the world of :mod:`tests.sumo.test_consecutive_sections`
with a station between the sections. The piece holds one 27 m tram each way: 70 m of room between the
clearance past S1 and the overlap before S2, against 77 m for a tram and its separation margin.

Two trams leave Alpha eastbound and two leave Bravo westbound. The first of each pair is granted its first
section alone (the piece is empty), runs through it and dwells at Mid, its first section released and the next
not yet asked for (a train asks for a section beyond a stop only when it is about to leave the stop). The
second of each pair then asks for its first section. Counting only the trains holding or waiting for that
section, the room looked empty: each was granted its first section alone, ran into it up to the first tram
standing at Mid, and the first trams, leaving Mid, each waited for the section the other's second tram held —
a deadlock that ended the run. Now a train counts the trains standing between the sections too, and the second
trams ask for both sections together.
"""

from __future__ import annotations

from pathlib import Path

import yaml

from tests.helpers import read_csv, read_summary, run_railsim
from tests.sumo.test_consecutive_sections import TRAM, _one_direction_at_a_time, build_two_sections
from tests.sumo.test_external_net import _COMMON, _stops, _write

PIECE_M = 100.0


def _run(folder: Path) -> tuple[Path, dict]:
    net, _ = build_two_sections(folder, PIECE_M)
    stops = _stops(
        folder,
        "mid",
        [
            ("a_e", "AJ1_0", 100, 400, "Alpha"),
            ("m_e", "XY_0", 40, 70, "Mid"),
            ("b_e", "J2B_0", 600, 900, "Bravo"),
            ("b_w", "BJ2_0", 100, 400, "Bravo"),
            ("m_w", "YX_0", 40, 70, "Mid"),
            ("a_w", "J1A_0", 600, 900, "Alpha"),
        ],
    )
    dwell = {"default": 30, "stations": {"Mid": 150}}  # the first trams stand at Mid while the second ones ask
    services = [
        {"id": "east", "from": "Alpha", "to": "Bravo", "vehicle": "tram", "departures": {"times": [0, 200]}},
        {"id": "west", "from": "Bravo", "to": "Alpha", "vehicle": "tram", "departures": {"times": [0, 205]}},
    ]
    raw = {
        "name": "room_between_sections",
        "world": {"net": str(net), "additional": [str(stops)]},
        **_COMMON,
        "vehicles": {"tram": TRAM},
        "services": [{**s, "dwell_s": dwell} for s in services],
    }
    scn = _write(folder, "mid.yaml", yaml.safe_dump(raw, sort_keys=False))
    out = folder / "out"
    res = run_railsim(["run", str(scn), "--out", str(out), "--no-progress"], cache_dir=folder / "c", timeout=600)
    assert (out / "summary.json").exists(), res.stderr[-2000:] + res.stdout[-2000:]
    return out, read_summary(out)


def test_trains_standing_between_two_sections_take_the_room(tmp_path: Path) -> None:
    out, s = _run(tmp_path)
    assert s["n_trains"] == s["n_arrived"] == 4, s.get("failure")
    assert s["collisions"] == 0 and s["sumo_collisions"] == 0 and s["switch_violations"] == 0
    events = read_csv(out / "events.csv")
    _one_direction_at_a_time(events)
    served = [r for r in read_csv(out / "stops.csv") if r["station"] == "mid"]
    assert len(served) == 4, served  # every tram stopped at Mid: the first ones stood there while the others asked
    reserved: dict[tuple[str, str], float] = {}
    for e in events:
        if e["kind"] == "section_reserved":
            for train in yaml.safe_load(e["detail"])["trains"]:
                reserved.setdefault((train, e["subject"]), float(e["t_s"]))
    # the second tram of each pair is granted its first section only once the first tram, standing at Mid, has
    # been granted the next one: never while the first one stands between the sections with nowhere to go
    for leader, follower, first, second in (
        ("east.000", "east.001", "track:-S1", "track:-S2"),
        ("west.000", "west.001", "track:-S2", "track:-S1"),
    ):
        assert reserved[(follower, first)] >= reserved[(leader, second)], (follower, reserved)
