"""The ``railsim`` executable's entry point: Ctrl-C while Python is still importing railsim is one line, exit 130.

The command's modules import numpy, pandas and the engine, which takes a noticeable fraction of a second; a
Ctrl-C then would otherwise print a bare ``KeyboardInterrupt`` traceback. This module imports nothing of railsim
at its top, so the ``try`` below covers every import and the whole command (:func:`railsim.cli.main.main`).
"""

from __future__ import annotations

import sys

EXIT_INTERRUPTED = 130


def main() -> int:
    try:
        from railsim.cli.main import main as run_command

        return run_command()
    except KeyboardInterrupt:
        print("railsim: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
