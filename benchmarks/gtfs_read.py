"""GTFS reading on a city-sized feed: :func:`railsim.timetable.gtfs.read_trips` of this checkout against another
commit's (default ``main``), wall time and peak memory, in the same run.

A synthetic but valid feed is written for each size (deflated zip, like a real one): ``ROWS`` stop_times rows as
trips of 40 calls, mostly **bus** trips (``route_type`` 3, as in a real city's feed) and a share of metro trips
(type 1; ``--rail-share``), on a weekday and a weekend service, with a ``calendar_dates.txt``, 2,000 stops (the
metro's with parent stations) and the usual extra columns (``shape_id``, ``pickup_type``,
``shape_dist_traveled``...). Each side reads the metro trips of a Tuesday, 06:00-10:00, in its own fresh process
(``PYTHONPATH`` its own ``railsim``; the other commit's is ``git archive`` d into a temporary folder): the wall
time of the call, the process's peak RSS (``VmHWM``; ``ru_maxrss`` would keep the parent's across ``exec``) and
its RSS before the call (imports done, with those ``read_trips`` makes in its body: a GTFS library), so
``peak_rss_mb - rss_before_mb`` is what the reading itself holds at its peak. Sides alternate over ``--reps`` and
the medians count; both sides must return the same trips (ids, routes, blocks, calls) and stops (ids and
positions; names are left out, a base may name a platform differently).

Prints one JSON object: per size, each side's runs and medians, and ``ratio_wall`` / ``ratio_peak_rss`` =
this checkout ÷ base (below 1: this checkout is faster or smaller).

    .venv/bin/python benchmarks/gtfs_read.py [--rows 80000,1000000] [--base main] [--reps 3]
"""

from __future__ import annotations

import argparse
import json
import os
import random
import statistics
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
CALLS = 40
N_STOPS = 2000

# one side's read, in its own process; one JSON line
CHILD = """
import hashlib, json, sys, time
from datetime import date
from railsim.timetable import gtfs
for module in sys.argv[2:]:  # what the side's read_trips imports on its first call: imported untimed
    __import__(module)
def rss_mb(key):
    with open("/proc/self/status") as f:
        return next(int(ln.split()[1]) for ln in f if ln.startswith(key + ":")) / 1024
before = rss_mb("VmRSS")
t0 = time.perf_counter()
feed = gtfs.read_trips(sys.argv[1], date(2019, 10, 1), 6 * 3600.0, 10 * 3600.0)
wall = time.perf_counter() - t0
peak = rss_mb("VmHWM")
h = hashlib.sha256()
for t in feed.trips:
    calls = [(c.stop_id, float(c.arrival_s), float(c.departure_s)) for c in t.calls]
    h.update(repr((t.trip_id, t.route_id, t.block_id, calls)).encode())
for s in sorted(feed.stops):
    h.update(repr((s, float(feed.stops[s].lon), float(feed.stops[s].lat))).encode())
print(json.dumps({"wall_s": round(wall, 3), "peak_rss_mb": round(peak, 1), "rss_before_mb": round(before, 1),
                  "trips": len(feed.trips), "stops": len(feed.stops), "digest": h.hexdigest()[:16]}))
"""


def _clock(t: int) -> str:
    return f"{t // 3600:02d}:{t % 3600 // 60:02d}:{t % 60:02d}"


def write_feed(path: Path, rows: int, rail_share: float, seed: int = 1) -> dict[str, int]:
    """A valid feed of about ``rows`` stop_times rows at ``path`` (module docstring); its table sizes."""
    rng = random.Random(seed)
    n_trips = max(2, rows // CALLS)
    n_rail = max(1, round(n_trips * rail_share))
    rail_routes = [f"M{k}" for k in range(1, 6)]
    bus_routes = [f"B{k}" for k in range(300)]
    metro_stops = [f"m{k}" for k in range(100)]
    bus_stops = [f"s{k}" for k in range(N_STOPS - len(metro_stops) - 20)]
    tables: dict[str, str] = {
        "agency.txt": "agency_id,agency_name,agency_url,agency_timezone\na,City Transit,http://a,America/Sao_Paulo\n",
        "calendar.txt": "service_id,monday,tuesday,wednesday,thursday,friday,saturday,sunday,start_date,end_date\n"
        "wk,1,1,1,1,1,0,0,20190101,20191231\nwe,0,0,0,0,0,1,1,20190101,20191231\n",
        "calendar_dates.txt": "service_id,date,exception_type\nwk,20191225,2\nwe,20191225,1\nwk,20191115,2\n",
        "routes.txt": "route_id,agency_id,route_short_name,route_long_name,route_type,route_color\n"
        + "".join(f"{r},a,{r},Metro {r},1,ff0000\n" for r in rail_routes)
        + "".join(f"{r},a,{r},Bus {r},3,0000ff\n" for r in bus_routes),
    }
    stops = ["stop_id,stop_name,stop_lat,stop_lon,location_type,parent_station\n"]
    for k in range(20):
        stops.append(f"P{k},Station {k},{-23.5 - k * 0.003:.6f},{-46.6 + k * 0.004:.6f},1,\n")
    for k, sid in enumerate(metro_stops):
        stops.append(f"{sid},Platform {k},{-23.5 - k % 20 * 0.003:.6f},{-46.6 + k % 20 * 0.004:.6f},0,P{k % 20}\n")
    for k, sid in enumerate(bus_stops):
        stops.append(f"{sid},Rua {k},{-23.4 - rng.random() * 0.3:.6f},{-46.5 - rng.random() * 0.3:.6f},0,\n")
    tables["stops.txt"] = "".join(stops)
    trips = ["route_id,service_id,trip_id,trip_headsign,direction_id,block_id,shape_id\n"]
    stop_times = [
        "trip_id,arrival_time,departure_time,stop_id,stop_sequence,pickup_type,drop_off_type,shape_dist_traveled\n"
    ]
    rail_at = set(rng.sample(range(n_trips), n_rail))
    for k in range(n_trips):
        rail = k in rail_at
        route = rng.choice(rail_routes if rail else bus_routes)
        service = "wk" if rng.random() < 0.75 else "we"
        tid = f"{route}_{service}_{k:07d}"
        trips.append(f"{route},{service},{tid},Terminal {route},{k % 2},,{route}_shp{k % 2}\n")
        pool = metro_stops if rail else bus_stops
        first = rng.randrange(len(pool) - CALLS)
        t = rng.randrange(5 * 3600, 23 * 3600)
        dist = 0.0
        for seq in range(1, CALLS + 1):
            arr = t
            t += 20 if rail else rng.choice((0, 10, 20))
            stop_times.append(f"{tid},{_clock(arr)},{_clock(t)},{pool[first + seq - 1]},{seq},0,0,{dist:.1f}\n")
            t += rng.randrange(60, 150)
            dist += rng.uniform(300.0, 900.0)
    tables["trips.txt"] = "".join(trips)
    tables["stop_times.txt"] = "".join(stop_times)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, text in tables.items():
            zf.writestr(name, text)
    return {
        "trips": n_trips,
        "rail_trips": n_rail,
        "stop_times": len(stop_times) - 1,
        "stop_times_mb": round(len(tables["stop_times.txt"]) / 1e6, 1),
        "zip_mb": round(path.stat().st_size / 1e6, 1),
    }


def base_tree(rev: str, into: Path) -> Path:
    """``railsim`` at commit ``rev`` (``git archive``) under ``into``."""
    data = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "railsim"], capture_output=True, check=True).stdout
    into.mkdir(parents=True)
    subprocess.run(["tar", "-x", "-C", str(into)], input=data, check=True)
    return into


