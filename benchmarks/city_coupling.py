"""Coupled-where-asked rate of formations at the merges and stations of an imported city (OSM extract).

The world is imported from an OSM file (``railsim network import``, platforms widened to ``--platform-m`` so
that a coupled pair fits on them) and its lines become services (``railsim timetable import --from-lines``:
one service per line and direction, with the stops OSM lists). The coupling places are then found from the
topology alone — no station or switch is named here:

* a **merge** is a switch that two services' routes both pass on different legs and after which they run on the
  same edge; each such (switch, pair of legs) is taken once, with the pair of services that pass it;
* its **join station** is the first station past the merge where both stop, that is not the leader's
  destination, where the leader standing has its rear clear of the merge, and whose platform holds leader +
  target gap + follower (the engine's rule for a join station);
* where the two routes part again (the next switch both pass on different legs, or one's destination) the pair
  decouples: ``decouple: {before_switch: X}`` before a diverge, nothing when the follower's trip ends first on
  the shared track.

Each run takes one merge (run k: the k-th merge, cycling) and one kind (``--kind merge``: ``couple:
{after_switch: X}``; ``--kind station``: ``couple: {at_station: S}`` at its join station; ``--kind both``
alternates, even runs merges): ``--pairs`` formations one every ``--period`` s, the leader a trip of one
service, the follower a trip of the other timed from the free-run plans of both (the engine's own) so that
it reaches the merge (``merge``) or the join station (``station``) a random offset after its leader, uniform in
[``--offset-min``, ``--offset-max``] s (negative: before it); and on each of the two services one unrelated
train between the units of two successive formations (as in ``benchmarks/merge_coupling.py``). Seeds 1, 2, ….

Prints one JSON object: the merges found, per run the formations asked, coupled where asked, the failure
reasons (``coupling_failed`` events), collisions and switch violations, and the rate per kind.

    .venv/bin/python benchmarks/city_coupling.py --osm tests/data/osm/potsdam_tram_2025.osm.gz \\
        [--lines 91,92,...] [--runs 8] [--pairs 5] [--kind both] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from railsim.engine.joins import MERGE_CLEAR_M  # noqa: E402
from tests.helpers import read_csv, read_summary, run_mapping  # noqa: E402

RAILSIM = str(Path(sys.executable).with_name("railsim"))
START_S = 120.0  # no unit leaves earlier (the timetable is shifted when a follower would leave before it)
UNRELATED_CLEAR_S = 60.0  # an unrelated train leaves its origin this long after / before a formation's unit


@dataclass(frozen=True)
class Place:
    """A merge of two services' routes and where the pair joins and parts past it."""

    switch_id: str
    leader: dict[str, Any]  # the services as the timetable import wrote them
    follower: dict[str, Any]
    leader_at_merge_s: float  # free-run time from departure to the switch point
    follower_at_merge_s: float
    station: str | None  # the join station (None: no platform past the merge holds the pair)
    leader_at_station_s: float
    follower_at_station_s: float
    decouple_switch: str | None


def _time_at(trip: Any, chainage_m: float) -> float:
    """Free-run time after departure at which ``trip``'s front passes ``chainage_m`` (linear between the planned
    departure of the stop before and the planned arrival at the stop after: the coupling offsets are drawn over
    minutes, this is accurate to seconds)."""
    stops = [s for s in trip.stops if s.kind == "station"]
    before = [s for s in stops if s.mark_m <= chainage_m]
    after = [s for s in stops if s.mark_m > chainage_m]
    if not before or not after:
        return 0.0
    a, b = before[-1], after[0]
    t_a = trip.planned_departure_s.get(a.station_id, trip.depart_s) - trip.depart_s
    t_b = trip.planned_arrival_s.get(b.station_id, t_a) - trip.depart_s
    return float(t_a + (t_b - t_a) * (chainage_m - a.mark_m) / max(1.0, b.mark_m - a.mark_m))


