"""The cache of ``railsim network import`` keeps one entry per input *and name*: the files of an entry are named
after the input file (``<name>.net.xml``, ``<name>.import.yaml``), so a renamed copy of an extract imported
before must not find the other name's entry (it did, and the import ended with "<name>.import.yaml: No such
file or directory")."""

from __future__ import annotations

from pathlib import Path

from network.osm_import import _cache_key


def test_the_same_bytes_under_another_name_are_another_cache_entry(tmp_path: Path) -> None:
    first, second = tmp_path / "cut.osm.gz", tmp_path / "city_tram.osm.gz"
    first.write_bytes(b"same bytes")
    second.write_bytes(b"same bytes")
    assert _cache_key(first, None, None) != _cache_key(second, None, None)
    assert _cache_key(first, None, None) == _cache_key(tmp_path / "cut.osm.gz", None, None)
