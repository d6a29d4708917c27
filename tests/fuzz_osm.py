"""A seeded fuzz of the two ways a user's own map data comes in: ``railsim network import`` on an OpenStreetMap
extract, and a SUMO ``.net.xml`` with its stops file read as it is (``railsim network show``, a scenario's
``world: {net, additional}``) — the approach of :mod:`tests.fuzz`, aimed at XML instead of YAML.

**The bases.** OSM: the smallest committed extract, ``tests/data/osm/jena_tram_2014.osm.gz`` (142 ways, 1,905
nodes, 17 tram route relations). Net: the world ``tests/data/lines/mini_y.yaml`` (a 6 km double-track line with a
branch, 14 trainStops) built by ``railsim network build``; its bytes are the same for one SUMO version, so mutant
``k`` is the same bytes on every machine with the pinned eclipse-sumo (:func:`mutant` takes the base bytes, so
the mutator itself needs no netconvert).

**The mutants** (:func:`mutant`; even ``k`` an OSM extract, odd ``k`` a net and its stops file; one to three
mutations each, seeded by ``seed`` and ``k``):

* OSM, on the parsed tree (:data:`OSM_OPS`): a way whose nodes are missing, a way of one node or none, a
  duplicate node id elsewhere, a node's ``lat``/``lon`` ``nan``, ``inf``, out of range, empty or a word, every
  ``railway`` tag removed (no rail at all), a route relation with no members, members that do not exist or the
  relation itself as a member, ``maxspeed`` such as ``fast``, ``-50``, ``1e308``, ``50 mph``, an odd
  ``gauge``, stations without a name, a 500-character name with control characters;
* net, on the parsed tree (:data:`NET_OPS`): an edge without lanes, a lane of length ``0``, negative, ``nan``,
  ``inf`` or a word, a lane speed of ``0``/``nan``, a junction removed, a connection to a lane that does not
  exist, no rail vClass anywhere, an empty lane shape; on the stops file: a stop on a lane that does not exist,
  positions ``nan``/``inf``/reversed, a stop without a name;
* bytes, on either file (:data:`BYTE_OPS`): truncated, not well-formed, not OSM / not a net (another root
  element), empty, a broken gzip stream, a billion-laughs entity, a huge header and nothing after it.

**The outcome** (:func:`check`): the command runs through :func:`railsim.cli.main.main` in this process under a
per-mutant time limit (:func:`tests.fuzz_sections._timed`); netconvert and SUMO are child processes, killed when
the time is up. OSM: ``network import FILE --out DIR``, and when it succeeds ``network show`` on the world it
wrote (an import that writes a world railsim cannot read is a silently broken world). Net: ``network show NET -a
STOPS``, then ``railsim validate`` on a one-train scenario over it, and for a sample (``--runs``) a short
``railsim run`` in a child process. Each is **ok** (exit 0), **refused** (exit 2, one line ``railsim: error:
FILE: ...`` naming a mutated file, no traceback) or a **defect** (a traceback, exit 4, a hang, an error line that
names no input file, a refusal of a world the import wrote, a run that crashes a world that validated).
``python -m tests.fuzz_osm --mutants N`` prints the figures as JSON.
"""

from __future__ import annotations

import copy
import gzip
import json
import os
import random
import re
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

from tests import fuzz, fuzz_sections

ROOT = Path(__file__).resolve().parents[1]
OSM_BASE = ROOT / "tests" / "data" / "osm" / "jena_tram_2014.osm.gz"
NET_LINE = ROOT / "tests" / "data" / "lines" / "mini_y.yaml"
TIMEOUT_S = 60.0  # per command; a healthy import of the base takes under 3 s, a net check under 5 s
RUN_TIMEOUT_S = 300.0  # a short run in a child process