def find_places(base: Path, gap_m: float) -> list[Place]:
    """Every merge of two services' routes in scenario ``base`` (module docstring), found from the routes the
    engine gives them and their free-run plans."""
    from network.world import load_world
    from railsim import scenario as scn_mod
    from railsim.engine.fleet import Fleet

    scn = scn_mod.load(base)
    bundle = load_world(scn.world, scn.source)
    if bundle.station_aliases:
        scn = scn_mod.with_station_ids(scn, bundle)
    fleet = Fleet(scn.source)
    fleet.build(scn, bundle, scn.simulation.step_s, scn.simulation.step_method)
    raw = {s["id"]: s for s in yaml.safe_load(base.read_text(encoding="utf-8"))["services"]}
    trips = {sid: ts[0] for sid, ts in fleet.trips_by_service.items() if ts}
    merges = {sid for sid, sw in bundle.switches.items() if sw.kind == "merge"}
    places: dict[tuple[str, str, str], Place] = {}
    for la, ta in sorted(trips.items()):
        for lb, tb in sorted(trips.items()):
            if la == lb:
                continue
            sw_b = {rs.switch_id: rs for rs in tb.route.switches}
            for ra in ta.route.switches:
                rb = sw_b.get(ra.switch_id)
                if ra.switch_id not in merges or rb is None or rb.leg == ra.leg or ra.leg != "normal":
                    continue  # the leader on the normal leg, the follower on the other: each merge once per pair
                key = (ra.switch_id, la.split("_")[0], lb.split("_")[0])
                if key in places:
                    continue
                places[key] = _place(ta, tb, ra, rb, raw[la], raw[lb], gap_m)
    return sorted(places.values(), key=lambda p: (p.station is None, p.switch_id, p.leader["id"]))


def _place(ta: Any, tb: Any, ra: Any, rb: Any, svc_a: dict, svc_b: dict, gap_m: float) -> Place:
    after_b = {s.station_id: s for s in tb.stops if s.kind == "station" and s.mark_m > rb.point_m}
    need_m = ta.vehicle.length_m + gap_m + tb.vehicle.length_m + 1.0
    station = next(
        (
            s
            for s in ta.stops
            if s.kind == "station"
            and s.mark_m - ta.vehicle.length_m - MERGE_CLEAR_M > ra.point_m  # the waiting leader clear of the merge
            and s.station_id in after_b
        ),
        None,
    )
    if station is not None and (station.is_destination or station.platform_m < need_m):
        station = None
    # where they part: the next switch past the merge both pass on different legs
    sw_b = {rs.switch_id: rs for rs in tb.route.switches if rs.point_m > rb.point_m}
    part = next(
        (
            rs.switch_id
            for rs in ta.route.switches
            if rs.point_m > ra.point_m and rs.switch_id in sw_b and sw_b[rs.switch_id].leg != rs.leg
        ),
        None,
    )
    return Place(
        switch_id=ra.switch_id,
        leader=svc_a,
        follower=svc_b,
        leader_at_merge_s=_time_at(ta, ra.point_m),
        follower_at_merge_s=_time_at(tb, rb.point_m),
        station=None if station is None else station.station_id,
        leader_at_station_s=0.0 if station is None else ta.planned_arrival_s[station.station_id] - ta.depart_s,
        follower_at_station_s=0.0 if station is None else tb.planned_arrival_s[station.station_id] - tb.depart_s,
        decouple_switch=part,
    )