def lazy_imports(tree: Path) -> list[str]:
    """The modules the side's ``read_trips`` imports inside its body (a GTFS library), to import before timing."""
    text = (tree / "railsim" / "timetable" / "gtfs.py").read_text(encoding="utf-8")
    body = text[text.index("def read_trips(") :]
    return [ln.split()[1] for ln in body.splitlines() if ln.startswith("    import ")]


def run_side(tree: Path, feed: Path) -> dict[str, Any]:
    env = {**os.environ, "PYTHONPATH": str(tree), "PYTHONHASHSEED": "0"}
    cmd = [sys.executable, "-c", CHILD, str(feed), *lazy_imports(tree)]
    done = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True)
    lines = [ln for ln in done.stdout.splitlines() if ln.startswith("{")]
    if done.returncode != 0 or not lines:
        raise SystemExit(f"the read in {tree} failed (exit {done.returncode}): {done.stderr.strip()[-500:]}")
    res: dict[str, Any] = json.loads(lines[-1])
    return res


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rows", default="80000,1000000", help="stop_times rows of each feed, comma-separated")
    ap.add_argument("--rail-share", type=float, default=0.04, help="share of the trips that are metro trips")
    ap.add_argument("--base", default="main", help="the commit to compare this checkout with")
    ap.add_argument("--reps", type=int, default=3)
    args = ap.parse_args(argv)
    out: dict[str, Any] = {"base": args.base, "reps": args.reps, "sizes": []}
    with tempfile.TemporaryDirectory(prefix="railsim-gtfs-read-") as tmp:
        sides = {"base": base_tree(args.base, Path(tmp) / "base"), "head": ROOT}
        for rows in (int(r) for r in args.rows.split(",")):
            feed = Path(tmp) / f"feed_{rows}.zip"
            size: dict[str, Any] = {"rows": rows, "feed": write_feed(feed, rows, args.rail_share)}
            runs: dict[str, list[dict[str, Any]]] = {"base": [], "head": []}
            for _ in range(args.reps):
                for name, tree in sides.items():
                    runs[name].append(run_side(tree, feed))
            for name, side_runs in runs.items():
                size[name] = {
                    "wall_s": statistics.median(r["wall_s"] for r in side_runs),
                    "peak_rss_mb": statistics.median(r["peak_rss_mb"] for r in side_runs),
                    "rss_before_mb": statistics.median(r["rss_before_mb"] for r in side_runs),
                    "runs_wall_s": [r["wall_s"] for r in side_runs],
                    "trips": side_runs[0]["trips"],
                    "stops": side_runs[0]["stops"],
                }
            digests = {r["digest"] for side_runs in runs.values() for r in side_runs}
            size["same_result"] = len(digests) == 1
            b, h = size["base"], size["head"]
            size["ratio_wall"] = round(h["wall_s"] / b["wall_s"], 3)
            size["ratio_peak_rss"] = round(h["peak_rss_mb"] / b["peak_rss_mb"], 3)
            size["ratio_read_rss"] = round(
                (h["peak_rss_mb"] - h["rss_before_mb"]) / max(b["peak_rss_mb"] - b["rss_before_mb"], 1e-9), 3
            )
            out["sizes"].append(size)
            feed.unlink()
    print(json.dumps(out, indent=1))
    return 0 if all(s["same_result"] for s in out["sizes"]) else 1


if __name__ == "__main__":
    sys.exit(main())
