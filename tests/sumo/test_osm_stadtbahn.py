"""``railsim network import --light-rail-as-tram`` on the centre of Cologne's Stadtbahn
(tests/data/osm/cologne_stadtbahn.osm.gz, source and licence in the README there): one fleet runs on
``railway=light_rail`` and ``railway=tram`` track, so the import without the option splits the stations into
two classes, drops the tram stops beside light-rail track and says which option joins them."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from tests.helpers import run_railsim

COLOGNE = Path(__file__).resolve().parents[1] / "data" / "osm" / "cologne_stadtbahn.osm.gz"
CENTRE = "6.93,50.92,6.97,50.95"  # Neumarkt, Dom/Hbf, Barbarossaplatz


def _import(tmp_path: Path, *extra: str) -> tuple[str, dict[str, Any]]:
    out_dir = tmp_path / ("joined" if extra else "plain")
    res = run_railsim(
        ["network", "import", str(COLOGNE), "--out", str(out_dir), "--bbox", CENTRE, *extra],
        cache_dir=tmp_path / "cache",
    )
    assert res.returncode == 0, res.stderr + res.stdout
    summary = yaml.safe_load((out_dir / "cologne_stadtbahn.import.yaml").read_text(encoding="utf-8"))
    return res.stdout, summary


def test_a_stadtbahn_imports_as_one_tram_network_with_the_option(tmp_path: Path) -> None:
    out, plain = _import(tmp_path)
    assert set(plain["stations"]) == {"tram", "rail_urban"}
    assert "import with --light-rail-as-tram" in out
    out, joined = _import(tmp_path, "--light-rail-as-tram")
    assert set(joined["stations"]) == {"tram"}
    assert joined["stations"]["tram"] > 2 * (plain["stations"]["tram"] + plain["stations"]["rail_urban"])
    assert "import with --light-rail-as-tram" not in out
