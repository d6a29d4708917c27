"""What an OpenStreetMap extract must be before netconvert reads it, checked in one streaming pass.

netconvert takes much of a damaged extract silently — a node at latitude ``nan``, a ``maxspeed`` of ``inf`` written
as the track's speed — and refuses the rest without saying where. :func:`check_osm_content` reads the file once
(:func:`network.xmlscan.scan`: well-formed XML, no entity declarations, an intact gzip stream) and refuses, naming
the element and its line:

* a root element other than ``<osm>``;
* a node whose ``lat``/``lon`` is not a number within -90..90 / -180..180 degrees;
* a way whose ``maxspeed`` is a number not above 0 or above :data:`MAX_SPEED_KMH` (one netconvert cannot read as a
  number — ``fast``, ``none`` — it ignores with a warning: the track's type speed applies);
* **a node id given twice with two different positions** (two extracts concatenated by hand, a broken merge): which
  of the two the tracks through it should pass is not in the file, and netconvert keeps one without a word. The same
  node given twice at the same position (an extract merged with itself) is the same node and passes.

The duplicate check keeps every node's id and position in three typed arrays (24 bytes a node: a city's extract of a
million nodes costs 24 MB), sorted once at the end, rather than a dictionary of Python objects (~150 bytes a node).
Ids that are not integers (OSM's are; an editor's are negative integers) are compared in a dictionary of their own.
"""

from __future__ import annotations

import math
from array import array
from pathlib import Path

import numpy as np

from network.xmlscan import scan
from railsim.errors import ConfigError
from railsim.inputs import excerpt

MAX_SPEED_KMH = 1000.0  # a way's maxspeed above this (or not above 0) is an error in the data, not a speed
OSM_SUFFIXES = (".osm", ".osm.xml", ".xml", ".osm.gz", ".osm.xml.gz", ".xml.gz", ".osm.pbf", ".pbf", ".o5m")


def input_name(osm_file: Path) -> str:
    """The extract's name without its OSM suffixes (``berlin.osm.gz`` → ``berlin``)."""
    name = osm_file.name
    for suffix in sorted(OSM_SUFFIXES, key=len, reverse=True):
        if name.endswith(suffix):
            return name[: -len(suffix)] or "osm"
    return osm_file.stem


def check_input(osm_file: Path) -> None:
    """The file exists and is OSM XML (netconvert of this SUMO reads no PBF/O5M)."""
    if not osm_file.is_file():
        raise ConfigError(osm_file, None, "expected an existing OpenStreetMap file (.osm, .osm.xml or .osm.gz)")
    if osm_file.name.endswith((".pbf", ".o5m")):
        raise ConfigError(
            osm_file,
            None,
            "this SUMO's netconvert reads OSM XML (.osm, .osm.gz), not PBF/O5M: convert it first, "
            f"e.g. `osmium cat {osm_file.name} -o {input_name(osm_file)}.osm`",
        )


class _NodePositions:
    """Every node's id, position and line, to find an id given twice at two positions (module docstring)."""

    def __init__(self) -> None:
        self.ids = array("q")
        self.lat = array("d")
        self.lon = array("d")
        self.lines = array("q")
        self.other: dict[str, tuple[float, float, int]] = {}  # ids that are not integers

    def add(self, osm_file: Path, node_id: str, lat: float, lon: float, line: int) -> None:
        try:
            key = int(node_id)
        except ValueError:
            seen = self.other.setdefault(node_id, (lat, lon, line))
            if seen[:2] != (lat, lon):
                raise _moved(osm_file, node_id, seen[2], line) from None
            return
        self.ids.append(key)
        self.lat.append(lat)
        self.lon.append(lon)
        self.lines.append(line)

    def check(self, osm_file: Path) -> None:
        """Refuse the first id (in file order of its second mention) given at two positions."""
        if len(self.ids) < 2:
            return
        ids = np.frombuffer(self.ids, dtype=np.int64)
        order = np.argsort(ids, kind="stable")  # equal ids keep file order
        same = ids[order[1:]] == ids[order[:-1]]
        if not same.any():
            return
        first, second = order[:-1][same], order[1:][same]
        lat, lon = np.frombuffer(self.lat, dtype=np.float64), np.frombuffer(self.lon, dtype=np.float64)
        moved = (lat[first] != lat[second]) | (lon[first] != lon[second])
        if moved.any():
            lines = np.frombuffer(self.lines, dtype=np.int64)
            k = int(np.argmin(np.where(moved, lines[second], np.iinfo(np.int64).max)))
            a, b = int(first[k]), int(second[k])
            raise _moved(osm_file, str(self.ids[a]), int(lines[a]), int(lines[b]))


def _moved(osm_file: Path, node_id: str, line_a: int, line_b: int) -> ConfigError:
    return ConfigError(
        osm_file,
        f"node[id={node_id}]",
        f"expected one position per node id, got two (lines {line_a} and {line_b}): the extract mixes two versions "
        "of the node; merge the extracts with a tool that keeps one (e.g. `osmium merge`)",
    )


def check_osm_content(osm_file: Path) -> None:
    """The one pass over the extract (module docstring); ConfigError naming the element and its line."""
    owner = ["", ""]  # the node/way/relation whose <tag> elements follow
    nodes = _NodePositions()

    def on_start(tag: str, attrs: dict[str, str], line: int) -> None:
        if tag in ("node", "way", "relation"):
            owner[:] = [tag, attrs.get("id", "")]
        if tag == "node":
            position = []
            for key, limit, what in (("lat", 90.0, "latitude"), ("lon", 180.0, "longitude")):
                raw = attrs.get(key)
                try:
                    value = float(raw if raw is not None else "nan")
                except ValueError:
                    value = math.nan
                if not -limit <= value <= limit:
                    raise ConfigError(
                        osm_file,
                        f"node[id={owner[1]}].{key}",
                        f"expected a {what} in -{limit:g}..{limit:g} degrees, got {excerpt(raw)} (line {line})",
                    )
                position.append(value)
            nodes.add(osm_file, owner[1], position[0], position[1], line)
        elif tag == "tag" and owner[0] == "way" and attrs.get("k") == "maxspeed":
            raw = attrs.get("v", "")
            try:
                kmh = float(raw.split()[0]) if raw.split() else None
            except ValueError:
                kmh = None  # not a number: netconvert warns and keeps the type's speed
            if kmh is not None and not 0.0 < kmh <= MAX_SPEED_KMH:
                raise ConfigError(
                    osm_file,
                    f"way[id={owner[1]}].maxspeed",
                    f"expected a speed above 0 and up to {MAX_SPEED_KMH:g} km/h, got {excerpt(raw)} (line {line})",
                )

    root = scan(osm_file, "an OpenStreetMap file", on_start)
    if root != "osm":
        raise ConfigError(osm_file, "root element", f"expected an OpenStreetMap file (an <osm> root), got <{root}>")
    nodes.check(osm_file)