COORDS = ("nan", "inf", "-inf", "1e308", "91", "-181", "", "north", "0x10", "1e-320")
SPEEDS = ("fast", "-50", "1e308", "50 mph", "0", "nan", "inf", "", "80;100", "walk")
GAUGES = ("odd", "0", "-1435", "1e308", "1435;1000", "nan", "")
LENGTHS = ("0", "-5", "nan", "inf", "-inf", "", "long", "1e308")
MISSING = "999999999999"
BILLION_LAUGHS = (
    '<?xml version="1.0"?>\n<!DOCTYPE lolz [\n <!ENTITY lol "lol">\n'
    + "".join(f' <!ENTITY lol{i} "{("&lol" + (str(i - 1) if i > 1 else "") + ";") * 10}">\n' for i in range(1, 10))
    + "]>\n"
)


@dataclass(frozen=True)
class Mutant:
    """One hostile input: its kind (``osm`` or ``net``), what was done, and its files (name -> bytes; the OSM
    extract, or the net and its stops file)."""

    index: int
    kind: str
    ops: tuple[str, ...]
    files: dict[str, bytes]


# ---- the mutator -------------------------------------------------------------------------------------------------


def _choice(rng: random.Random, elems: list[ET.Element]) -> ET.Element | None:
    return elems[rng.randrange(len(elems))] if elems else None


def _tag(elem: ET.Element, key: str, value: str | None) -> None:
    """Set (``None``: remove) the OSM tag ``key`` of ``elem``."""
    for t in list(elem.findall("tag")):
        if t.get("k") == key:
            elem.remove(t)
    if value is not None:
        ET.SubElement(elem, "tag", {"k": key, "v": value})


def _ways(root: ET.Element) -> list[ET.Element]:
    return root.findall("way")


def _osm_way_nodes(rng: random.Random, root: ET.Element) -> str:
    way = _choice(rng, _ways(root))
    if way is None:
        return "way nodes (no way)"
    nds = way.findall("nd")
    how = rng.choice(("missing", "one", "none", "missing_all"))
    if how == "missing" and nds:
        nds[rng.randrange(len(nds))].set("ref", MISSING)
    elif how == "missing_all":
        for i, nd in enumerate(nds):
            nd.set("ref", f"{MISSING}{i}")
    else:
        for nd in nds[1 if how == "one" else 0 :]:
            way.remove(nd)
    return f"way {way.get('id')} nodes {how}"


def _osm_duplicate_node(rng: random.Random, root: ET.Element) -> str:
    node = _choice(rng, root.findall("node"))
    if node is None:
        return "duplicate node (no node)"
    twin = copy.deepcopy(node)
    twin.set("lat", str(float(node.get("lat", "0")) + rng.choice((0.0, 0.01, -45.0))))
    root.insert(rng.randrange(len(root) + 1), twin)
    return f"duplicate node {node.get('id')}"


def _osm_coordinate(rng: random.Random, root: ET.Element) -> str:
    nodes = root.findall("node")
    value, key = rng.choice(COORDS), rng.choice(("lat", "lon", "both"))
    picked = nodes if rng.random() < 0.2 else [n for n in [_choice(rng, nodes)] if n is not None]
    for node in picked:
        for k in ("lat", "lon") if key == "both" else (key,):
            node.set(k, value)
    return f"{key}={value!r} on {len(picked)} nodes"


def _osm_no_rail(rng: random.Random, root: ET.Element) -> str:
    for elem in root:
        _tag(elem, "railway", None)
    return "no railway tags"


def _osm_relation(rng: random.Random, root: ET.Element) -> str:
    rel = _choice(rng, root.findall("relation"))
    if rel is None:
        return "relation (none)"
    how = rng.choice(("empty", "missing", "self", "cycle"))
    members = rel.findall("member")
    if how == "empty":
        for m in members:
            rel.remove(m)
    elif how == "missing":
        for m in members:
            m.set("ref", MISSING)
    else:
        other = rel if how == "self" else _choice(rng, root.findall("relation")) or rel
        ET.SubElement(rel, "member", {"type": "relation", "ref": other.get("id", ""), "role": ""})
        if how == "cycle":
            ET.SubElement(other, "member", {"type": "relation", "ref": rel.get("id", ""), "role": ""})
    return f"relation {rel.get('id')} {how}"


