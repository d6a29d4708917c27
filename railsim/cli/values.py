"""Command-line values checked where argparse reads them, and usage errors on one line.

Each function here is an argparse ``type=``: it returns the value or raises ``argparse.ArgumentTypeError`` with
what was expected, and :class:`OneLineParser` prints that as the single line
``railsim: error: argument --seed: expected an integer in [0, 2147483647] (SUMO's seed range), got '-5'``
(exit 2), as every other bad input. The user's text is quoted through :func:`railsim.inputs.excerpt` (bounded,
escaped).

* :func:`seed` — SUMO's ``--seed`` is a 32-bit signed int: ``[0, MAX_SEED]``;
* :func:`seconds` — a finite number of seconds ``>= MIN_TIMEOUT_S`` (a timeout of ``1e-9`` s or ``nan`` is no limit
  anyone means);
* :func:`path` — a file-system path without a NUL byte (the OS cannot take one) and not empty;
* :func:`count` — a positive integer (a number of runs, workers, seeds), at most :data:`MAX_COUNT`.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import NoReturn

from railsim.inputs import excerpt
from railsim.scenario.model import MAX_SEED

MIN_TIMEOUT_S = 1.0  # no run of railsim finishes faster: SUMO alone takes longer to start
MAX_COUNT = 10**6  # a count above this is a typo (a study's own bounds are tighter: railsim.studies.bounds)


class OneLineParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose usage errors are one line (``railsim: error: …``) and exit 2."""

    def error(self, message: str) -> NoReturn:
        text = " ".join(message.split())
        sys.stderr.write(f"railsim: error: {text} (see {self.prog} --help)\n")
        raise SystemExit(2)


def _fail(expected: str, text: str) -> argparse.ArgumentTypeError:
    return argparse.ArgumentTypeError(f"expected {expected}, got {excerpt(text)}")


def seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise _fail(f"an integer in [0, {MAX_SEED}] (SUMO's seed range)", text) from None
    if not 0 <= value <= MAX_SEED:
        raise _fail(f"an integer in [0, {MAX_SEED}] (SUMO's seed range)", text)
    return value


def seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise _fail(f"a number of seconds >= {MIN_TIMEOUT_S:g}", text) from None
    if not math.isfinite(value) or value < MIN_TIMEOUT_S:
        raise _fail(f"a finite number of seconds >= {MIN_TIMEOUT_S:g}", text)
    return value


def path(text: str) -> str:
    if not text or "\x00" in text:
        raise _fail("a file or folder path (not empty, no NUL byte)", text)
    return text


def count(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise _fail(f"an integer in [1, {MAX_COUNT}]", text) from None
    if not 1 <= value <= MAX_COUNT:
        raise _fail(f"an integer in [1, {MAX_COUNT}]", text)
    return value


def metres(text: str) -> float:
    """A length in metres: a finite number > 0 (at most 10 km)."""
    try:
        value = float(text)
    except ValueError:
        raise _fail("a length in metres in (0, 10000]", text) from None
    if not math.isfinite(value) or not 0.0 < value <= 10000.0:
        raise _fail("a length in metres in (0, 10000]", text)
    return value