def scenario(base: dict[str, Any], place: Place, kind: str, seed: int, args: argparse.Namespace) -> dict[str, Any]:
    """One run's scenario (module docstring): ``base`` gives the world, vehicles and controllers."""
    rng = np.random.default_rng(seed)
    if kind == "merge":
        lead_to_s, fol_to_s = place.leader_at_merge_s, place.follower_at_merge_s
        lo, hi = args.offset_min, args.offset_max
    else:
        lead_to_s, fol_to_s = place.leader_at_station_s, place.follower_at_station_s
        lo, hi = args.station_offset_min, args.station_offset_max
    pairs = []
    for k in range(args.pairs):
        lead_s = k * args.period
        pairs.append((lead_s, float(round(lead_s + lead_to_s - fol_to_s + rng.uniform(lo, hi), 1))))
    shift_s = max(0.0, START_S - min(min(p) for p in pairs))  # no unit leaves before START_S
    pairs = [(a + shift_s, b + shift_s) for a, b in pairs]
    order_l = sorted(range(len(pairs)), key=lambda k: pairs[k][0])
    order_f = sorted(range(len(pairs)), key=lambda k: pairs[k][1])
    trains = [
        ("lead", place.leader, [pairs[k][0] for k in order_l]),
        ("fol", place.follower, [pairs[k][1] for k in order_f]),
    ]
    for name, svc, unit in (("lead_x", place.leader, 0), ("fol_x", place.follower, 1)):
        times = sorted(p[unit] for p in pairs) + [max(max(p) for p in pairs) + args.period]
        for k, (after_s, before_s) in enumerate(zip(times, times[1:])):
            a_s, b_s = after_s + UNRELATED_CLEAR_S, before_s - UNRELATED_CLEAR_S
            if b_s > a_s:
                trains.append((f"{name}{k}", svc, [float(round(rng.uniform(a_s, b_s), 1))]))
    services = []
    for sid, svc, times in trains:
        spec = {key: svc[key] for key in ("from", "to", "via", "vehicle", "dwell_s") if key in svc}
        services.append({"id": sid, **spec, "departures": {"times": sorted(times)}})
    couple = {"after_switch": place.switch_id} if kind == "merge" else {"at_station": place.station}
    formations = []
    for k in range(len(pairs)):
        fm: dict[str, Any] = {
            "id": f"{kind}{k}",
            "leader": {"service": "lead", "trip": order_l.index(k)},
            "follower": {"service": "fol", "trip": order_f.index(k)},
            "target_gap_m": args.gap,
            "couple": couple,
        }
        if place.decouple_switch is not None:
            fm["decouple"] = {"before_switch": place.decouple_switch}
        formations.append(fm)
    duration_s = max(max(p) for p in pairs) + args.period + 3600.0
    return {
        "name": f"city_coupling_{kind}",
        "world": base["world"],
        "simulation": {**base["simulation"], "duration_s": duration_s, "seed": seed, "start_time": "00:00:00"},
        "vehicles": base["vehicles"],
        "controllers": base["controllers"],
        "roles": base["roles"],
        "services": services,
        "formations": formations,
    }


def _import(args: argparse.Namespace, folder: Path) -> Path:
    """The world and the lines' services (``railsim network import`` + ``timetable import --from-lines``)."""
    world = folder / "world"
    lines = ["--lines", args.lines] if args.lines else []
    cmd = [RAILSIM, "network", "import", str(args.osm), "--out", str(world), "--platform-m", str(args.platform_m)]
    subprocess.run(cmd + lines, check=True, capture_output=True, text=True)
    base = folder / "lines.yaml"
    cmd = [RAILSIM, "timetable", "import", "--from-lines", "--world", str(world), "--headway-s", "3600"]
    cmd += ["--from", "00:00", "--to", "00:01", "--out", str(base)] + lines
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    return base


