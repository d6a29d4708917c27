"""``railsim network import --light-rail-as-tram``: where one fleet runs on light-rail and tram track (a Stadtbahn
such as Cologne's), light-rail track imports as tram track, so the network is one class (without it Cologne's
extract splits into 43 tram and 23 light-rail stations and netconvert drops 356 tram stops beside light-rail
track; with it, 216 tram stations)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from network.osm_import import LIGHT_RAIL_AS_TRAM_TYPES, _cache_key, light_rail_as_tram_types, netconvert_args


def test_the_option_adds_a_type_file_that_makes_light_rail_tram_track(tmp_path: Path) -> None:
    plain = netconvert_args(Path("city.osm"), tmp_path, "city", None)
    stadtbahn = netconvert_args(Path("city.osm"), tmp_path, "city", None, light_rail_as_tram=True)
    types_plain = plain[plain.index("--type-files") + 1].split(",")
    types = stadtbahn[stadtbahn.index("--type-files") + 1].split(",")
    assert types[:-1] == types_plain  # SUMO's maps first: railsim's entry overrides theirs
    assert types[-1] == str(tmp_path / LIGHT_RAIL_AS_TRAM_TYPES)
    (entry,) = ET.fromstring(light_rail_as_tram_types())
    assert entry.get("id") == "railway.light_rail" and entry.get("allow") == "tram"


def test_the_option_is_part_of_the_cache_key(tmp_path: Path) -> None:
    osm = tmp_path / "city.osm"
    osm.write_text('<osm version="0.6"/>', encoding="utf-8")
    assert _cache_key(osm, None, None) != _cache_key(osm, None, None, light_rail_as_tram=True)
