"""Joins at a station after a merge, on the generated Y world and on an imported city (real SUMO runs).

* **Y world** (:file:`tests/data/lines/merge_y.yaml`): a formation joining at C (``couple: {at_station: c}``),
  its leader from E and its follower from G over the merge ``c_down``, and an unrelated train from E 60 s behind
  the leader. First come, first served it took the merge before the follower and stood at C behind the waiting
  leader (the join ``blocked``); the merge order now holds it short of ``c_down`` until the follower asked, and
  the pair couples at C.
* **Y world, a stop before the merge**: the follower dwells 240 s at F, 1.3 km before the merge; its wait for
  its leader is counted from when it leaves F (it has no stop left before the merge), not from its first held
  request on the way to F (the wait ran out while it still stood at F, and it went first: `wrong_order`).
* **Y world, a branch train due before the follower**: it leaves G after the leader asked for the merge and
  before the follower leaves; the leader yields to it (``merge_leader_yields``) although it was not on the line
  yet, instead of letting it run between the two.
* **Dresden** (:file:`tests/data/osm/dresden_tram_2025.osm.gz`, imported with platforms widened to 70 m): lines 9
  (from Zoo) and 11 (from Strehlener Platz) merge before Lennéplatz, where both stop twice (OSM maps two stop
  positions one after the other on the same track). A formation joining there couples at the first of the two
  stops and the pair leaves together; the leader was held for ever (the follower's *next* stop was at the same
  station, read as "still at the join station": no train arrived).
* **Potsdam, a platform just past the merge**: lines 91 and 93 merge at points ``30566579`` right before the
  second platform of Platz der Einheit/West (the first lies before the points on line 91). The leader waits at
  the second (waiting at the first it held the points its follower needed: ``timeout``), the follower, held short
  of the points behind it, asks to couple standing there, and the pair couples.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tests.helpers import merge_world, ok_stdout, read_csv, read_summary, run_clean, run_railsim

OSM = Path(__file__).resolve().parents[1] / "data" / "osm"
POTSDAM = OSM / "potsdam_tram_2025.osm.gz"
DRESDEN = OSM / "dresden_tram_2025.osm.gz"


def _run(tmp_path: Path, name: str, data: dict[str, Any]) -> tuple[Path, list[dict[str, Any]]]:
    return run_clean(tmp_path, data, name)


def test_a_train_behind_the_leader_waits_at_the_merge_for_a_join_at_the_station_after_it(tmp_path: Path) -> None:
    data = merge_world([(0.0, 140.0)], others=[("mid", "e", 60.0)])
    data["formations"][0]["couple"] = {"at_station": "c"}
    out, events = _run(tmp_path, "join_after_merge", data)
    grants = [
        h for e in events if e["kind"] == "lock_granted" and e["subject"] == "c_down" for h in e["detail"]["holders"]
    ]
    assert grants == ["lead.000", "fol.000", "mid.000"]
    assert not [e for e in events if e["kind"] == "coupling_failed"]
    assert read_summary(out)["formations_asked"] == [
        {"id": "m0", "asked": "at_station c", "coupled": True, "where": "at_station c", "reason": None}
    ]


def _potsdam(
    tmp_path: Path,
    services: list[tuple[str, str, str, list[str], float]],
    formation: dict[str, Any],
    osm: Path = POTSDAM,
) -> dict[str, Any]:
    """A scenario on a city imported with 70 m platforms (Potsdam unless ``osm`` names another extract): one trip
    per service ``(id, from, to, via, departure)``, one formation ``j`` (leader ``lead``, follower ``fol``, 10 m
    target gap)."""
    world = tmp_path / "city"
    stem = osm.name.removesuffix(".osm.gz")
    args = ["network", "import", str(osm), "--out", str(world), "--platform-m", "70"]
    ok_stdout(run_railsim(args, cache_dir=tmp_path / "cache"))
    return {
        "name": "city_join",
        "world": {
            "net": str(world / f"{stem}.net.xml"),
            "additional": [str(world / f"{stem}.stops.tram.add.xml")],
            "vclass": "tram",
        },
        "simulation": {"step_s": 0.5, "duration_s": 1800.0, "seed": 1},
        "vehicles": {"tram": {"preset": "cq3_6car", "length_m": 27.0, "max_speed_kmh": 70.0}},
        "controllers": {"ato": {"type": "ato"}, "sep": {"type": "separation"}, "vc": {"type": "cacc"}},
        "roles": {"ato": "ato", "separation": "sep", "coupled": "vc"},
        "services": [
            {
                "id": sid,
                "from": origin,
                "to": dest,
                "via": via,
                "vehicle": "tram",
                "dwell_s": 20,
                "departures": {"times": [dep_s]},
            }
            for sid, origin, dest, via, dep_s in services
        ],
        "formations": [
            {
                "id": "j",
                "leader": {"service": "lead", "trip": 0},
                "follower": {"service": "fol", "trip": 0},
                "target_gap_m": 10.0,
                **formation,
            }
        ],
    }


def test_a_join_at_a_station_served_twice_in_a_row_leaves_together_on_dresden(tmp_path: Path) -> None:
    services = [
        ("lead", "Zoo", "Hauptbahnhof Nord", ["Lennéplatz"], 0.0),
        ("fol", "Strehlener Platz", "Hauptbahnhof Nord", ["Lennéplatz"], 120.0),
    ]
    data = _potsdam(tmp_path, services, {"couple": {"at_station": "lenneplatz"}}, osm=DRESDEN)
    out, _ = _run(tmp_path, "join", data)
    assert read_summary(out)["formations_asked"][0]["coupled"]
    at = [r for r in read_csv(out / "stops.csv") if r["station"] == "lenneplatz"]
    first = {r["trip_id"]: r for r in reversed(at)}  # each trip's first stop there
    assert len(at) == 4  # both trips stop twice at Lennéplatz (OSM maps two stop positions one after the other)
    assert abs(float(first["lead.000"]["departure_s"]) - float(first["fol.000"]["departure_s"])) <= 0.5


def test_a_follower_serving_a_stop_before_the_merge_waits_for_its_leader_from_when_it_leaves_it(
    tmp_path: Path,
) -> None:
    # the follower dwells 240 s at F, 1.3 km before the merge (within the engine's 1.5 km request distance); its
    # leader leaves E 300 s after it. Counted from its first held request (approaching F) the wait ran out before it
    # left F and it went first ("wrong_order"); counted from its leaving F it waits there for its leader
    data = merge_world([(300.0, 0.0)])
    fol = next(s for s in data["services"] if s["id"] == "fol")
    fol["dwell_s"] = {"default": 20, "stations": {"f": 240}}
    out, events = _run(tmp_path, "dwell_before_merge", data)
    ended = [e["detail"] for e in events if e["kind"] == "merge_wait_ended"]
    assert [e["reason"] for e in ended] == ["leader_asked"]
    grants = [
        h for e in events if e["kind"] == "lock_granted" and e["subject"] == "c_down" for h in e["detail"]["holders"]
    ]
    assert grants == ["lead.000", "fol.000"]
    assert read_summary(out)["formations_asked"][0]["coupled"]


def test_a_follower_held_short_of_the_merge_by_its_waiting_leader_couples_on_potsdam(tmp_path: Path) -> None:
    # lines 91 (from Dortustraße) and 93 (from Platz der Einheit/Nord) merge at points 30566579, right before the
    # second platform of Platz der Einheit/West; the first lies before the merge on the leader's way
    services = [
        ("lead", "Dortustraße", "Alter Markt/Landtag", ["Platz der Einheit/West"], 0.0),
        ("fol", "Platz der Einheit/Nord", "Platz der Einheit/Bildungsforum", ["Platz der Einheit/West"], 100.0),
    ]
    couple = {"couple": {"after_switch": "30566579"}, "decouple": {"before_switch": "4073068946"}}
    out, events = _run(tmp_path, "held_short", _potsdam(tmp_path, services, couple))
    (row,) = read_summary(out)["formations_asked"]
    on_run = row.pop("on_run")
    assert row == {
        "id": "j",
        "asked": "after_switch 30566579",
        "coupled": True,
        "where": "after_switch 30566579",
        "reason": None,
    }
    # the platform starts just past the merge: the leader stands before its follower may pass the points, and the
    # summary says so (the pair couples standing, as it does here)
    assert on_run["feasible"] is False and on_run["least_gap_m"] is None
    assert on_run["switch_interval_s"] > on_run["leader_to_halt_s"] - on_run["hold_s"]
    held = [e["detail"]["station"] for e in events if e["kind"] == "departure_held_for_follower"]
    assert held == ["platz-der-einheit-west"]


def test_the_leader_yields_to_a_branch_train_due_before_its_follower(tmp_path: Path) -> None:
    # br.000 leaves G 250 s after the leader left E, the follower 330 s after: when the leader came within the
    # request distance of the merge neither was on the line, it asked at once and br.000 ran between the two
    out, events = _run(tmp_path, "yield_scheduled", merge_world([(0.0, 330.0)], others=[("br", "g", 250.0)]))
    grants = [
        h for e in events if e["kind"] == "lock_granted" and e["subject"] == "c_down" for h in e["detail"]["holders"]
    ]
    assert grants == ["br.000", "lead.000", "fol.000"]
    assert [e["detail"]["to"] for e in events if e["kind"] == "merge_leader_yields"] == ["br.000"]
    assert read_summary(out)["formations_asked"][0]["coupled"]