def _failures(out: Path) -> list[dict[str, Any]]:
    """The ``coupling_failed`` events of a run: formation, time and the logged reason with its details."""
    return [
        {"formation": e["subject"], "t_s": float(e["t_s"]), **json.loads(e["detail"] or "{}")}
        for e in read_csv(out / "events.csv")
        if e["kind"] == "coupling_failed"
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--osm", type=Path, default=Path("tests/data/osm/potsdam_tram_2025.osm.gz"))
    ap.add_argument("--lines", default=None, help="line refs to import (default: every line)")
    ap.add_argument("--platform-m", type=float, default=70.0, help="platforms widened to this (network import)")
    ap.add_argument("--kind", choices=("merge", "station", "both"), default="both")
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--pairs", type=int, default=5)
    ap.add_argument("--period", type=float, default=600.0)
    ap.add_argument("--gap", type=float, default=10.0, help="target gap of the formations [m]")
    ap.add_argument("--offset-min", type=float, default=-60.0, help="merge: follower at the merge after its leader")
    ap.add_argument("--offset-max", type=float, default=120.0)
    ap.add_argument("--station-offset-min", type=float, default=20.0, help="station: follower due after its leader")
    ap.add_argument("--station-offset-max", type=float, default=150.0)
    ap.add_argument("--out", type=Path, default=None, help="keep the run folders here (default: a temporary folder)")
    args = ap.parse_args()
    t0 = time.perf_counter()
    folder = (args.out or Path(tempfile.mkdtemp(prefix="city_coupling_"))).resolve()  # railsim runs elsewhere
    folder.mkdir(parents=True, exist_ok=True)
    base_path = _import(args, folder)
    base = yaml.safe_load(base_path.read_text(encoding="utf-8"))
    base["world"] = {
        **base["world"],
        "net": str(folder / base["world"]["net"]),
        "additional": [str(folder / a) for a in base["world"]["additional"]],
    }
    places = [p for p in find_places(base_path, args.gap) if p.station is not None]
    if not places:
        raise SystemExit("no merge with a join station past it in this world")
    rows = []
    for seed in range(1, args.runs + 1):
        kind = args.kind if args.kind != "both" else ("merge" if seed % 2 else "station")
        place = places[((seed - 1) // (2 if args.kind == "both" else 1)) % len(places)]
        res, out = run_mapping(folder, scenario(base, place, kind, seed, args), f"run{seed}")
        where = {
            "switch": place.switch_id,
            "station": place.station,
            "leader": place.leader["id"],
            "follower": place.follower["id"],
            "decouple_before": place.decouple_switch,
        }
        if res.returncode != 0:
            rows.append(
                {
                    "seed": seed,
                    "kind": kind,
                    **where,
                    "exit": res.returncode,
                    "error": res.stderr.strip().splitlines()[-1:],
                }
            )
            continue
        s = read_summary(out)
        asked = s.get("formations_asked", [])
        rows.append(
            {
                "seed": seed,
                "kind": kind,
                **where,
                "exit": 0,
                "asked": len(asked),
                "coupled_where_asked": sum(1 for r in asked if r["coupled"]),
                "reasons": dict(Counter(r["reason"] for r in asked if not r["coupled"])),
                "failures": _failures(out),
                "collisions": s["collisions"],
                "switch_violations": s["switch_violations"],
                "arrived": f"{s['n_arrived']}/{s['n_trains']}",
            }
        )
    ok = [r for r in rows if r["exit"] == 0]
    per_kind = {}
    for kind in ("merge", "station"):
        rk = [r for r in ok if r["kind"] == kind]
        asked_n, coupled_n = sum(r["asked"] for r in rk), sum(r["coupled_where_asked"] for r in rk)
        if rk:
            per_kind[kind] = {
                "asked": asked_n,
                "coupled_where_asked": coupled_n,
                "rate": coupled_n / asked_n if asked_n else None,
            }
    print(
        json.dumps(
            {
                "osm": str(args.osm),
                "settings": {k: str(v) for k, v in vars(args).items()} | {"out": str(folder)},
                "places_found": len(places),
                "runs": rows,
                "per_kind": per_kind,
                "collisions": sum(r["collisions"] for r in ok),
                "switch_violations": sum(r["switch_violations"] for r in ok),
                "failed_runs": len(rows) - len(ok),
                "wall_s": round(time.perf_counter() - t0, 1),
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    main()
