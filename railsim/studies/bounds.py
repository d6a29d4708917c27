"""How much a study may ask for: a case count and a run count refused before anything is expanded or run.

A sweep's grid multiplies (six axes of ten values are 10⁶ cases in a twelve-line file) and ``--runs`` is typed by
hand, so a slip can ask for more runs than a cluster finishes in a year, and expanding it alone would take minutes
and gigabytes. Every study counts its cases from the axes' lengths first (a product, not a list) and refuses a
count above :func:`max_cases` with one line naming the number, the limit and how to raise it: the environment
variable :data:`ENV_MAX_CASES` (an integer >= 1).
"""

from __future__ import annotations

import os

from railsim.errors import ConfigError

DEFAULT_MAX_CASES = 100_000  # a sweep this large runs for days on one machine; more is almost surely a slip
ENV_MAX_CASES = "RAILSIM_MAX_CASES"


def max_cases() -> int:
    """The largest number of cases (runs) one study may have: :data:`ENV_MAX_CASES` or the default."""
    text = os.environ.get(ENV_MAX_CASES)
    if text is None or not text.strip():
        return DEFAULT_MAX_CASES
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise ConfigError(f"${ENV_MAX_CASES}", None, f"expected an integer >= 1, got {text[:40]!r}")
    return value


def check_cases(n_cases: int, source: object, field: str | None, what: str = "cases") -> None:
    """Refuse ``n_cases`` above :func:`max_cases`, naming ``source`` and ``field`` (the file or option asking)."""
    limit = max_cases()
    if n_cases > limit:
        raise ConfigError(
            str(source),
            field,
            f"{n_cases:,} {what} exceed the limit of {limit:,} per study (set {ENV_MAX_CASES} to allow more)",
        )
