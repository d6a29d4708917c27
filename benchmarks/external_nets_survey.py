"""Survey: does railsim run on other people's SUMO rail nets? One row per net: validate, run, outcome.

    .venv/bin/python benchmarks/external_nets_survey.py NETS_DIR --out OUT_DIR [--duration-s 1800]
        [--services 3] [--trips 1] [--trip-gap-s 300] [--paths 1] [--stops-per-path 3] [--platform-m 150]
        [--formation] [--unrestricted-lanes CLASS]

``NETS_DIR`` holds SUMO nets (``*.net.xml``, searched recursively, one net per folder; e.g. SUMO's own
``tests/sumo/rail`` nets and the ``tools/game`` nets of the eclipse-sumo package). A net's additional files are the
``*.add.xml`` files next to it that hold ``trainStop``/``busStop`` elements. A net with fewer than two stations
railsim can route between gets **survey stops** (``OUT_DIR/<net>/survey.stops.add.xml``): ``trainStop``s of
``--platform-m`` (or the whole edge if shorter) on ``--stops-per-path`` edges of at least 20 m spread along the
longest rail path (by metres; its first and last edge among them), and with ``--paths`` > 1 along the next
longest paths that start and end elsewhere (another branch, the other track), so services cross, merge and meet.

For each net the survey writes a small scenario (``OUT_DIR/<net>/scenario.yaml``): up to ``--services`` ATO
services on the listed routes through the most stations (the longest, its opposite direction if the net has one,
the next longest, …), 60 s apart, each with ``--trips`` trips ``--trip-gap-s`` apart; ``--formation`` couples a
second unit behind the first service's first trip from its origin (``couple: {on_departure: true}``);
``--unrestricted-lanes`` is the world option for nets drawn without lane permissions. It runs ``railsim validate``
and ``railsim run`` in child processes and records the outcome:

* ``arrived n/m, stops k/l`` (trains that reached their last station, stops served of those scheduled; +
  ``collisions`` ours / ``sumo_collisions`` SUMO's when non-zero, and ``**HIDDEN COLLISIONS**`` when SUMO saw more
  than railsim reported) for a run that finished (``(exit 1)`` when railsim flagged it);
* ``refused: <message>`` for a clean refusal (exit 2, one line), at load, validate or run;
* ``exit 3: <message>`` for a run that ended in a deadlock, a stall, a train never inserted or a SUMO error;
* ``crash (exit N): <last stderr line>`` for anything else (a traceback, a SUMO crash, a timeout).

It prints a Markdown table (net × outcome) and writes it to ``OUT_DIR/survey.md``. The nets are not part of
the repository: fetch them yourself.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import networkx as nx
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from network.external import load_net  # noqa: E402
from railsim.errors import ConfigError  # noqa: E402

MAX_SERVICES = 3  # default of --services
STOP_LENGTH_M = 150.0  # survey platform length (or the whole edge if shorter)
MIN_STOP_EDGE_M = 20.0  # survey stops go on edges at least this long


@dataclass
class Row:
    net: str
    stations: str
    validate: str
    run: str


def _stop_files(net: Path) -> list[Path]:
    return sorted(
        p
        for p in net.parent.glob("*.add.xml")
        if "<trainStop" in (text := p.read_text(errors="replace")) or "<busStop" in text
    )


def _short(text: str, n: int = 160) -> str:
    text = " ".join(text.split())
    return text if len(text) <= n else text[: n - 1] + "…"


def _survey_stops(net: Path, folder: Path, opt: Options) -> Path:
    """trainStops on ``stops_per_path`` edges spread along the longest rail path of ``net`` (in metres: its first, its
    last and evenly between) and, with ``paths`` > 1, along the next longest paths that start and end elsewhere
    (another branch, the other track), so services cross, merge and meet."""
    bundle = load_net(net, [], unrestricted_lanes=opt.unrestricted_lanes)
    g = bundle.graph
    farthest: list[tuple[float, list[str]]] = []  # the longest path from each edge
    for src in sorted(g.nodes):
        dist, found = nx.single_source_dijkstra(g, src, weight="cost_m")
        dst = max(sorted(dist), key=lambda e: dist[e])
        if len(found[dst]) >= 2:
            farthest.append((dist[dst], found[dst]))
    farthest.sort(key=lambda t: (-t[0], t[1]))
    chosen: list[list[str]] = []
    used: set[str] = set()
    for _, path in farthest:
        long_edges = [e for e in path if float(g.nodes[e]["length_m"]) >= MIN_STOP_EDGE_M]  # no stop on a stub
        ends = {long_edges[0], long_edges[-1]} if len(long_edges) >= 2 else set()
        if not ends or (chosen and ends & used):
            continue
        chosen.append(long_edges)
        used |= set(path) | {str(g.nodes[e].get("bidi")) for e in path if g.nodes[e].get("bidi")}
        if len(chosen) >= opt.paths:
            break
    if not chosen:
        raise ConfigError(net, None, "survey: no rail path of two edges or more to put stops on")
    picks: list[str] = []
    for path in chosen:
        n = min(max(opt.stops_per_path, 2), len(path))
        picks += [path[round(i * (len(path) - 1) / (n - 1))] for i in range(n)]
    lines = []
    for k, edge in enumerate(dict.fromkeys(picks)):
        length = float(g.nodes[edge]["length_m"])
        lane = min(_lanes(bundle, edge))
        start = max(0.0, length - opt.platform_m - 1.0)
        end = max(start + 1.0, length - 1.0)
        lines.append(
            f'  <trainStop id="survey_{k}" lane="{lane}" startPos="{start:.1f}" endPos="{end:.1f}" name="S{k}"/>'
        )
    out = folder / "survey.stops.add.xml"
    out.write_text("<additional>\n" + "\n".join(lines) + "\n</additional>\n", encoding="utf-8")
    return out


def _lanes(bundle: Any, edge: str) -> set[str]:
    """Lane ids of ``edge`` that allow the bundle's rail vClass (read from SUMO's net with sumolib)."""
    import sumolib

    net = sumolib.net.readNet(str(bundle.net_file))
    return {ln.getID() for ln in net.getEdge(edge).getLanes() if ln.allows(bundle.vclass)}


def _pick_routes(bundle: Any, max_services: int = MAX_SERVICES) -> list[tuple[str, str]]:
    """Up to ``max_services`` (from, to) station pairs: the longest listed route, its opposite, the next longest…"""
    ranked = sorted(bundle.routes.values(), key=lambda r: (-len({s.station_id for s in r.stops}), -r.length_m, r.id))
    pairs: list[tuple[str, str]] = []
    for r in ranked:
        a, _, b = r.id.partition("->")
        for pair in ((a, b), (b, a)):
            if pair not in pairs and f"{pair[0]}->{pair[1]}" in bundle.routes:
                pairs.append(pair)
        if len(pairs) >= max_services:
            break
    return pairs[:max_services]


@dataclass
class Options:
    """How hard the survey drives each net (command-line options of the same names)."""

    duration_s: float = 1800.0
    services: int = MAX_SERVICES
    trips: int = 1
    trip_gap_s: float = 300.0
    stops_per_path: int = 3
    paths: int = 1
    platform_m: float = STOP_LENGTH_M
    formation: bool = False
    unrestricted_lanes: str | None = None


def _scenario(name: str, net: Path, adds: list[Path], pairs: list[tuple[str, str]], opt: Options) -> dict:
    """Services start 60 s apart; with ``trips`` > 1 each runs again every ``trip_gap_s``, so trains meet and
    follow. ``formation``: a second unit on the first service's first trip, coupled from its origin."""
    world: dict[str, Any] = {"net": str(net), "additional": [str(p) for p in adds]}
    if opt.unrestricted_lanes:
        world["unrestricted_lanes"] = opt.unrestricted_lanes
    services = [
        {
            "id": f"s{k}",
            "from": a,
            "to": b,
            "vehicle": "unit",
            "departures": {"times": [60.0 * k + opt.trip_gap_s * t for t in range(opt.trips)]},
            "dwell_s": 20,
        }
        for k, (a, b) in enumerate(pairs)
    ]
    raw: dict[str, Any] = {
        "name": f"survey_{name}",
        "world": world,
        "simulation": {"step_s": 0.5, "duration_s": opt.duration_s, "seed": 1},
        "vehicles": {"unit": {"preset": "cq3_6car"}},
        "controllers": {"ato": {"type": "ato"}, "sep": {"type": "separation"}, "vc": {"type": "cacc"}},
        "roles": {"ato": "ato", "separation": "sep", "coupled": "vc"},
        "services": services,
    }
    if opt.formation and services:
        follower = {**services[0], "id": "f0", "departures": {"times": [0.0]}}
        raw["services"] = [*services, follower]
        raw["formations"] = [
            {
                "id": "vc0",
                "leader": {"service": "s0", "trip": 0},
                "follower": {"service": "f0", "trip": 0},
                "target_gap_m": 30,
                "couple": {"on_departure": True},
            }
        ]
    return raw