def _osm_way_tag(rng: random.Random, root: ET.Element) -> str:
    key = rng.choice(("maxspeed", "gauge", "oneway", "railway"))
    value = rng.choice(
        {"maxspeed": SPEEDS, "gauge": GAUGES, "oneway": ("yes", "-1", "maybe"), "railway": ("", "x" * 300)}[key]
    )
    picked = _ways(root) if rng.random() < 0.3 else [w for w in [_choice(rng, _ways(root))] if w is not None]
    for way in picked:
        _tag(way, key, value)
    return f"{key}={value!r:.20} on {len(picked)} ways"


def _osm_station_name(rng: random.Random, root: ET.Element) -> str:
    stops = [n for n in root.findall("node") if n.find("tag[@k='name']") is not None]
    value = rng.choice((None, "", " ", "x" * 500 + "\x01\t", "A/B:C"))
    picked = stops if rng.random() < 0.5 else stops[: 1 + rng.randrange(max(1, len(stops)))]
    for node in picked:
        _tag(node, "name", value)
    return f"name={value!r:.12} on {len(picked)} stops"


OSM_OPS: tuple[Callable[[random.Random, ET.Element], str], ...] = (
    _osm_way_nodes,
    _osm_duplicate_node,
    _osm_coordinate,
    _osm_coordinate,
    _osm_no_rail,
    _osm_relation,
    _osm_way_tag,
    _osm_way_tag,
    _osm_station_name,
)


def _net_edges(root: ET.Element) -> list[ET.Element]:
    return [e for e in root.findall("edge") if e.get("function") != "internal"]


def _net_lanes(rng: random.Random, root: ET.Element) -> str:
    edge = _choice(rng, _net_edges(root))
    if edge is None:
        return "lanes (no edge)"
    how = rng.choice(("none", "length", "length", "speed", "shape", "allow"))
    lanes = edge.findall("lane")
    if how == "none":
        for ln in lanes:
            edge.remove(ln)
        return f"edge {edge.get('id')} without lanes"
    value = rng.choice(
        {"length": LENGTHS, "speed": ("0", "nan", "-1", "1e308"), "shape": ("", "0,0", "a,b c,d")}.get(
            how, ("passenger", "ship", "nothing")
        )
    )
    attr = {"none": "", "length": "length", "speed": "speed", "shape": "shape", "allow": "allow"}[how]
    for ln in lanes:
        ln.set(attr, value)
    return f"edge {edge.get('id')} lane {attr}={value!r}"


def _net_junction(rng: random.Random, root: ET.Element) -> str:
    junction = _choice(rng, [j for j in root.findall("junction") if j.get("type") != "internal"])
    if junction is None:
        return "junction (none)"
    root.remove(junction)
    return f"junction {junction.get('id')} removed"


def _net_connection(rng: random.Random, root: ET.Element) -> str:
    conn = _choice(rng, root.findall("connection"))
    if conn is None:
        return "connection (none)"
    how = rng.choice(("to", "toLane", "via", "from"))
    conn.set(how, {"to": "no_such_edge", "toLane": "7", "via": "no_such_lane_0", "from": "no_such_edge"}[how])
    return f"connection {how} missing"


def _net_no_rail(rng: random.Random, root: ET.Element) -> str:
    value = rng.choice(("passenger", None))
    for lane in root.iter("lane"):
        if value is None:
            lane.attrib.pop("allow", None)
            lane.attrib.pop("disallow", None)
        else:
            lane.set("allow", value)
    return f"no rail vClass (allow={value})"


def _stops_op(rng: random.Random, root: ET.Element) -> str:
    stop = _choice(rng, list(root))
    if stop is None:
        return "stop (none)"
    how = rng.choice(("lane", "start", "end", "reversed", "name", "id"))
    if how == "lane":
        stop.set("lane", rng.choice(("no_such_lane_0", "", "main_up_0_9")))
    elif how in ("start", "end"):
        stop.set(f"{how}Pos", rng.choice(LENGTHS))
    elif how == "reversed":
        stop.set("startPos", stop.get("endPos", "1"))
        stop.set("endPos", "1")
    elif how == "name":
        stop.attrib.pop("name", None)
    else:
        stop.set("id", root[0].get("id", ""))
    return f"stop {how}"


NET_OPS: tuple[Callable[[random.Random, ET.Element], str], ...] = (
    _net_lanes,
    _net_lanes,
    _net_junction,
    _net_connection,
    _net_no_rail,
)


