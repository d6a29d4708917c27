"""Matching GTFS stops to the stations of an imported world, by name and by position.

A GTFS feed and an OSM extract name the same station differently often enough ("Japão-Liberdade" and "Japão -
Liberdade", "Rautatieasema" and "Rautatieasema (M)", "Sé" and "Se"), and a feed covers more than an extract.
:func:`match_stops` decides, for each GTFS stop (named by its parent station when it has one), which station of
the world it is:

1. **Name**: the normalised names are equal (:func:`normalise`: Unicode letters transliterated to ASCII —
   ``NFKD`` and the combining marks dropped, ``ß`` → ``ss`` —, lower case, a bracketed suffix like ``(M)``
   dropped, words joined by single spaces, common words for a station — "station", "estação", "metro"... —
   dropped). If several stations share the name, the nearest wins.
2. **Position**: otherwise the nearest station within ``radius_m`` (default 300 m) whose name is similar
   (``difflib`` ratio ≥ 0.6 on the normalised names), or, within ``radius_m / 3``, any station.

A name match farther than ``doubt_m`` (default 500 m) away, or a match by position alone, is **doubtful**: kept,
and listed with its distance so a user can check it. A stop with no match is **unmatched** (listed with the
nearest station and its distance). Positions come from the world's ``stations.yaml`` (lon/lat of each
station's platform centre, written by ``railsim network import``) and the feed's ``stop_lat``/``stop_lon``.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from network.geo import distance_m
from network.names import ascii_letters
from railsim.timetable.gtfs import GtfsStop

DEFAULT_RADIUS_M = 300.0
DEFAULT_DOUBT_M = 500.0
SIMILAR_RATIO = 0.6
_STOPWORDS = frozenset(
    {
        "station",
        "stn",
        "estacao",
        "metro",
        "metrô",
        "cptm",
        "tram",
        "bahnhof",
        "bf",
        "hbf",
        "gare",
        "stazione",
        "u",
        "s",
    }
)


@dataclass(frozen=True)
class WorldStation:
    """A station of the world: name (as the scenario names it), rail class, lon/lat (NaN if unknown)."""

    name: str
    vclass: str
    lon: float
    lat: float


@dataclass(frozen=True)
class Match:
    """How one GTFS stop matched: the station name (``None`` if unmatched), how, the distance [m], doubtful."""

    stop_id: str
    stop_name: str
    station: str | None
    how: str  # "name" | "position" | "none"
    distance_m: float
    doubtful: bool
    nearest: str = ""  # for an unmatched stop: the nearest station


def normalise(name: str) -> str:
    """A station name reduced to what identifies it (module docstring, step 1)."""
    text = ascii_letters(name).lower()
    text = re.sub(r"\([^)]*\)", " ", text)
    words = [w for w in re.split(r"[^a-z0-9]+", text) if w and w not in _STOPWORDS]
    return " ".join(words)


def _dist(stop: GtfsStop, st: WorldStation) -> float:
    if any(math.isnan(v) for v in (stop.lon, stop.lat, st.lon, st.lat)):
        return math.nan
    return distance_m(stop.lon, stop.lat, st.lon, st.lat)


def match_stops(
    stops: Iterable[GtfsStop],
    stations: Iterable[WorldStation],
    radius_m: float = DEFAULT_RADIUS_M,
    doubt_m: float = DEFAULT_DOUBT_M,
) -> dict[str, Match]:
    """``{stop_id: Match}`` for every GTFS stop (module docstring)."""
    stations = list(stations)
    by_name: dict[str, list[WorldStation]] = {}
    for st in stations:
        by_name.setdefault(normalise(st.name), []).append(st)
    out: dict[str, Match] = {}
    for stop in stops:
        key = normalise(stop.name)
        named = by_name.get(key, [])
        dists = [(_dist(stop, st), st) for st in stations]
        if named:
            d, st = min(((_dist(stop, s), s) for s in named), key=lambda x: (math.isnan(x[0]), x[0]))
            out[stop.stop_id] = Match(stop.stop_id, stop.name, st.name, "name", d, bool(d > doubt_m))
            continue
        near = sorted((x for x in dists if not math.isnan(x[0])), key=lambda x: x[0])
        chosen = None
        for d, st in near:
            if d > radius_m:
                break
            ratio = difflib.SequenceMatcher(None, key, normalise(st.name)).ratio()
            if ratio >= SIMILAR_RATIO or d <= radius_m / 3.0:
                chosen = (d, st)
                break
        if chosen is not None:
            out[stop.stop_id] = Match(stop.stop_id, stop.name, chosen[1].name, "position", chosen[0], True)
        else:
            nearest = near[0] if near else (math.nan, None)
            out[stop.stop_id] = Match(
                stop.stop_id, stop.name, None, "none", nearest[0], False, nearest[1].name if nearest[1] else ""
            )
    return out


def report_lines(matches: Mapping[str, Match], limit: int = 40) -> list[str]:
    """Readable lines: counts, then the doubtful and the unmatched stops (by name, once each)."""
    ok = [m for m in matches.values() if m.station and not m.doubtful]
    doubt = [m for m in matches.values() if m.station and m.doubtful]
    none = [m for m in matches.values() if not m.station]
    lines = [f"stops: {len(ok)} matched, {len(doubt)} doubtful, {len(none)} unmatched"]
    seen: set[tuple[str, str]] = set()
    for m in sorted(doubt, key=lambda m: m.stop_name)[:limit]:
        if (m.stop_name, m.station or "") in seen:
            continue
        seen.add((m.stop_name, m.station or ""))
        lines.append(f"  doubtful: {m.stop_name!r} -> {m.station!r} by {m.how}, {m.distance_m:.0f} m")
    names = sorted({(m.stop_name, m.nearest, m.distance_m) for m in none}, key=lambda x: x[0])
    for name, nearest, d in names[:limit]:
        where = f"nearest {nearest!r} at {d:.0f} m" if nearest else "no position"
        lines.append(f"  unmatched: {name!r} ({where})")
    if len(names) > limit:
        lines.append(f"  ... and {len(names) - limit} more unmatched")
    return lines
