"""Station ids and name matching write every letter in ASCII, including those Unicode NFKD leaves whole."""

from __future__ import annotations

from network.external import _slug
from network.names import ascii_letters
from railsim.timetable.matching import normalise


def test_station_ids_transliterate_letters_nfkd_leaves_whole() -> None:
    assert _slug("Marie-Juchacz-Straße") == "marie-juchacz-strasse"  # was marie-juchacz-stra-e
    assert _slug("Humboldtring/Nuthestraße") == "humboldtring-nuthestrasse"
    assert _slug("Østerport") == "osterport" and _slug("Łódź Fabryczna") == "lodz-fabryczna"
    assert _slug("Colón") == "colon" and _slug("Glienicker Brücke") == "glienicker-brucke"


def test_ascii_letters_keeps_other_characters_and_name_matching_agrees() -> None:
    assert ascii_letters("Platz der Einheit/Nord (Tram)") == "Platz der Einheit/Nord (Tram)"
    assert ascii_letters("Æbeløgade") == "AEbelogade"
    assert normalise("Marie-Juchacz-Straße") == normalise("Marie-Juchacz-Strasse")