def _railsim(args: list[str], timeout_s: float) -> tuple[int, str]:
    cmd = [sys.executable, "-m", "railsim.cli.main", *args]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s, cwd=ROOT, env=dict(os.environ))
    except subprocess.TimeoutExpired:
        return -1, f"timeout after {timeout_s:g} s"
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    return proc.returncode, lines[-1] if lines else ""


def _outcome(rc: int, err: str, summary: Path | None = None) -> str:
    if rc in (0, 1) and summary is not None and summary.exists():
        import json

        s = json.loads(summary.read_text())
        text = f"arrived {s.get('n_arrived')}/{s.get('n_trains')}, stops {s.get('n_stops_served')}/{s.get('n_stops_scheduled')}"
        for key in ("collisions", "sumo_collisions", "switch_violations"):
            if s.get(key):
                text += f", {key} {s[key]}"
        if (s.get("sumo_collisions") or 0) > (s.get("collisions") or 0):
            text += " **HIDDEN COLLISIONS**"  # SUMO saw more than railsim reported: the worst defect
        if rc != 0:
            text += f" (exit {rc})"
        return text
    if rc == 3:
        return "exit 3: " + _short(err.removeprefix("railsim: error: "))
    if rc == 0:
        return "ok"
    if rc == 2 and "Traceback" not in err:
        return "refused: " + _short(err.removeprefix("railsim: error: "))
    return f"crash (exit {rc}): {_short(err)}"