def _root_start(text: str) -> int:
    """Where the root element's start tag begins (after the XML declaration and comments)."""
    return next((i for i, ch in enumerate(text) if ch == "<" and text[i + 1 : i + 2] not in ("?", "!")), 0)


def _byte_op(rng: random.Random, data: bytes) -> tuple[bytes, str]:
    """One mutation of a file's bytes (plain XML, before any gzip); the bytes and a label."""
    kind = rng.choice(("truncate", "malformed", "root", "empty", "laughs", "header"))
    if kind == "truncate":
        cut = rng.randrange(len(data) + 1)
        return data[:cut], f"truncated at {cut}"
    if kind == "malformed":
        i = rng.randrange(len(data) + 1)
        junk = rng.choice((b"<", b"&", b"\x00", b"</osm>", b'"', b"\xff\xfe"))
        return data[:i] + junk + data[i:], f"{junk!r} at {i}"
    if kind == "root":
        text = data.decode("utf-8", "replace")
        start = _root_start(text)
        end = text.find(" ", start)
        tag = text[start + 1 : end].strip(">")
        text = text[:start] + "<html" + text[end:]
        return text[: text.rfind("</")].encode() + b"</html>\n", f"root <{tag}> -> <html>"
    if kind == "empty":
        return rng.choice((b"", b"   \n", b'<?xml version="1.0"?>\n')), "empty"
    if kind == "laughs":
        text = data.decode("utf-8", "replace")
        start = _root_start(text)
        end = text.find(">", start) + 1
        return (BILLION_LAUGHS + text[start:end] + "&lol9;" + text[end:]).encode(), "billion laughs"
    text = data.decode("utf-8", "replace")
    header = text[: text.find(">", _root_start(text)) + 1].encode()
    return header + b"<!--" + b" " * 4_000_000 + b"-->", "header only (4 MB)"


def _gzip(data: bytes) -> bytes:
    return gzip.compress(data, mtime=0)


def osm_mutant(index: int, seed: int, base: bytes) -> Mutant:
    """OSM mutant ``index`` of campaign ``seed`` from the plain XML ``base`` (deterministic)."""
    rng = random.Random(seed * 1_000_003 + index * 7_919 + 1)
    ops: list[str] = []
    data = base
    if rng.random() < 0.75:
        root = ET.fromstring(base)
        for _ in range(rng.choice((1, 1, 2, 3))):
            ops.append(rng.choice(OSM_OPS)(rng, root))
        data = ET.tostring(root, encoding="utf-8", xml_declaration=True)
    if not ops or rng.random() < 0.15:
        data, label = _byte_op(rng, data)
        ops.append(label)
    if rng.random() < 0.5:
        packed = _gzip(data)
        if rng.random() < 0.1:
            cut = rng.randrange(10, max(11, len(packed)))
            packed = packed[:cut] + bytes(rng.randrange(256) for _ in range(16))
            ops.append(f"gzip broken at {cut}")
        return Mutant(index, "osm", tuple(ops), {"extract.osm.gz": packed})
    return Mutant(index, "osm", tuple(ops), {"extract.osm": data})


def net_mutant(index: int, seed: int, net: bytes, stops: bytes) -> Mutant:
    """Net mutant ``index`` of campaign ``seed`` from the net and stops file bytes (deterministic)."""
    rng = random.Random(seed * 1_000_003 + index * 7_919 + 2)
    ops: list[str] = []
    files = {"world.net.xml": net, "world.stops.add.xml": stops}
    target = rng.choice(("world.net.xml", "world.net.xml", "world.stops.add.xml"))
    if rng.random() < 0.8:
        root = ET.fromstring(files[target])
        for _ in range(rng.choice((1, 1, 2))):
            op = rng.choice(NET_OPS) if target == "world.net.xml" else _stops_op
            ops.append(op(rng, root))
        files[target] = ET.tostring(root, encoding="utf-8", xml_declaration=True)
    else:
        files[target], label = _byte_op(rng, files[target])
        ops.append(f"{target}: {label}")
    return Mutant(index, "net", tuple(ops), files)


