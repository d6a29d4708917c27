"""Names to ASCII: the letters of a stop or station name written with a-z, so ids and name matches survive accents.

Unicode NFKD splits an accented letter into its base letter and a combining mark (``ó`` → ``o`` + ``´``); the
mark is dropped. Letters NFKD leaves whole get their usual transliteration (``ß`` → ``ss``, ``ø`` → ``o``,
``ł`` → ``l``, ``æ`` → ``ae``, ``œ`` → ``oe``, ``đ`` → ``d``, ``þ`` → ``th``): without it ``Marie-Juchacz-Straße``
became the station id ``marie-juchacz-stra-e``.
"""

from __future__ import annotations

import unicodedata

_WHOLE_LETTERS = str.maketrans(
    {"ß": "ss", "ẞ": "SS", "ø": "o", "Ø": "O", "ł": "l", "Ł": "L", "æ": "ae", "Æ": "AE", "œ": "oe", "Œ": "OE",
     "đ": "d", "Đ": "D", "þ": "th", "Þ": "TH"}
)  # fmt: skip


def ascii_letters(text: str) -> str:
    """``text`` with every letter written in ASCII (module docstring); other characters are kept."""
    text = unicodedata.normalize("NFKD", text.translate(_WHOLE_LETTERS))
    return "".join(ch for ch in text if not unicodedata.combining(ch))
