"""Geographic positions on a SUMO net made from OpenStreetMap: net x/y (metres) -> longitude/latitude (degrees).

netconvert projects OSM to UTM (WGS84 ellipsoid) and shifts the result by the net's ``netOffset``; the
``<location>`` element keeps both (``projParameter="+proj=utm +zone=35 ..."``). Matching a GTFS stop (lon/lat)
to a station of the net needs the way back: :func:`net_to_lonlat` undoes the offset and inverts the UTM
projection with the series of Snyder, *Map Projections — A Working Manual* (USGS PP 1395, 1987, eqs. 8-18 to
8-25; sub-millimetre within a UTM zone, far below the tens of metres a stop match cares about). No pyproj:
only the transverse Mercator on WGS84 is ever needed here.

A net without a UTM ``projParameter`` (a drawn net, or one already in lon/lat: ``proj.plain-geo``) has no
geographic position: :func:`read_location` returns ``None`` and callers match by name only.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

WGS84_A_M = 6378137.0  # semi-major axis
WGS84_F = 1.0 / 298.257223563  # flattening
UTM_K0 = 0.9996  # scale on the central meridian
UTM_FALSE_EASTING_M = 500000.0
UTM_FALSE_NORTHING_SOUTH_M = 10000000.0


@dataclass(frozen=True)
class NetLocation:
    """The projection of a net: UTM ``zone`` (1-60), ``south`` hemisphere, and the net's offset (x, y) [m]."""

    zone: int
    south: bool
    offset_x_m: float
    offset_y_m: float


def read_location(net_file: Path) -> NetLocation | None:
    """The ``<location>`` of a .net.xml when it is a UTM projection, else ``None`` (reads only the head)."""
    for _, elem in ET.iterparse(str(net_file), events=("start",)):
        if elem.tag != "location":
            continue
        proj = elem.get("projParameter", "")
        m = re.search(r"\+proj=utm\b.*?\+zone=(\d+)", proj)
        if not m:
            return None
        dx, _, dy = (elem.get("netOffset") or "0,0").partition(",")
        return NetLocation(int(m.group(1)), "+south" in proj, float(dx), float(dy or 0.0))
    return None


def utm_to_lonlat(easting_m: float, northing_m: float, zone: int, south: bool) -> tuple[float, float]:
    """(longitude, latitude) in degrees of a UTM coordinate on WGS84 (Snyder 1987, eqs. 8-18 to 8-25)."""
    e2 = WGS84_F * (2.0 - WGS84_F)
    ep2 = e2 / (1.0 - e2)
    x = easting_m - UTM_FALSE_EASTING_M
    y = northing_m - (UTM_FALSE_NORTHING_SOUTH_M if south else 0.0)
    mu = (y / UTM_K0) / (WGS84_A_M * (1.0 - e2 / 4.0 - 3.0 * e2**2 / 64.0 - 5.0 * e2**3 / 256.0))
    e1 = (1.0 - math.sqrt(1.0 - e2)) / (1.0 + math.sqrt(1.0 - e2))
    phi1 = (
        mu
        + (3.0 * e1 / 2.0 - 27.0 * e1**3 / 32.0) * math.sin(2.0 * mu)
        + (21.0 * e1**2 / 16.0 - 55.0 * e1**4 / 32.0) * math.sin(4.0 * mu)
        + (151.0 * e1**3 / 96.0) * math.sin(6.0 * mu)
        + (1097.0 * e1**4 / 512.0) * math.sin(8.0 * mu)
    )
    sin1, cos1, tan1 = math.sin(phi1), math.cos(phi1), math.tan(phi1)
    c1 = ep2 * cos1**2
    t1 = tan1**2
    n1 = WGS84_A_M / math.sqrt(1.0 - e2 * sin1**2)
    r1 = WGS84_A_M * (1.0 - e2) / (1.0 - e2 * sin1**2) ** 1.5
    d = x / (n1 * UTM_K0)
    lat = phi1 - (n1 * tan1 / r1) * (
        d**2 / 2.0
        - (5.0 + 3.0 * t1 + 10.0 * c1 - 4.0 * c1**2 - 9.0 * ep2) * d**4 / 24.0
        + (61.0 + 90.0 * t1 + 298.0 * c1 + 45.0 * t1**2 - 252.0 * ep2 - 3.0 * c1**2) * d**6 / 720.0
    )
    lon = (
        d
        - (1.0 + 2.0 * t1 + c1) * d**3 / 6.0
        + (5.0 - 2.0 * c1 + 28.0 * t1 - 3.0 * c1**2 + 8.0 * ep2 + 24.0 * t1**2) * d**5 / 120.0
    ) / cos1
    lon0 = math.radians((zone - 1) * 6 - 180 + 3)
    return math.degrees(lon0 + lon), math.degrees(lat)


def net_to_lonlat(loc: NetLocation, x_m: float, y_m: float) -> tuple[float, float]:
    """(longitude, latitude) of a point of the net (net coordinates, metres)."""
    return utm_to_lonlat(x_m - loc.offset_x_m, y_m - loc.offset_y_m, loc.zone, loc.south)


def distance_m(lon1: float, lat1: float, lon2: float, lat2: float) -> float:
    """Great-circle distance [m] between two lon/lat points (haversine on a 6,371 km sphere)."""
    p1, p2 = math.radians(lat1), math.radians(lat2)
    dp, dl = p2 - p1, math.radians(lon2 - lon1)
    h = math.sin(dp / 2.0) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dl / 2.0) ** 2
    return 2.0 * 6371000.0 * math.asin(min(1.0, math.sqrt(h)))