def mutant(index: int, seed: int, osm_base: bytes, net_base: tuple[bytes, bytes]) -> Mutant:
    """Mutant ``index``: an OSM extract for even ``index``, a net for odd."""
    if index % 2 == 0:
        return osm_mutant(index, seed, osm_base)
    return net_mutant(index, seed, *net_base)


def bases(workdir: Path) -> tuple[bytes, tuple[bytes, bytes]]:
    """The plain OSM XML of the base extract, and the net and stops file of the base world (built here)."""
    from network import build

    bundle = build(NET_LINE, out_dir=workdir / "base")
    net = re.sub(rb"<!--.*?-->\s*", b"", bundle.net_file.read_bytes(), flags=re.DOTALL)  # netconvert's date and paths
    return gzip.decompress(OSM_BASE.read_bytes()), (net, bundle.stops_file.read_bytes())


# ---- running the commands ------------------------------------------------------------------------------------------


def _cli(argv: list[str], timeout_s: float) -> fuzz.Outcome:
    """``railsim ARGV`` through :func:`railsim.cli.main.main` in this process, under a time limit."""
    from railsim.cli.main import main

    return fuzz_sections._timed(lambda: main(argv), timeout_s)


def judge(res: fuzz.Outcome, inputs: list[Path]) -> tuple[str, str]:
    """``(ok | refused | defect, detail)``: exit 0 is ok; exit 2 with exactly one ``railsim: error:`` line naming
    one of ``inputs`` (log lines aside) and no traceback is a clean refusal; anything else is a defect."""
    if res.problem is not None:
        return "defect", res.problem
    if res.rc == 0:
        return "ok", ""
    errors = [ln for ln in res.stderr.splitlines() if ln.startswith("railsim: error: ")]
    if res.rc != 2:
        return "defect", f"exit {res.rc}: {res.stderr.strip()[-300:]}"
    if "Traceback" in res.stderr or len(errors) != 1:
        return "defect", f"expected one error line, got: {res.stderr.strip()[-300:]}"
    if not any(errors[0].startswith(f"railsim: error: {p}: ") for p in inputs):
        return "defect", f"the error names no input file: {errors[0][:300]}"
    return "refused", errors[0]


def _scenario(net: Path, stops: Path, out: Path) -> Path:
    """A one-train scenario from station A to station B of the base world, over ``net`` and ``stops``."""
    text = (
        f"name: fuzz_net\nworld: {{net: {json.dumps(str(net))}, additional: [{json.dumps(str(stops))}]}}\n"
        "simulation: {step_s: 0.5, duration_s: 240, seed: 1}\nvehicles: {cq6: {preset: cq3_6car}}\n"
        "controllers: {ato: {type: ato}, sep: {type: separation}}\nroles: {ato: ato, separation: sep}\n"
        "services:\n  - {id: up, from: a, to: c, vehicle: cq6, departures: {times: [0]}, dwell_s: 20}\n"
        "outputs: {formats: [csv]}\n"
    )
    out.write_text(text, encoding="utf-8")
    return out