def survey_one(net: Path, out: Path, opt: Options) -> Row:
    name = net.parent.name  # one net per folder, named by its folder
    folder = out / name
    folder.mkdir(parents=True, exist_ok=True)
    adds = _stop_files(net)
    try:
        bundle = load_net(net, adds, unrestricted_lanes=opt.unrestricted_lanes)
        pairs = _pick_routes(bundle, opt.services)
        if not pairs:
            adds = [*adds, _survey_stops(net, folder, opt)]
            bundle = load_net(net, adds, unrestricted_lanes=opt.unrestricted_lanes)
            pairs = _pick_routes(bundle, opt.services)
    except ConfigError as exc:
        return Row(name, "-", "refused at load: " + _short(str(exc)), "-")
    stations = f"{len(bundle.stations)} ({'survey stops' if any(p.name.startswith('survey') for p in adds) else 'own'})"
    if not pairs:
        return Row(name, stations, "no route between any two stations", "-")
    path = folder / "scenario.yaml"
    path.write_text(yaml.safe_dump(_scenario(name, net, adds, pairs, opt), sort_keys=False), encoding="utf-8")
    rc, err = _railsim(["validate", str(path)], 600)
    validate = "ok" if rc == 0 else _outcome(rc, err)
    run_dir = folder / "run"
    rc, err = _railsim(["run", str(path), "--out", str(run_dir), "--no-progress"], 1200)
    return Row(name, stations, validate, _outcome(rc, err, run_dir / "summary.json"))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("nets", type=Path, help="folder of SUMO nets (*.net.xml, searched recursively)")
    ap.add_argument("--out", type=Path, required=True, help="folder for scenarios, runs and survey.md")
    ap.add_argument("--duration-s", type=float, default=1800.0, help="simulated horizon of each run [s]")
    ap.add_argument("--services", type=int, default=MAX_SERVICES, help="ATO services per net (routes picked)")
    ap.add_argument("--trips", type=int, default=1, help="trips per service (> 1: trains meet and follow)")
    ap.add_argument("--trip-gap-s", type=float, default=300.0, help="time between a service's trips [s]")
    ap.add_argument("--stops-per-path", type=int, default=3, help="survey stops along each path")
    ap.add_argument("--paths", type=int, default=1, help="survey paths (> 1: others start and end elsewhere)")
    ap.add_argument("--platform-m", type=float, default=STOP_LENGTH_M, help="survey platform length [m]")
    ap.add_argument("--formation", action="store_true", help="couple a second unit to s0's first trip")
    ap.add_argument("--unrestricted-lanes", default=None, help="world option: rail class of lanes without permissions")
    args = ap.parse_args(argv)
    opt = Options(
        args.duration_s,
        args.services,
        args.trips,
        args.trip_gap_s,
        args.stops_per_path,
        args.paths,
        args.platform_m,
        args.formation,
        args.unrestricted_lanes,
    )
    rows = []
    for net in sorted(args.nets.rglob("*.net.xml")):
        rows.append(survey_one(net, args.out, opt))
        print(
            f"| {rows[-1].net} | {rows[-1].stations} | {rows[-1].validate} | {rows[-1].run} |",
            file=sys.stderr,
            flush=True,
        )
    table = ["| net | stations | validate | run |", "|---|---|---|---|"] + [
        f"| {r.net} | {r.stations} | {r.validate} | {r.run} |" for r in rows
    ]
    text = "\n".join(table)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "survey.md").write_text(text + "\n", encoding="utf-8")
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
