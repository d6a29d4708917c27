"""Clock times: the one place where scenario files speak "HH:MM" instead of seconds.

Inside the program every time is seconds from t = 0. A scenario's ``simulation.start_time`` and its
departure strings are clock times; the validator turns them into seconds after midnight with
:func:`parse_clock` and subtracts the start time. Hours run to 47 so that a service day can continue past
midnight ("25:10" is ten past one the next morning). :func:`format_clock` goes the other way for messages
and labels.
"""

from __future__ import annotations

import math
import re

_CLOCK_RE = re.compile(r"^(\d{1,2}):(\d{2})(?::(\d{2}(?:\.\d+)?))?$")
CLOCK_WHAT = 'a clock time "HH:MM" or "HH:MM:SS"'  # what an error message says was expected


def parse_clock(text: str) -> float:
    """Seconds after midnight of ``"HH:MM"`` / ``"HH:MM:SS[.s]"`` (hours 0–47). ValueError if malformed."""
    m = _CLOCK_RE.match(text.strip()) if isinstance(text, str) else None
    if not m:
        raise ValueError(text)
    hours, minutes = int(m.group(1)), int(m.group(2))
    seconds = float(m.group(3)) if m.group(3) else 0.0
    if hours > 47 or minutes > 59 or seconds >= 60.0:
        raise ValueError(text)
    return hours * 3600.0 + minutes * 60.0 + seconds


def format_clock(seconds_after_midnight: float) -> str:
    """``"HH:MM:SS"`` (fractions of a second kept when present)."""
    whole = int(math.floor(seconds_after_midnight))
    frac = seconds_after_midnight - whole
    h, rem = divmod(whole, 3600)
    m, s = divmod(rem, 60)
    text = f"{h:02d}:{m:02d}:{s:02d}"
    return text + f"{frac:.3f}"[1:].rstrip("0").rstrip(".") if frac > 1e-9 else text