def _run(scenario: Path, cache: Path) -> tuple[str, str]:
    """A short ``railsim run`` of an accepted net mutant in a child process (SUMO runs in it)."""
    import subprocess

    from tests.helpers import run_railsim

    out = scenario.with_suffix("")
    try:
        res = run_railsim(["run", str(scenario), "--out", str(out), "--no-progress"], cache, RUN_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return "defect", f"run: hang (> {RUN_TIMEOUT_S:g} s)"
    if res.returncode in (0, 1) and "Traceback" not in res.stderr:
        return "ok", f"run exit {res.returncode}"
    if res.returncode == 3 and "Traceback" not in res.stderr:
        return "ok", f"run exit 3: {res.stderr.strip()[-200:]}"
    return "defect", f"run exit {res.returncode}: {res.stderr.strip()[-300:]}"


def check(m: Mutant, workdir: Path, timeout_s: float = TIMEOUT_S, run: bool = False) -> tuple[str, str]:
    """Write ``m``'s files into ``workdir`` and classify what railsim makes of them (module docstring)."""
    paths = {name: workdir / name for name in m.files}
    for name, data in m.files.items():
        paths[name].write_bytes(data)
    if m.kind == "osm":
        (osm,) = paths.values()
        out = workdir / "world"
        verdict = judge(_cli(["network", "import", str(osm), "--out", str(out)], timeout_s), [osm])
        if verdict[0] != "ok":
            return verdict
        nets = sorted(out.glob("*.net.xml"))
        adds = [a for p in sorted(out.glob("*.stops.*.add.xml")) for a in ("-a", str(p))]
        shown = judge(_cli(["network", "show", str(nets[0]), *adds], timeout_s), [])
        return shown if shown[0] != "refused" else ("defect", f"the imported world is refused: {shown[1]}")
    net, stops = paths["world.net.xml"], paths["world.stops.add.xml"]
    verdict = judge(_cli(["network", "show", str(net), "-a", str(stops)], timeout_s), [net, stops])
    if verdict[0] != "ok":
        return verdict
    scenario = _scenario(net, stops, workdir / "scenario.yaml")
    verdict = judge(_cli(["validate", str(scenario)], timeout_s), [net, stops, scenario])
    if verdict[0] != "ok" or not run:
        return verdict
    return _run(scenario, Path(os.environ["RAILSIM_CACHE"]))


@dataclass
class Figures:
    """A campaign's counts (``by_kind``: kind -> outcome -> count) and every defect with its mutant."""

    mutants: int = 0
    ok: int = 0
    refused: int = 0
    defects: int = 0
    runs: int = 0
    by_kind: dict[str, dict[str, int]] = field(default_factory=dict)
    defect_list: list[str] = field(default_factory=list)
    seconds: float = 0.0
    slowest_s: float = 0.0


def campaign(n: int, workdir: Path, seed: int = 0, runs: int = 0, first: int = 0) -> Figures:
    """Check mutants ``first .. first + n - 1``; ``runs`` accepted net mutants (the first ones) also run."""
    import shutil

    workdir = workdir.resolve()
    old_cache = os.environ.get("RAILSIM_CACHE")
    os.environ["RAILSIM_CACHE"] = str(workdir / "cache")
    fig = Figures()
    t0 = time.perf_counter()
    try:
        osm_base, net_base = bases(workdir)
        for k in range(first, first + n):
            m = mutant(k, seed, osm_base, net_base)
            folder = workdir / f"mutant_{k:05d}"
            folder.mkdir()
            t1 = time.perf_counter()
            run = m.kind == "net" and fig.runs < runs
            outcome, detail = check(m, folder, run=run)
            fig.runs += int(run and outcome == "ok")
            fig.slowest_s = max(fig.slowest_s, time.perf_counter() - t1)
            fig.mutants += 1
            fig.ok, fig.refused = fig.ok + (outcome == "ok"), fig.refused + (outcome == "refused")
            fig.defects += outcome == "defect"
            counts = fig.by_kind.setdefault(m.kind, {"ok": 0, "refused": 0, "defect": 0})
            counts[outcome] += 1
            if outcome == "defect":
                fig.defect_list.append(f"mutant {k} ({m.kind}: {'; '.join(m.ops)}): {detail}")
            else:
                shutil.rmtree(folder, ignore_errors=True)
    finally:
        if old_cache is None:
            os.environ.pop("RAILSIM_CACHE", None)
        else:
            os.environ["RAILSIM_CACHE"] = old_cache
    fig.seconds = time.perf_counter() - t0
    return fig


def main(argv: list[str] | None = None) -> int:
    ap = fuzz.campaign_parser("Fuzz network import (OSM) and user nets; the figures as JSON.", 100, first=True)
    ap.add_argument("--runs", type=int, default=0, help="also run this many accepted net mutants (child processes)")
    ap.add_argument("--keep", metavar="DIR", help="work here and keep the defects' files (default: a temp folder)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="railsim-fuzz-osm-") as tmp:
        work = Path(args.keep) if args.keep else Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        fig = campaign(args.mutants, work, args.seed, args.runs, args.first)
    print(json.dumps(asdict(fig), indent=1))
    return 1 if fig.defects else 0


if __name__ == "__main__":
    sys.exit(main())
